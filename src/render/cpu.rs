//! The CPU reference renderer: the output frame from a fisheye image, in f64, following the
//! frame plan exactly. Slow and simple on purpose; it is the oracle the GPU renderer is
//! tested against, with the same filtering (`render::mip`): each pixel takes a trilinear
//! sample of the fisheye's mip chain at the footprint its quad neighbours give (those the
//! same view draws, in the same image of a lens pair).

use super::mip::{Pyramid, lod};
use super::stitch::Stitches;
use crate::frame::{FrameError, PixelFormat, PlaneLayout};
use crate::plan::paint::render_pixels;
use crate::plan::{Filter, FramePlan, PlannedView};
use glam::DVec2;
use image::RgbImage;

/// Renders the output frame; pixels of no view, and pixels whose ray falls outside the lens's
/// image circle or the fisheye frame, are black. A lens pair's seam is blended first
/// (`render::stitch`), as the GPU renderer does. Fisheye pixels outside the lens's imaged box
/// count as black (they reach the output only through coarse mip levels at the rim).
pub fn render(plan: &FramePlan, fisheye: &RgbImage, filter: Filter) -> RgbImage {
    assert_eq!(
        (fisheye.width(), fisheye.height()),
        (plan.lens.width, plan.lens.height),
        "the plan's lens must be scaled to the fisheye frame"
    );
    if plan.lens.pair.is_some() {
        // A pair's seam is blended in the frame's bytes, as the GPU renderer takes them.
        let layout = PlaneLayout::tight(PixelFormat::Rgba, fisheye.width(), fisheye.height())
            .expect("a fisheye frame has pixels");
        let data = crate::frame::yuv::encode(fisheye, &layout);
        return render_frame(plan, &data, &layout, filter, PixelFormat::Rgba)
            .expect("the frame is of its own layout");
    }
    let pyramid = Pyramid::kept(fisheye, &plan.lens.imaged_box());
    render_from(plan, &pyramid, filter, false)
}

/// The same from a frame's bytes in any [`PixelFormat`], as the GPU renders it into `output`
/// frames: a 4:2:0 frame is filtered as it comes, luma from full size and chroma from half
/// (`render::mip`); when `output` is 4:2:0 too, its chroma is sampled once per 2x2 quad of
/// the output (per view), else once per pixel.
pub fn render_frame(
    plan: &FramePlan,
    data: &[u8],
    layout: &PlaneLayout,
    filter: Filter,
    output: PixelFormat,
) -> Result<RgbImage, FrameError> {
    layout.check(data)?;
    assert_eq!(
        (layout.width, layout.height),
        (plan.lens.width, plan.lens.height),
        "the plan's lens must be scaled to the fisheye frame"
    );
    let mut stitches = Stitches::default();
    let stitched = stitches.stitched(&plan.lens, layout, data);
    let pyramid = Pyramid::from_frame(stitched, layout, &plan.lens.imaged_box());
    Ok(render_from(plan, &pyramid, filter, output.is_yuv()))
}

/// `quad_chroma`: 4:2:0 chroma once per quad (4:2:0 output) rather than per pixel.
fn render_from(plan: &FramePlan, pyramid: &Pyramid, filter: Filter, quad_chroma: bool) -> RgbImage {
    // Whether `view` draws frame pixel (x, y): the last view containing it (tiles cover views).
    let draws = |view: &PlannedView, x: u32, y: u32| {
        let drawn = plan.views.iter().rev().find(|v| v.rect.contains(x, y));
        drawn.is_some_and(|v| std::ptr::eq(v, view))
    };
    // Where frame pixel (x, y) of `view` lands in the fisheye, if it sees anything.
    let land = |view: &PlannedView, x: u32, y: u32| {
        let r = view.rect;
        let p = DVec2::new(x as f64 - r.x as f64 + 0.5, y as f64 - r.y as f64 + 0.5);
        plan.fisheye_pixel(view, p)
    };
    // Where a pixel of `view` lands and its level of detail, from its quad neighbours x ^ 1
    // and y ^ 1 where this same view draws them and they see something.
    let point = |view: &PlannedView, x: u32, y: u32| {
        let q = land(view, x, y)?;
        let level = match filter {
            Filter::Bilinear => 0.0,
            Filter::Mip => {
                // A neighbour in the other image of a lens pair does not count either.
                let neighbour = |nx, ny| {
                    let n = draws(view, nx, ny).then(|| land(view, nx, ny)).flatten()?;
                    plan.lens.same_image(q, n).then_some(n)
                };
                lod(q, neighbour(x ^ 1, y), neighbour(x, y ^ 1))
            }
        };
        Some((q, level))
    };
    render_pixels(plan, |view, x, y| {
        let (q, level) = point(view, x, y)?;
        if !pyramid.is_420() || !quad_chroma {
            return Some(pyramid.sample(q, level));
        }
        // 4:2:0: the chroma this view's pixels of the 2x2 quad share, sampled once at the mean
        // of where they land, at the largest of their levels of detail (shaders/render.wgsl).
        let (qx, qy) = (x & !1, y & !1);
        let group: Vec<(DVec2, f64)> = [(qx, qy), (qx + 1, qy), (qx, qy + 1), (qx + 1, qy + 1)]
            .into_iter()
            .filter(|&(gx, gy)| draws(view, gx, gy))
            .filter_map(|(gx, gy)| point(view, gx, gy))
            .collect();
        let centre = group.iter().map(|g| g.0).sum::<DVec2>() / group.len() as f64;
        let chroma_lod = group.iter().map(|g| g.1).fold(0.0, f64::max);
        Some(pyramid.sample_420(q, level, centre, chroma_lod))
    })
}
