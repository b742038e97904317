//! The WGSL sources, composed: each pass is the shared lens library, the lens models' dispatch
//! (made here from the models' registry, `Model::NAMES`) and the common definitions, followed
//! by the pass's own file. Embedded at build time so the binary needs no shader files at run
//! time.

use crate::lens::Model;

pub const LENS: &str = include_str!("../../../shaders/lens.wgsl");
pub const COMMON: &str = include_str!("../../../shaders/common.wgsl");
pub const INGEST: &str = include_str!("../../../shaders/ingest.wgsl");
pub const LEVELS: &str = include_str!("../../../shaders/levels.wgsl");
pub const MIP: &str = include_str!("../../../shaders/mip.wgsl");
pub const VIEWS: &str = include_str!("../../../shaders/views.wgsl");
pub const RENDER: &str = include_str!("../../../shaders/render.wgsl");

/// `radial_r(theta, k)`: the normalized radius of the model whose code is the LENS_MODEL
/// override, by its twin `NAME_r` in shaders/lens.wgsl; negative for an unknown code.
pub fn lens_models() -> String {
    let cases: String = Model::NAMES
        .iter()
        .enumerate()
        .map(|(code, name)| format!("        case {code}u: {{ return {name}_r(theta, k); }}\n"))
        .collect();
    format!(
        "// Made from the lens models' registry (src/lens/models/mod.rs).\n\
         fn radial_r(theta: f32, k: vec4f) -> f32 {{\n    switch LENS_MODEL & (PAIR_BIT - 1u) {{\n{cases}        \
         default: {{ return -1.0; }}\n    }}\n}}\n"
    )
}

/// A pass's full source: lens library, the models' dispatch, common definitions, then the
/// pass.
pub fn compose(pass: &str) -> String {
    [LENS, &lens_models(), COMMON, pass].join("\n")
}

/// Every pass, named, as compiled.
pub fn passes() -> [(&'static str, String); 3] {
    [
        ("ingest", compose(&[LEVELS, INGEST].join("\n"))),
        // The mip pass reads no lens and no parameters.
        ("mip", [LEVELS, MIP].join("\n")),
        ("render", compose(&[VIEWS, RENDER].join("\n"))),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_pass_parses_and_validates_with_naga() {
        let layer = ("layer", compose(super::super::layer::SOURCE));
        for (name, source) in passes().into_iter().chain([layer]) {
            let module = naga::front::wgsl::parse_str(&source)
                .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::default(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        }
    }

    #[test]
    fn every_lens_model_has_its_wgsl_twin() {
        for name in Model::NAMES {
            let twin = format!("fn {name}_r(theta: f32, k: vec4f) -> f32");
            assert!(LENS.contains(&twin), "shaders/lens.wgsl lacks {twin}");
        }
    }
}
