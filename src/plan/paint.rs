//! A plan walked pixel by pixel on the CPU: each output pixel of each view (tiles over views),
//! rows in parallel, its colour from a function of the view and the point in it. The CPU
//! reference renderer (`crate::render::cpu`) and the ground-truth scenes (`crate::scene`)
//! both paint this way, so they differ only in where the colour comes from.

use super::{FramePlan, PlannedView};
use crate::image_ops::{sample_offsets, to_rgb8};
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;

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
pub fn render_pixels<F>(plan: &FramePlan, pixel: F) -> RgbImage
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
