//! The CPU reference renderer: the output frame from a fisheye image, in f64, following the
//! frame plan exactly. Slow and simple on purpose; it is the oracle the GPU renderer is
//! tested against, with the same filtering (`render::mip`): each pixel takes a trilinear
//! sample of the fisheye's mip chain at the footprint its quad neighbours give (those the
//! same view draws).

use super::frame::{FrameError, PlaneLayout};
use super::mip::{Filter, Pyramid, lod};
use super::plan::{FramePlan, PlannedView};
use crate::image_ops::{sample_offsets, to_rgb8};
use crate::lens::Lens;
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;

/// Renders the output frame; pixels of no view, and pixels whose ray falls outside the lens's
/// image circle or the fisheye frame, are black. Fisheye pixels outside the lens's imaged box
/// count as black (they reach the output only through coarse mip levels at the rim).
pub fn render(plan: &FramePlan, fisheye: &RgbImage, filter: Filter) -> RgbImage {
    assert_eq!(
        (fisheye.width(), fisheye.height()),
        (plan.lens.width, plan.lens.height),
        "the plan's lens must be scaled to the fisheye frame"
    );
    render_from(
        plan,
        &Pyramid::new(&imaged_only(fisheye, &plan.lens)),
        filter,
    )
}

/// The same from a frame's bytes in any [`PixelFormat`](super::PixelFormat): a 4:2:0 frame
/// is filtered as it comes, luma from full size and chroma from half (`render::mip`), as the
/// GPU does.
pub fn render_frame(
    plan: &FramePlan,
    data: &[u8],
    layout: &PlaneLayout,
    filter: Filter,
) -> Result<RgbImage, FrameError> {
    layout.check(data)?;
    assert_eq!(
        (layout.width, layout.height),
        (plan.lens.width, plan.lens.height),
        "the plan's lens must be scaled to the fisheye frame"
    );
    let pyramid = Pyramid::from_frame(data, layout, &plan.lens.imaged_box());
    Ok(render_from(plan, &pyramid, filter))
}

fn render_from(plan: &FramePlan, pyramid: &Pyramid, filter: Filter) -> RgbImage {
    render_pixels(plan, |view, x, y| {
        let r = view.rect;
        let p = DVec2::new((x - r.x) as f64 + 0.5, (y - r.y) as f64 + 0.5);
        let q = plan.fisheye_pixel(view, p)?;
        let level = match filter {
            Filter::Bilinear => 0.0,
            Filter::Mip => {
                // The quad neighbours x ^ 1 and y ^ 1 (frame coordinates), where this same view
                // is drawn and sees something.
                let neighbour = |nx: u32, ny: u32| {
                    let drawn = plan.views.iter().rev().find(|v| v.rect.contains(nx, ny));
                    let n = DVec2::new(nx as f64 - x as f64, ny as f64 - y as f64);
                    drawn
                        .is_some_and(|v| std::ptr::eq(v, view))
                        .then(|| plan.fisheye_pixel(view, p + n))
                        .flatten()
                };
                lod(q, neighbour(x ^ 1, y), neighbour(x, y ^ 1))
            }
        };
        Some(pyramid.sample(q, level))
    })
}

/// The fisheye with every pixel outside the lens's imaged box black, as the GPU sees it.
fn imaged_only(fisheye: &RgbImage, lens: &Lens) -> RgbImage {
    let (columns, rows) = lens.imaged_box();
    let mut out = RgbImage::new(fisheye.width(), fisheye.height());
    for y in rows {
        for x in columns.clone() {
            out.put_pixel(x, y, *fisheye.get_pixel(x, y));
        }
    }
    out
}

/// Renders every view of a plan with `colour(view, point)` averaged over the plan's
/// supersampling grid; None is black. What the ground-truth renderer uses.
pub fn render_with<F>(plan: &FramePlan, colour: F) -> RgbImage
where
    F: Fn(&PlannedView, DVec2) -> Option<DVec3> + Sync,
{
    render_pixels(plan, |view, x, y| {
        let base = DVec2::new((x - view.rect.x) as f64, (y - view.rect.y) as f64);
        let n = view.samples * view.samples;
        let sum: DVec3 = sample_offsets(view.samples)
            .filter_map(|o| colour(view, base + o))
            .sum();
        Some(sum / n as f64)
    })
}

/// Calls `pixel(view, x, y)` for every frame pixel of every view, rows in parallel. Later views
/// (tiles) are drawn over earlier ones, so overlay mode 1 covers its corner.
fn render_pixels<F>(plan: &FramePlan, pixel: F) -> RgbImage
where
    F: Fn(&PlannedView, u32, u32) -> Option<DVec3> + Sync,
{
    let (w, h) = (plan.layout.width, plan.layout.height);
    let mut out = vec![0u8; (w * h * 3) as usize];
    out.par_chunks_mut((w * 3) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as u32;
            for view in plan
                .views
                .iter()
                .filter(|v| y >= v.rect.y && y < v.rect.bottom())
            {
                for x in view.rect.x..view.rect.right() {
                    let rgb = to_rgb8(pixel(view, x, y).unwrap_or(DVec3::ZERO));
                    row[(x * 3) as usize..(x * 3 + 3) as usize].copy_from_slice(&rgb);
                }
            }
        });
    RgbImage::from_raw(w, h, out).expect("buffer sized to the frame")
}
