//! The WGSL sources, composed: each pass is the shared lens library and common definitions
//! followed by the pass's own file. Embedded at build time so the binary needs no shader
//! files at run time.

pub const LENS: &str = include_str!("../../../shaders/lens.wgsl");
pub const COMMON: &str = include_str!("../../../shaders/common.wgsl");
pub const INGEST: &str = include_str!("../../../shaders/ingest.wgsl");
pub const LEVELS: &str = include_str!("../../../shaders/levels.wgsl");
pub const MIP: &str = include_str!("../../../shaders/mip.wgsl");
pub const RENDER: &str = include_str!("../../../shaders/render.wgsl");

/// A pass's full source: lens library, common definitions, then the pass.
pub fn compose(pass: &str) -> String {
    [LENS, COMMON, pass].join("\n")
}

/// Every pass, named, as compiled.
pub fn passes() -> [(&'static str, String); 3] {
    [
        ("ingest", [LENS, COMMON, LEVELS, INGEST].join("\n")),
        // The mip pass reads no lens and no parameters.
        ("mip", [LEVELS, MIP].join("\n")),
        ("render", compose(RENDER)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_pass_parses_and_validates_with_naga() {
        for (name, source) in passes() {
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
        for f in [
            "fn equidistant_r(",
            "fn equisolid_r(",
            "fn stereographic_r(",
            "fn orthographic_r(",
            "fn kannala_brandt_r(",
            "fn double_sphere_r(",
            "fn ocam_r(",
        ] {
            assert!(LENS.contains(f), "shaders/lens.wgsl lacks {f}");
        }
    }
}
