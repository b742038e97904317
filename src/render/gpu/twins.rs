//! The WGSL side of every constant, struct and workgroup size the Rust side shares with the
//! shaders, read back from the composed sources with naga and held to its Rust twin: a
//! constant that changes on one side only, or a struct field that moves, fails here rather
//! than as a wrong picture.

use super::blocks::{MIXED, NO_VIEW};
use super::layer::{GpuLayerEntry, GpuLayerParams, MAX_ENTRIES};
use super::params::{
    GpuLens, GpuParams, GpuView, KIND_BLACK, KIND_FISHEYE, KIND_PANORAMA, KIND_RECTILINEAR,
    MAX_VIEWS, SHUTTER_BIT,
};
use super::pipelines::{MIXED_WORKGROUP, WORKGROUP};
use super::planes::{IngestTargets, MipStep, Region};
use super::shaders::passes;
use crate::frame::{PixelFormat, yuv};
use crate::geometry::shutter::KNOTS;
use crate::plan::Filter;
use crate::plan::SHUTTER_STEPS;
use naga::{Expression, Literal, Module, TypeInner};
use std::mem::offset_of;

fn modules() -> Vec<(&'static str, Module)> {
    let layer = ("layer", super::shaders::compose(super::layer::SOURCE));
    passes()
        .into_iter()
        .chain([layer])
        .map(|(name, source)| (name, naga::front::wgsl::parse_str(&source).unwrap()))
        .collect()
}

/// Every module-scope constant of the passes that is a number, by name (as f64).
fn constants() -> Vec<(String, f64)> {
    let mut out = vec![];
    for (_, module) in modules() {
        for (_, c) in module.constants.iter() {
            let value = match module.global_expressions[c.init] {
                Expression::Literal(Literal::U32(v)) => v as f64,
                Expression::Literal(Literal::I32(v)) => v as f64,
                Expression::Literal(Literal::F32(v)) => v as f64,
                _ => continue,
            };
            out.push((c.name.clone().unwrap_or_default(), value));
        }
    }
    out
}

#[test]
fn every_wgsl_constant_with_a_rust_twin_has_its_value() {
    let twins: [(&str, f64); 21] = [
        ("FORMAT_RGBA", PixelFormat::Rgba.shader_code() as f64),
        ("FORMAT_I420", PixelFormat::I420.shader_code() as f64),
        ("FORMAT_NV12", PixelFormat::Nv12.shader_code() as f64),
        ("FILTER_MIP", Filter::Mip.shader_code() as f64),
        ("FILTER_BILINEAR", Filter::Bilinear.shader_code() as f64),
        ("KIND_BLACK", KIND_BLACK as f64),
        ("KIND_RECTILINEAR", KIND_RECTILINEAR as f64),
        ("KIND_PANORAMA", KIND_PANORAMA as f64),
        ("KIND_FISHEYE", KIND_FISHEYE as f64),
        ("MAX_VIEWS", MAX_VIEWS as f64),
        ("MAX_ENTRIES", MAX_ENTRIES as f64),
        ("LAYER_PANORAMA", KIND_PANORAMA as f64),
        ("SHUTTER_BIT", SHUTTER_BIT as f64),
        ("SHUTTER_STEPS", SHUTTER_STEPS as f64),
        ("KNOTS", KNOTS as f64),
        ("MIXED", MIXED as f64),
        ("NO_VIEW", NO_VIEW as i32 as f64),
        ("KR", yuv::KR as f32 as f64),
        ("KB", yuv::KB as f32 as f64),
        ("KG", yuv::KG as f32 as f64),
        ("PAIR_BIT", crate::lens::PAIR_BIT as f64),
    ];
    let wgsl = constants();
    for (name, rust) in twins {
        let values: Vec<f64> = wgsl
            .iter()
            .filter(|(n, _)| n == name)
            .map(|(_, v)| *v)
            .collect();
        assert!(!values.is_empty(), "no WGSL constant {name}");
        for v in values {
            assert_eq!(v, rust, "WGSL {name} is {v}, its Rust twin {rust}");
        }
    }
}

/// A WGSL struct's size and member offsets, by name, in the first module that declares it.
fn wgsl_struct(name: &str) -> (u32, Vec<(String, u32)>) {
    for (_, module) in modules() {
        for (_, ty) in module.types.iter() {
            if let (Some(n), TypeInner::Struct { members, span }) = (&ty.name, &ty.inner)
                && n == name
            {
                let members = members
                    .iter()
                    .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                    .collect();
                return (*span, members);
            }
        }
    }
    panic!("no WGSL struct {name}")
}

/// Asserts that WGSL struct `$wgsl` and Rust struct `$rust` have the same size and the same
/// fields at the same offsets.
macro_rules! same_layout {
    ($rust:ty, $wgsl:literal, [$($field:ident),+ $(,)?]) => {{
        let (size, members) = wgsl_struct($wgsl);
        assert_eq!(size as usize, size_of::<$rust>(), "{} size", $wgsl);
        let rust = [$((stringify!($field), offset_of!($rust, $field))),+];
        let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
        let rust_names: Vec<&str> = rust.iter().map(|(n, _)| *n).collect();
        assert_eq!(names, rust_names, "{} fields", $wgsl);
        for ((name, offset), (_, rust_offset)) in members.iter().zip(rust) {
            assert_eq!(*offset as usize, rust_offset, "{}.{name} offset", $wgsl);
        }
    }};
}

#[test]
fn every_wgsl_struct_with_a_rust_twin_has_its_layout() {
    same_layout!(
        GpuParams,
        "Params",
        [
            output,
            output_planes,
            input,
            input_planes,
            lens,
            shutter_line,
            shutter
        ]
    );
    same_layout!(
        GpuLens,
        "Lens",
        [
            affine,
            inverse,
            offset_frame,
            limits,
            k,
            counts,
            pol,
            invpol,
            second_affine,
            second_inverse,
            second_offset,
            second_limits,
            second_k,
            second_from_first
        ]
    );
    same_layout!(GpuView, "View", [rect, kind, m0, m1, m2, p]);
    same_layout!(
        GpuLayerParams,
        "LayerParams",
        [output, output_planes, picture, lens]
    );
    same_layout!(GpuLayerEntry, "Entry", [view, share]);
    same_layout!(Region, "Region", [offset, stride, width, height]);
    same_layout!(IngestTargets, "Targets", [level1, level2, chroma1, imaged]);
    same_layout!(MipStep, "Step", [finer, coarser, channels]);
}

#[test]
fn every_entry_point_has_the_workgroup_size_the_dispatches_assume() {
    let want = [
        ("ingest", [WORKGROUP, WORKGROUP, 1]),
        ("downsample", [WORKGROUP, WORKGROUP, 1]),
        ("draw", [WORKGROUP, WORKGROUP, 1]),
        ("draw_mixed", [MIXED_WORKGROUP, 1, 1]),
        ("layer", [WORKGROUP, WORKGROUP, 1]),
    ];
    let modules = modules();
    for (name, size) in want {
        let entry = modules
            .iter()
            .flat_map(|(_, m)| &m.entry_points)
            .find(|e| e.name == name)
            .unwrap_or_else(|| panic!("no entry point {name}"));
        assert_eq!(entry.workgroup_size, size, "{name}");
    }
}
