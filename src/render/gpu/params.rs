//! The per-frame data the shaders read, laid out once: `GpuParams` (uniform, WGSL `Params`
//! in shaders/common.wgsl, holding `GpuLens` = WGSL `Lens` in shaders/lens.wgsl) and one
//! `GpuView` (WGSL `View` in shaders/render.wgsl) per view and tile. Only vec4-shaped
//! fields, so the Rust and WGSL layouts agree without padding rules; sizes asserted below.

use super::GpuError;
use crate::frame::PlaneLayout;
use crate::geometry::Projection;
use crate::geometry::shutter::KNOTS;
use crate::layout::Rect;
use crate::lens::Lens;
use crate::lens::pair::Part;
use crate::plan::{FramePlan, PlannedView, ViewMap};
use bytemuck::{Pod, Zeroable};
use glam::DMat3;

pub const OCAM_POL: usize = 8;
pub const OCAM_INVPOL: usize = 24;
/// Views and tiles one frame may hold (4 views + a row of 120-px tiles across 7680 px).
pub const MAX_VIEWS: usize = 68;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLens {
    pub affine: [f32; 4],
    pub inverse: [f32; 4],
    pub offset_frame: [f32; 4],
    pub limits: [f32; 4],
    pub k: [f32; 4],
    pub counts: [u32; 4],
    pub pol: [[f32; 4]; OCAM_POL / 4],
    pub invpol: [[f32; 4]; OCAM_INVPOL / 4],
    /// A lens pair's second lens, as the first's fields above (zero for one lens; the
    /// offset's z is 1 for a pair), and the rotation into its frame (quaternion xyzw).
    pub second_affine: [f32; 4],
    pub second_inverse: [f32; 4],
    pub second_offset: [f32; 4],
    pub second_limits: [f32; 4],
    pub second_k: [f32; 4],
    pub second_from_first: [f32; 4],
}
const _: () = assert!(size_of::<GpuLens>() == 320);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuParams {
    pub output: [u32; 4],
    pub output_planes: [u32; 4],
    pub input: [u32; 4],
    pub input_planes: [u32; 4],
    pub lens: GpuLens,
    /// The rolling shutter's knot coordinate (`ShutterTable::line`, xyz) and whether the frame
    /// has one (w: 1 or 0).
    pub shutter_line: [f32; 4],
    /// `ShutterTable::knots`, quaternions (x, y, z, w).
    pub shutter: [[f32; 4]; KNOTS],
}
const _: () = assert!(size_of::<GpuParams>() == 64 + 320 + 16 + 16 * KNOTS);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuView {
    pub rect: [u32; 4],
    pub kind: [u32; 4],
    pub m0: [f32; 4],
    pub m1: [f32; 4],
    pub m2: [f32; 4],
    pub p: [f32; 4],
}
const _: () = assert!(size_of::<GpuView>() == 96);

/// `KIND_*` in shaders/render.wgsl.
pub(super) const KIND_BLACK: u32 = 0;
pub(super) const KIND_RECTILINEAR: u32 = 1;
pub(super) const KIND_PANORAMA: u32 = 2;
pub(super) const KIND_FISHEYE: u32 = 3;
/// The bit of VIEW_KINDS (shaders/views.wgsl) that says the frame has a rolling shutter to
/// correct: the draw pipelines of frames without one leave its code out.
pub(super) const SHUTTER_BIT: u32 = 4;

fn packed<const N: usize>(coefficients: &[f64]) -> [[f32; 4]; N] {
    let mut out = [[0.0; 4]; N];
    for (i, c) in coefficients.iter().enumerate() {
        out[i / 4][i % 4] = *c as f32;
    }
    out
}

pub fn gpu_lens(lens: &Lens) -> Result<GpuLens, GpuError> {
    let c = lens.radial.model.coefficients();
    if c.pol.len() > OCAM_POL || c.invpol.len() > OCAM_INVPOL {
        return Err(GpuError::Lens {
            lens: lens.name.clone(),
            what: format!(
                "OCam polynomials of {} and {} coefficients; the GPU takes at most \
                 {OCAM_POL} and {OCAM_INVPOL}",
                c.pol.len(),
                c.invpol.len()
            ),
        });
    }
    let first = Part {
        radial: lens.radial.clone(),
        affine: lens.affine,
        half_fov: lens
            .pair
            .as_ref()
            .map_or(lens.half_fov, |p| p.first.half_fov),
    };
    let [affine, inverse, offset, limits, k] = part_fields(&first);
    let mut out = GpuLens {
        affine,
        inverse,
        offset_frame: [offset[0], offset[1], lens.width as f32, lens.height as f32],
        limits,
        k,
        counts: [c.pol.len() as u32, c.invpol.len() as u32, 0, 0],
        pol: packed(c.pol),
        invpol: packed(c.invpol),
        ..GpuLens::zeroed()
    };
    if let Some(pair) = &lens.pair {
        let [affine, inverse, offset, limits, k] = part_fields(&pair.second);
        let q = pair.second_from_first;
        out.second_affine = affine;
        out.second_inverse = inverse;
        out.second_offset = [offset[0], offset[1], 1.0, 0.0];
        out.second_limits = limits;
        out.second_k = k;
        out.second_from_first = [q.x, q.y, q.z, q.w].map(|v| v as f32);
    }
    Ok(out)
}

