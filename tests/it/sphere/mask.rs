//! An invisible airframe (issue 59): an arm across the front lens's rim, where the back lens
//! sees past it, painted black into the pair's frame; masked in the pair, the view that looks
//! at it is the view without it.

use super::*;
use digiview::lens::pair::Mask;
use std::f64::consts::PI;

/// The front lens's direction `theta` from its axis, `phi` round it (its image's x towards y).
fn direction(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// The view's middle's direction round the front lens's axis.
fn azimuth(plan: &FramePlan, v: &digiview::plan::PlannedView) -> f64 {
    let mid = DVec2::new(v.rect.w as f64, v.rect.h as f64) / 2.0;
    let r = plan.lens_from_world * plan.world_ray(v, mid).unwrap();
    r.y.atan2(r.x)
}

/// The front lens's pixels from `from` off its axis to its rim, within `half` of `phi`, black.
fn paint_arm(frame: &mut RgbImage, lens: &Lens, (from, phi, half): (f64, f64, f64)) {
    let pair = lens.pair.as_ref().unwrap();
    for (x, y, px) in frame.enumerate_pixels_mut() {
        let p = DVec2::new(x as f64, y as f64);
        if pair.side_at(p) != Side::First {
            continue;
        }
        let Some(r) = pair.first.unproject(p) else {
            continue;
        };
        let off = (r.y.atan2(r.x) - phi + PI).rem_euclid(2.0 * PI) - PI;
        if r.z.acos() >= from && off.abs() <= half {
            *px = image::Rgb([0, 0, 0]);
        }
    }
}

/// A polygon round the arm: `margin` wider each way, to just inside the image circle.
fn mask_round(lens: &Lens, (from, phi, half): (f64, f64, f64), margin: f64) -> Mask {
    let first = &lens.pair.as_ref().unwrap().first;
    let centre = first.project(DVec3::Z).unwrap();
    let rim = first.half_fov - 0.1 * DEG;
    let steps = 16;
    let at = |theta: f64, k: usize| {
        let a = phi - half - margin + (half + margin) * 2.0 * k as f64 / steps as f64;
        first.project(direction(theta, a)).unwrap()
    };
    let inner = (0..=steps).map(|k| at(from - margin, k));
    // Just past the rim: the image circle's edge pixels are inside.
    let outer = (0..=steps)
        .rev()
        .map(|k| centre + (at(rim, k) - centre) * 1.005);
    Mask {
        points: inner.chain(outer).collect(),
    }
}

/// The first of `views` drawn from `frame` through `lens`, against the truth, dB.
fn score(gpu: &Gpu, frame: &RgbImage, lens: &Lens, views: [(f64, f64); 4]) -> f64 {
    let s = state(views);
    let plan = FramePlan::new(&s, lens).unwrap();
    let mut renderer = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    let got = render_image(&mut renderer, frame, &plan).unwrap().to_rgb();
    psnr(&got, &truth(world(), &plan, &s), plan.views[0].rect)
}

#[test]
fn an_arm_across_the_front_lenss_rim_masked_in_the_pair_leaves_the_view_as_without_it() {
    let gpu = gpu();
    let lens = pair(0.0);
    let views = ON_THE_SEAM;
    let s = state(views);
    let plan = FramePlan::new(&s, &lens).unwrap();
    // An arm 20° wide from 6° below the front lens's horizon to its rim, where the view
    // looks: the middle third of the view, both sides of the seam.
    let arm = (84.0 * DEG, azimuth(&plan, &plan.views[0]), 10.0 * DEG);
    let clean = fisheye(world(), &lens, &s);
    let mut painted = clean.clone();
    paint_arm(&mut painted, &lens, arm);
    let mut masked = lens.clone();
    let pair = std::sync::Arc::make_mut(masked.pair.as_mut().unwrap());
    // The mask's edge eases in over the feather (4deg): the polygon that much wider.
    pair.masks = vec![mask_round(&lens, arm, 5.0 * DEG)];
    let without = score(&gpu, &clean, &lens, views);
    let seen = score(&gpu, &painted, &lens, views);
    let hidden = score(&gpu, &painted, &masked, views);
    let masked_clean = score(&gpu, &clean, &masked, views);
    eprintln!(
        "view on the arm, against truth: no arm {without:.2} dB, arm {seen:.2}, arm masked \
         {hidden:.2}, masked with no arm {masked_clean:.2}"
    );
    assert!(
        seen <= without - 5.0,
        "the arm shows: {seen:.2} against {without:.2} dB"
    );
    assert!(
        (hidden - without).abs() <= 0.5,
        "masked, the arm leaves {hidden:.2} dB against {without:.2}"
    );
}
