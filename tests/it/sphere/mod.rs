//! The full sphere from two fisheyes back to back (issue 59): lens.cal's DUAL pair (two 195°
//! lenses side by side in one frame, the first looking down), a synthetic pair frame drawn
//! from a panorama of real photographs with the back lens twisted 2° from the back-to-back
//! pose, rendered on the GPU with the pair's rotation known; views that straddle the seam
//! (the horizon) against ground truth, and the same frame rendered with the rotation left
//! uncalibrated as a negative control.

use crate::common;
use common::gpu::*;
use common::*;
use digiview::frame::PixelFormat;
use digiview::geometry::Euler;
use digiview::geometry::rotation::MOUNT_FROM_LENS;
use digiview::image_ops::{bilinear, pixel, psnr};
use digiview::layout::Rect;
use digiview::lens::pair::{PairPose, correction};
use digiview::lens::pair_fit::fit_pair;
use digiview::lens::{Lens, Side};
use digiview::modes::{LayoutMode, OverlayMode};
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::render::gpu::renderer::render_image;
use digiview::scene::PanoramaWorld;
use digiview::scene::panorama::mosaic;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::State;
use glam::{DMat2, DMat3, DVec2, DVec3};
use image::RgbImage;
use std::sync::OnceLock;

mod klv;
mod mask;
mod scan;
mod shutter;
mod sources;
mod stream;
mod v360;

/// The pair frame's size: half the shipped rig's 3840x1920.
const FRAME: (u32, u32) = (1920, 960);

/// The panorama of photographs the pair sees (built once for the binary).
fn world() -> &'static PanoramaWorld {
    static WORLD: OnceLock<PanoramaWorld> = OnceLock::new();
    WORLD.get_or_init(|| {
        let dir = photos();
        let photos: Vec<RgbImage> = ["dog", "eagle", "giraffe", "horses", "kite", "person"]
            .iter()
            .map(|n| image::open(dir.join(format!("{n}.jpg"))).unwrap().to_rgb8())
            .collect();
        PanoramaWorld::new(mosaic(&photos, 4096, 2048, 8))
    })
}

/// The DUAL pair with the back lens turned by `roll` (about its axis) from back to back.
fn pair(roll: f64) -> Lens {
    posed([roll, 0.0, 0.0])
}

/// The DUAL pair with the back lens turned by roll, pitch and yaw from back to back.
fn posed([roll, pitch, yaw]: [f64; 3]) -> Lens {
    let cal = lens_cal();
    let lens = |n: &str| cal.find(n).unwrap().lens();
    let pose = PairPose {
        correction: correction(roll, pitch, yaw),
        baseline: DVec3::ZERO,
        feather: 4.0 * DEG,
        masks: vec![],
    };
    let dual = cal.find("DUAL").unwrap();
    Lens::paired(&lens("DUALF"), &lens("DUALB"), "DUAL", dual.lens_id, pose)
        .for_frame(FRAME.0, FRAME.1, None)
}

/// Four 90° views at 320x240 (layout 4, 640x480), aimed as `views` (yaw, pitch) say.
fn state(views: [(f64, f64); 4]) -> State {
    let mut s = four_view_state(7);
    s.settings.lens = lens_cal().find("DUAL").unwrap().lens_id;
    (s.settings.sensor.width, s.settings.sensor.height) = FRAME;
    s.settings.output.layout = LayoutMode::Four;
    s.settings.output.overlay = OverlayMode::None;
    for (cam, (yaw, pitch)) in s.settings.cameras.iter_mut().zip(views) {
        *cam = view(yaw, pitch, 90.0, 1, 7);
    }
    s
}

/// `serve` with `source` through DUAL, one 90° view across the seam (640x480), and the last
/// picture FFmpeg decoded from its stream, which FFmpeg took without a complaint.
fn served_through_dual(source: &str) -> (common::serve::Serve, RgbImage) {
    use common::serve::{Serve, until_running};
    let serve = Serve::start_video(&[
        "--source",
        source,
        "--lens",
        "DUAL",
        "--size",
        "640x480",
        "--layout",
        "0",
        "--cam",
        "0:yaw=30deg,pitch=0deg,fov=90deg,lock=7",
    ]);
    until_running(&serve);
    let got = crate::players::pull(serve.rtsp.clone().unwrap(), "tcp")
        .join()
        .unwrap();
    let bad = crate::players::complaints(&got.log);
    assert!(bad.is_empty(), "FFmpeg reports {bad:#?}");
    (serve, got.last)
}