/// One lens's matrix, inverse, principal point, limits (half field of view, normalized radius
/// there, the model's θ and radius limits) and coefficients, as `GpuLens` holds them.
fn part_fields(part: &Part) -> [[f32; 4]; 5] {
    let m = part.affine.matrix;
    let inv = m.inverse();
    let r_limit = part.radial.r_of_theta(part.half_fov).unwrap_or(0.0);
    let o = part.affine.offset;
    [
        [m.x_axis.x, m.x_axis.y, m.y_axis.x, m.y_axis.y].map(|v| v as f32),
        [inv.x_axis.x, inv.x_axis.y, inv.y_axis.x, inv.y_axis.y].map(|v| v as f32),
        [o.x as f32, o.y as f32, 0.0, 0.0],
        [
            part.half_fov as f32,
            r_limit as f32,
            part.radial.limits.theta_max as f32,
            part.radial.limits.r_max.min(f32::MAX as f64) as f32,
        ],
        part.radial.model.coefficients().k.map(|v| v as f32),
    ]
}

fn columns(m: DMat3) -> [[f32; 4]; 3] {
    [m.x_axis, m.y_axis, m.z_axis].map(|c| [c.x as f32, c.y as f32, c.z as f32, 0.0])
}

/// A rectified projection as the shaders take it: its KIND_*, the matrix `m` (a view-frame
/// ray to the frame the shader projects in) as they apply it, and the projection's numbers
/// (views.wgsl's `View::p`).
pub fn projection_params(projection: Projection, m: DMat3) -> (u32, DMat3, [f64; 4]) {
    match projection {
        Projection::Rectilinear { width, height, fov } => (
            KIND_RECTILINEAR,
            m,
            [
                Projection::focal(width, fov),
                width / 2.0,
                height / 2.0,
                0.0,
            ],
        ),
        Projection::Panorama {
            width,
            height,
            fov,
            pitch,
        } => (
            KIND_PANORAMA,
            m * DMat3::from_rotation_y(-pitch),
            [fov / width, pitch, width / 2.0, height / 2.0],
        ),
    }
}

pub fn gpu_view(plan: &FramePlan, view: &PlannedView) -> GpuView {
    let (kind, m, p) = match view.map {
        ViewMap::Rays {
            projection,
            world_from_view,
        } => projection_params(projection, plan.lens_from_world * world_from_view),
        ViewMap::Fisheye { origin, scale } => (
            KIND_FISHEYE,
            DMat3::IDENTITY,
            [origin.x, origin.y, scale, 0.0],
        ),
        ViewMap::Black => (KIND_BLACK, DMat3::IDENTITY, [0.0; 4]),
    };
    rays_view(view.rect, (kind, m, p), 0)
}

/// A rectangle of the output whose pixels map to rays as `(kind, m, p)` say
/// ([`projection_params`]); `flag` is the pass's own (`kind.y`).
pub fn rays_view(r: Rect, (kind, m, p): (u32, DMat3, [f64; 4]), flag: u32) -> GpuView {
    let [m0, m1, m2] = columns(m);
    GpuView {
        rect: [r.x, r.y, r.w, r.h],
        kind: [kind, flag, 0, 0],
        m0,
        m1,
        m2,
        p: p.map(|v| v as f32),
    }
}

/// The frame's parameters and views: `levels` in the source's mip chain, `mixed_blocks` in
/// the block map's list for the draw pass's per-pixel dispatch.
pub fn frame_params(
    plan: &FramePlan,
    input: &PlaneLayout,
    output: &PlaneLayout,
    levels: u32,
    mixed_blocks: u32,
) -> Result<(GpuParams, Vec<GpuView>), GpuError> {
    let views: Vec<GpuView> = plan.views.iter().map(|v| gpu_view(plan, v)).collect();
    if views.len() > MAX_VIEWS {
        return Err(GpuError::TooManyViews(views.len(), MAX_VIEWS));
    }
    let mut params = GpuParams {
        output: [
            output.width,
            output.height,
            views.len() as u32,
            output.stride,
        ],
        output_planes: [
            output.chroma[0],
            output.chroma[1],
            output.chroma_stride,
            mixed_blocks,
        ],
        input: [input.width, input.height, input.stride, input.chroma_stride],
        input_planes: [input.chroma[0], input.chroma[1], levels, 0],
        lens: gpu_lens(&plan.lens)?,
        shutter_line: [0.0; 4],
        shutter: [[0.0, 0.0, 0.0, 1.0]; KNOTS],
    };
    if let Some(table) = &plan.shutter {
        let l = table.line;
        params.shutter_line = [l.x as f32, l.y as f32, l.z as f32, 1.0];
        params.shutter = table.knots.map(|q| [q.x, q.y, q.z, q.w].map(|v| v as f32));
    }
    Ok((params, views))
}
