//! The CPU reference renderer: the output frame from a fisheye image, in f64, following the
//! frame plan exactly. Slow and simple on purpose; it is the oracle the GPU renderer is
//! tested against. Each output pixel averages an n × n grid of bilinear fisheye samples, n
//! from the plan, so minified views (debug, wide panoramas, small tiles) are box-filtered.

use super::plan::FramePlan;
use crate::image_ops::{bilinear, sample_offsets, to_rgb8};
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;

/// Renders the output frame; pixels of no view, and samples outside the lens's image circle
/// or the fisheye frame, are black.
pub fn render(plan: &FramePlan, fisheye: &RgbImage) -> RgbImage {
    assert_eq!(
        (fisheye.width(), fisheye.height()),
        (plan.lens.width, plan.lens.height),
        "the plan's lens must be scaled to the fisheye frame"
    );
    render_with(plan, |view, p| {
        plan.fisheye_pixel(view, p).map(|q| bilinear(fisheye, q))
    })
}

/// Renders every view of a plan with `colour(view, point)`; None is black. Rows in parallel.
pub fn render_with<F>(plan: &FramePlan, colour: F) -> RgbImage
where
    F: Fn(&super::PlannedView, DVec2) -> Option<DVec3> + Sync,
{
    let (w, h) = (plan.layout.width, plan.layout.height);
    let mut out = vec![0u8; (w * h * 3) as usize];
    out.par_chunks_mut((w * 3) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as u32;
            // Later views (tiles) are drawn over earlier ones, so overlay mode 1 covers its corner.
            for view in plan
                .views
                .iter()
                .filter(|v| y >= v.rect.y && y < v.rect.bottom())
            {
                let offsets: Vec<DVec2> = sample_offsets(view.samples).collect();
                for x in view.rect.x..view.rect.right() {
                    let base = DVec2::new((x - view.rect.x) as f64, (y - view.rect.y) as f64);
                    let sum: DVec3 = offsets.iter().filter_map(|o| colour(view, base + *o)).sum();
                    let rgb = to_rgb8(sum / offsets.len() as f64);
                    row[(x * 3) as usize..(x * 3 + 3) as usize].copy_from_slice(&rgb);
                }
            }
        });
    RgbImage::from_raw(w, h, out).expect("buffer sized to the frame")
}