/// Views that straddle the seam: the horizon, all round, a little above and below.
const ON_THE_SEAM: [(f64, f64); 4] = [(0.0, 0.0), (95.0, 12.0), (200.0, -12.0), (290.0, 5.0)];

/// One lens of the pair alone, and the state that mounts it as the pair holds it (for the
/// second, the mount turned by the pair's rotation): what that lens alone sees.
fn alone(s: &State, pair: &Lens, side: Side) -> (State, Lens) {
    let name = if side == Side::First {
        "DUALF"
    } else {
        "DUALB"
    };
    let lens = lens_cal()
        .find(name)
        .unwrap()
        .lens()
        .for_frame(FRAME.0, FRAME.1, None);
    let mut s = s.clone();
    if side == Side::Second {
        // lens_from_world = (V M L)^T; the second lens's is Q (V M L)^T = (V M' L)^T.
        let q = DMat3::from_quat(pair.pair.as_ref().unwrap().second_from_first);
        let l = MOUNT_FROM_LENS;
        let m = s.settings.mount.euler().matrix() * l * q.transpose() * l.transpose();
        let e = Euler::from_matrix(&m);
        (
            s.settings.mount.yaw,
            s.settings.mount.pitch,
            s.settings.mount.roll,
        ) = (e.yaw, e.pitch, e.roll);
    }
    (s, lens)
}

/// Views rendered three ways: through the pair (GPU and CPU reference), through the lens
/// that sees each pixel best alone (`one`: the single-lens ground truth), and exactly (the
/// world itself).
struct Rendered {
    plan: FramePlan,
    gpu: RgbImage,
    cpu: RgbImage,
    one: RgbImage,
    truth: RgbImage,
}

/// `views` rendered from the frame lens `drawn` captures, through lens `lens` (the pair as
/// lens.cal has it, which may not be how it was drawn).
fn render(gpu: &Gpu, drawn: &Lens, lens: &Lens, views: [(f64, f64); 4]) -> Rendered {
    render_with(gpu, (drawn, lens), views, Filter::Mip)
}

/// [`render`] with the GPU's filter `filter`.
fn render_with(
    gpu: &Gpu,
    (drawn, lens): (&Lens, &Lens),
    views: [(f64, f64); 4],
    filter: Filter,
) -> Rendered {
    let s = state(views);
    let frame = fisheye(world(), drawn, &s);
    let plan = FramePlan::new(&s, lens).unwrap();
    let mut renderer = renderer_on(gpu, PixelFormat::Rgba, filter);
    let got = render_image(&mut renderer, &frame, &plan).unwrap().to_rgb();
    let mut alone_render = |side| {
        let (s, lens) = alone(&s, drawn, side);
        let plan = FramePlan::new(&s, &lens).unwrap();
        render_image(&mut renderer, &frame, &plan).unwrap().to_rgb()
    };
    let (first, second) = (alone_render(Side::First), alone_render(Side::Second));
    Rendered {
        gpu: got,
        cpu: cpu::render(&plan, &frame, Filter::Mip),
        one: best_of(&plan, drawn, [first, second]),
        truth: truth(world(), &plan, &s),
        plan,
    }
}

/// The single-lens ground truth of `plan` (drawn through `pair`): each pixel from the render
/// through the lens that sees it best alone (`first`, `second`).
fn best_of(plan: &FramePlan, pair: &Lens, [first, second]: [RgbImage; 2]) -> RgbImage {
    let mut one = first;
    let pair = pair.pair.as_ref().unwrap();
    for v in &plan.views {
        for (x, y) in pixels_of(v.rect) {
            let p = DVec2::new((x - v.rect.x) as f64 + 0.5, (y - v.rect.y) as f64 + 0.5);
            let ray = plan.world_ray(v, p).map(|r| plan.lens_from_world * r);
            if ray.is_some_and(|r| pair.best(r).0 == Side::Second) {
                one.put_pixel(x, y, *second.get_pixel(x, y));
            }
        }
    }
    one
}

