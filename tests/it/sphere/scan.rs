//! The detection scan on the pair: its views, fixed in the world and tiling the sphere, are
//! all seen through the pair (one lens alone leaves the far side out), and each is drawn as
//! the lens that sees it best draws it alone (the single-lens ground truth), zenith included.

use super::*;
use digiview::detect::scan::{MOTION_VIEWS, all_views, visible};

fn the_detection_scan_sees_the_whole_sphere_through_the_pair(gpu: &Gpu) {
    let lens = pair(2.0 * DEG);
    let s = state(ON_THE_SEAM);
    let frame = fisheye(world(), &lens, &s);
    let to_lens = FramePlan::new(&s, &lens).unwrap().lens_from_world;
    let (seen, plan) = visible(&lens, to_lens, MOTION_VIEWS);
    let all = all_views(MOTION_VIEWS.fov).len();
    // Each lens alone, mounted as the pair holds it, on the same frame: the same scan views
    // laid out alike.
    let aims: Vec<_> = seen.iter().map(|v| (v.yaw, v.pitch, v.fov)).collect();
    let columns = plan.layout.width / MOTION_VIEWS.width;
    let size = (MOTION_VIEWS.width, MOTION_VIEWS.height);
    let mut renderer = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    let mut draw = |plan: &FramePlan| render_image(&mut renderer, &frame, plan).unwrap().to_rgb();
    let [front, back] = [Side::First, Side::Second].map(|side| {
        let (s, one) = alone(&s, &lens, side);
        let to_lens = FramePlan::new(&s, &one).unwrap().lens_from_world;
        (one, to_lens)
    });
    let front_sees = visible(&front.0, front.1, MOTION_VIEWS).0.len();
    let [first, second] = [front, back]
        .map(|(one, to_lens)| draw(&FramePlan::mosaic(&one, to_lens, &aims, size, columns)));
    eprintln!(
        "scan views seen: {} of {all} through the pair, {front_sees} through the front lens alone",
        seen.len()
    );
    assert_eq!(seen.len(), all, "the pair leaves scan views out");
    assert!(front_sees < all, "one lens alone sees the whole sphere?");
    let got = draw(&plan);
    let one = best_of(&plan, &lens, [first, second]);
    let want = truth(world(), &plan, &s);
    let score =
        |b: &RgbImage| -> Vec<f64> { plan.views.iter().map(|v| psnr(&got, b, v.rect)).collect() };
    let (vs_one, vs_truth) = (score(&one), score(&want));
    let at: Vec<String> = seen
        .iter()
        .map(|v| format!("({:.0}, {:.0})", v.yaw / DEG, v.pitch / DEG))
        .collect();
    eprintln!("scan views at (yaw, pitch) {at:?}");
    eprintln!("against the best lens alone (dB): {vs_one:.1?}");
    eprintln!("against truth (dB): {vs_truth:.1?}");
    assert!(vs_one.iter().all(|&p| p >= 38.0), "{vs_one:.1?}");
}

on_each_backend!(the_detection_scan_sees_the_whole_sphere_through_the_pair);