/// The luma of a pixel (BT.709).
fn luma(img: &RgbImage, p: DVec2) -> f64 {
    bilinear(img, p).dot(DVec3::new(0.2126, 0.7152, 0.0722))
}

/// The shift (pixels) that carries patch `r` of `b` onto `a`, by Lucas-Kanade on luma; None
/// where the patch has too little texture to say.
fn shift(a: &RgbImage, b: &RgbImage, r: Rect) -> Option<DVec2> {
    let mut d = DVec2::ZERO;
    for _ in 0..8 {
        let (mut h, mut g) = (DMat2::ZERO, DVec2::ZERO);
        for y in r.y..r.bottom() {
            for x in r.x..r.right() {
                let p = DVec2::new(x as f64, y as f64);
                let q = p + d;
                let grad = DVec2::new(
                    luma(b, q + DVec2::X) - luma(b, q - DVec2::X),
                    luma(b, q + DVec2::Y) - luma(b, q - DVec2::Y),
                ) * 0.5;
                h += DMat2::from_cols(grad * grad.x, grad * grad.y);
                g += grad * (luma(a, p) - luma(b, q));
            }
        }
        let texture = h.determinant().sqrt() / (r.w * r.h) as f64;
        if texture < 20.0 {
            return None;
        }
        d += h.inverse() * g;
    }
    Some(d)
}

/// The worst shift between `got` and `want` over textured 24x24 patches of a view whose
/// middle looks within 3° of the horizon (the seam), and how many there were.
fn worst_shift(plan: &FramePlan, got: &RgbImage, want: &RgbImage) -> (f64, usize) {
    let mut worst = (0.0f64, 0);
    for v in &plan.views {
        for py in (v.rect.y + 4..v.rect.bottom() - 28).step_by(12) {
            for px in (v.rect.x + 4..v.rect.right() - 28).step_by(12) {
                let mid = DVec2::new((px - v.rect.x + 12) as f64, (py - v.rect.y + 12) as f64);
                let ray = plan.world_ray(v, mid).unwrap();
                if (-ray.z).asin().abs() > 3.0 * DEG {
                    continue;
                }
                if let Some(d) = shift(got, want, Rect::new(px, py, 24, 24)) {
                    worst = (worst.0.max(d.length()), worst.1 + 1);
                }
            }
        }
    }
    worst
}

/// The pixels of a view within 3° of the seam, where the pair blends its lenses (a 4°
/// feather) and both see: what the seam can spoil. Past it a view is drawn from one lens.
fn both_see(plan: &FramePlan, v: &digiview::plan::PlannedView) -> Vec<(u32, u32)> {
    let pair = plan.lens.pair.as_ref().unwrap();
    let r = v.rect;
    let near = |&(x, y): &(u32, u32)| {
        let p = DVec2::new((x - r.x) as f64 + 0.5, (y - r.y) as f64 + 0.5);
        let ray = plan.world_ray(v, p).map(|ray| plan.lens_from_world * ray);
        ray.is_some_and(|ray| pair.best(ray).1.abs() <= 6.0 * DEG)
    };
    pixels_of(r).filter(near).collect()
}

/// Every pixel of a rectangle, row by row.
fn pixels_of(r: Rect) -> impl Iterator<Item = (u32, u32)> {
    (r.y..r.bottom()).flat_map(move |y| (r.x..r.right()).map(move |x| (x, y)))
}

/// PSNR of `a` against `b` over some pixels.
fn psnr_over(a: &RgbImage, b: &RgbImage, pixels: &[(u32, u32)]) -> f64 {
    let sum: f64 = pixels
        .iter()
        .map(|&(x, y)| (pixel(a, x, y) - pixel(b, x, y)).length_squared())
        .sum();
    let mse = sum / (3 * pixels.len()) as f64;
    10.0 * (255.0 * 255.0 / mse.max(1e-12)).log10()
}

/// Each view's PSNR between two renders over the band both lenses see, and over the whole
/// view.
fn scores(r: &Rendered, a: &RgbImage, b: &RgbImage) -> Vec<(f64, f64)> {
    r.plan
        .views
        .iter()
        .map(|v| (psnr_over(a, b, &both_see(&r.plan, v)), psnr(a, b, v.rect)))
        .collect()
}

fn views_across_the_seam_match_ground_truth(gpu: &Gpu) {
    let twisted = pair(2.0 * DEG);
    let r = render(gpu, &twisted, &twisted, ON_THE_SEAM);
    let vs_cpu = psnr(&r.gpu, &r.cpu, whole(&r.gpu));
    let vs_one = scores(&r, &r.gpu, &r.one);
    let (pair_truth, one_truth) = (scores(&r, &r.gpu, &r.truth), scores(&r, &r.one, &r.truth));
    let (shift, patches) = worst_shift(&r.plan, &r.gpu, &r.truth);
    eprintln!(
        "across the seam (band within 3deg, whole view): GPU vs CPU {vs_cpu:.1} dB; against \
         the best lens alone {vs_one:.2?} dB; against truth {pair_truth:.2?} dB (the best lens \
         alone {one_truth:.2?}); worst shift {shift:.3} px over {patches} patches"
    );
    assert!(vs_cpu >= 45.0, "GPU vs CPU reference {vs_cpu:.1} dB");
    assert!(vs_one.iter().all(|&(band, _)| band >= 38.0), "{vs_one:.2?}");
    assert!(
        patches >= 40 && shift <= 0.5,
        "{shift:.3} px over {patches} patches"
    );
    // The negative control: the back lens's 2° twist left out of lens.cal.
    let bad = render(gpu, &twisted, &pair(0.0), ON_THE_SEAM);
    let bad_vs_one = scores(&bad, &bad.gpu, &bad.one);
    let (bad_shift, _) = worst_shift(&bad.plan, &bad.gpu, &bad.truth);
    eprintln!(
        "uncalibrated: against the best lens alone {bad_vs_one:.2?} dB; worst shift {bad_shift:.3} px"
    );
    assert!(
        bad_vs_one.iter().all(|&(band, _)| band < 38.0),
        "{bad_vs_one:.2?}"
    );
    assert!(bad_shift > 0.5, "{bad_shift:.3} px");
    // Straight up (the back lens's centre) as sharp as straight down (the front's), and
    // 60° up as 60° down.
    let ud = render(
        gpu,
        &twisted,
        &twisted,
        [(0.0, 90.0), (0.0, -90.0), (90.0, 60.0), (90.0, -60.0)],
    );
    let ud: Vec<f64> = scores(&ud, &ud.gpu, &ud.truth)
        .iter()
        .map(|s| s.1)
        .collect();
    eprintln!("up, down, 60deg up, 60deg down: against truth {ud:.2?} dB");
    assert!(
        (ud[0] - ud[1]).abs() <= 0.5 && (ud[2] - ud[3]).abs() <= 0.5,
        "{ud:.2?}"
    );
    assert!(ud.iter().all(|&p| p >= 30.0), "{ud:.2?}");
}

on_each_backend!(views_across_the_seam_match_ground_truth);

/// A frame's right half (the second lens's image) made `gain` times as bright.
fn brighter_second(frame: &mut RgbImage, gain: f64) {
    let half = frame.width() / 2;
    for (x, _, p) in frame.enumerate_pixels_mut() {
        if x >= half {
            p.0 = p.0.map(|c| (c as f64 * gain).round().min(255.0) as u8);
        }
    }
}

#[test]
fn the_pair_fit_finds_the_back_lens_turned_2_degrees_from_what_both_lenses_see() {
    let truth = [2.0, 0.4, -0.3];
    let s = state(ON_THE_SEAM);
    let mut frame = fisheye(world(), &posed(truth.map(|a| a * DEG)), &s);
    // The back lens's exposure is not the front's: the fit must not care.
    brighter_second(&mut frame, 1.5);
    let luma = image::DynamicImage::ImageRgb8(frame).to_luma8();
    let fit = fit_pair(&pair(0.0), &luma, |line| eprintln!("{line}")).unwrap();
    let got = fit.rotation.map(f64::to_degrees);
    eprintln!(
        "fitted roll, pitch, yaw {got:.4?}deg (sigma {:.4?}deg) for {truth:?}; rms luma \
         difference {:.2} -> {:.2} over {} rays; gain {:.3}",
        fit.sigma.map(f64::to_degrees),
        fit.before_rms,
        fit.after_rms,
        fit.rays,
        fit.gain
    );
    for (g, t) in got.iter().zip(truth) {
        assert!((g - t).abs() <= 0.05, "{got:.4?} against {truth:?}");
    }
    assert!(fit.after_rms < fit.before_rms / 3.0);
}

/// `digiview` with the lens.cal at `cal`.
fn digiview(args: &[&str], cal: &std::path::Path) -> std::process::Output {
    let out = super::cli::digiview(args, cal);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "digiview {args:?}: {err}");
    out
}

#[test]
fn synth_dual_then_pair_fit_write_then_render_looks_straight_up() {
    let dir = tempfile::tempdir().unwrap();
    let cal = dir.path().join("lens.cal");
    std::fs::copy(super::cli::shipped(), &cal).unwrap();
    let pano = dir.path().join("pano.png");
    world().image.save(&pano).unwrap();
    let (frame, up) = (dir.path().join("pair.png"), dir.path().join("up.png"));
    let p = |p: &std::path::Path| p.to_str().unwrap().to_string();
    digiview(
        &[
            "synth",
            "--dual",
            "--world",
            &p(&pano),
            "--size",
            "1920x960",
        ]
        .into_iter()
        .chain([
            "--pair-rotation",
            "2deg,0.4deg,-0.3deg",
            "--out",
            &p(&frame),
        ])
        .collect::<Vec<_>>(),
        &cal,
    );
    assert_eq!(image::image_dimensions(&frame).unwrap(), (1920, 960));
    let fit = digiview(
        &["lens", "pair-fit", "DUAL", "--frame", &p(&frame), "--write"],
        &cal,
    );
    let said = String::from_utf8_lossy(&fit.stdout);
    eprintln!("{said}");
    let angle = |name: &str| -> f64 {
        let after = said.split(&format!("{name} ")).nth(1).unwrap();
        after.split("deg").next().unwrap().parse().unwrap()
    };
    let got = [angle("roll"), angle("pitch"), angle("yaw")];
    for (g, want) in got.iter().zip([2.0, 0.4, -0.3]) {
        assert!((g - want).abs() <= 0.05, "{said}");
    }
    let shown = digiview(&["lens", "show", "DUAL"], &cal);
    let shown = String::from_utf8_lossy(&shown.stdout);
    assert!(shown.contains("rotation = [\"1.99") || shown.contains("rotation = [\"2.00"));
    assert!(shown.contains("by = \"digiview lens pair-fit\""), "{shown}");
    digiview(&["lens", "check", "DUAL"], &cal);
    // Straight up, through the back lens: the sky of the panorama, not black.
    digiview(
        &[
            "render",
            "--input",
            &p(&frame),
            "--lens",
            "DUAL",
            "--layout",
            "0",
        ]
        .into_iter()
        .chain([
            "--cam",
            "0:pitch=90deg,fov=90deg,lock=7",
            "--backend",
            "cpu",
        ])
        .chain(["--size", "640x480", "--out", &p(&up)])
        .collect::<Vec<_>>(),
        &cal,
    );
    let up = image::open(&up).unwrap().to_rgb8();
    // The view's middle (the frame's sides are the layout's bars).
    let middle = image::imageops::crop_imm(&up, 120, 60, 360, 360).to_image();
    let black = middle
        .pixels()
        .filter(|p| p.0.iter().all(|&c| c < 8))
        .count();
    assert!(black < 100, "{black} black pixels of {}", 360 * 360);
}
