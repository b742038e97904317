//! FFmpeg's `v360 input=dfisheye` beside the pair (issue 59): the same synthetic pair (the
//! back lens twisted 2° from back to back, left out of what v360 is told, as it has no way to
//! be told), the same views, each against the ground truth. v360 takes each lens as an
//! f-theta lens whose field (`ih_fov`, `iv_fov`: here 197°, the field the lens's scale puts
//! across its half of the frame) is centred in its half, and splits the sphere at the plane between the lenses: no
//! calibration, no blend, no exposure match. Its aim for each view is worked out from the
//! view's own rays, and checked before any figure is taken: on a frame whose pixels carry
//! their own coordinates, v360 (nearest neighbour) samples, away from its split, the pixel the
//! pair projects the same ray to.

use super::*;
use image::imageops::crop_imm;
use std::path::Path;
use std::process::Command;

/// Where v360 looks for a view, in its options' degrees, and the field it is told fills each
/// half of the frame's width (and height).
struct Aim {
    yaw: f64,
    pitch: f64,
    roll: f64,
    in_fov: f64,
}

/// A ray in the first lens's frame in v360's (x right, y down, z forward of its unturned
/// view): its unturned view looks along the second lens's axis with that image's right and
/// down (an FFmpeg probe: it samples the right half's centre, and its right and down are the
/// image's), so the first lens's frame turned half round its down axis.
fn in_v360(r: DVec3) -> DVec3 {
    DVec3::new(-r.x, r.y, -r.z)
}

/// v360's yaw, pitch and roll for view `v` of `plan`: its rotation R (view rays to v360's
/// frame) is yaw about down (right positive), then pitch about right (up positive), then
/// roll about forward (right to down positive), R = Ry Rx Rz, as its rotation matrix is built.
fn aim(plan: &FramePlan, v: &digiview::plan::PlannedView, pair: &Lens) -> Aim {
    let ray = |x: f64, y: f64| {
        let r = plan.world_ray(v, DVec2::new(x, y)).unwrap();
        in_v360(plan.lens_from_world * r)
    };
    let (cx, cy) = (v.rect.w as f64 / 2.0, v.rect.h as f64 / 2.0);
    let z = ray(cx, cy).normalize();
    let right = ray(cx + 1.0, cy).normalize() - z;
    let x = (right - z * right.dot(z)).normalize();
    let y = z.cross(x);
    let first = &pair.pair.as_ref().unwrap().first;
    // Pixels per radian: v360's r = theta / in_fov * half width.
    let f = first
        .project(DVec3::new(0.1f64.sin(), 0.0, 0.1f64.cos()))
        .unwrap()
        .x
        - first.project(DVec3::Z).unwrap().x;
    let half = (pair.width / 2) as f64;
    // Straight along v360's down axis yaw and roll turn alike: roll 0 then.
    let (yaw, roll) = match (1.0 - z.y * z.y).sqrt() < 1e-6 {
        true => ((-x.z).atan2(x.x), 0.0),
        false => (z.x.atan2(z.z), x.y.atan2(y.y)),
    };
    Aim {
        yaw: yaw.to_degrees(),
        pitch: (-z.y).clamp(-1.0, 1.0).asin().to_degrees(),
        roll: roll.to_degrees(),
        in_fov: (half / (f / 0.1)).to_degrees(),
    }
}

/// v360 drawing the view `a` aims at, `w`x`h` with a horizontal field of `hfov` degrees, from
/// the dual-fisheye frame `input`.
fn v360(input: &Path, a: &Aim, (w, h): (u32, u32), hfov: f64, interp: &str) -> RgbImage {
    let vfov = 2.0 * ((hfov / 2.0).to_radians().tan() * h as f64 / w as f64).atan();
    let filter = format!(
        "v360=input=dfisheye:output=flat:interp={interp}:ih_fov={:.6}:iv_fov={0:.6}:w={w}:\
         h={h}:h_fov={hfov}:v_fov={:.6}:yaw={:.6}:pitch={:.6}:roll={:.6}",
        a.in_fov,
        vfov.to_degrees(),
        a.yaw,
        a.pitch,
        a.roll
    );
    let out = input.with_file_name(format!("v360-{interp}.png"));
    let done = Command::new("ffmpeg")
        .args(["-hide_banner", "-v", "error", "-y", "-i"])
        .arg(input)
        .args(["-vf", &filter, "-pix_fmt", "rgb24"])
        .arg(&out)
        .output()
        .expect("ffmpeg runs");
    assert!(done.status.success(), "{filter}: {done:?}");
    image::open(&out).unwrap().to_rgb8()
}

/// A frame whose pixels carry their own coordinates: red and green the low bytes of column
/// and row, blue their high nibbles.
fn coded(w: u32, h: u32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x % 256) as u8,
            (y % 256) as u8,
            ((x / 256) * 16 + y / 256) as u8,
        ])
    })
}

/// The frame pixel a pixel of `coded` came from.
fn decoded(p: &image::Rgb<u8>) -> DVec2 {
    let [r, g, b] = p.0.map(u32::from);
    DVec2::new((r + 256 * (b / 16)) as f64, (g + 256 * (b % 16)) as f64)
}

/// The farthest (pixels) v360's samples of view `v` lie from where `pair` projects the same
/// rays, over the view's pixels more than 5° from v360's split; and how many there were.
fn aim_error(
    dir: &Path,
    plan: &FramePlan,
    v: &digiview::plan::PlannedView,
    pair: &Lens,
) -> (f64, usize) {
    // One coded frame serves every view (the pair, so its frame, is the same for all).
    let input = dir.join("coded.png");
    if !input.exists() {
        coded(pair.width, pair.height).save(&input).unwrap();
    }
    let size = (v.rect.w, v.rect.h);
    let a = aim(plan, v, pair);
    let got = v360(&input, &a, size, 90.0, "near");
    let p = pair.pair.as_ref().unwrap();
    let mut worst = (0.0f64, 0);
    for (x, y) in pixels_of(Rect::new(0, 0, size.0, size.1)) {
        let ray = plan.world_ray(v, DVec2::new(x as f64 + 0.5, y as f64 + 0.5));
        let r = plan.lens_from_world * ray.unwrap();
        let want = match in_v360(r).z {
            z if z > 5f64.to_radians().sin() => p.second.project(p.second_from_first * r),
            z if z < -5f64.to_radians().sin() => p.first.project(r),
            _ => continue,
        };
        let off = (decoded(got.get_pixel(x, y)) - want.unwrap())
            .abs()
            .max_element();
        worst = (worst.0.max(off), worst.1 + 1);
    }
    worst
}

/// Against the ground truth, dB, each of `views`: the pair as calibrated, the pair left
/// uncalibrated (lens.cal's nominal pose), and v360 on the same frame; the farthest v360's
/// aim is from the pair's projection, pixels.
fn scored(gpu: &Gpu, dir: &Path, views: [(f64, f64); 4]) -> (Vec<[f64; 3]>, f64) {
    let twisted = pair(2.0 * DEG);
    let nominal = pair(0.0);
    // Both drawn with one bilinear sample per pixel, as v360's `line`.
    let seam = render_with(gpu, (&twisted, &twisted), views, Filter::Bilinear);
    let blind = render_with(gpu, (&twisted, &nominal), views, Filter::Bilinear);
    let input = dir.join("pair.png");
    fisheye(world(), &twisted, &state(views))
        .save(&input)
        .unwrap();
    let (mut rows, mut worst) = (vec![], 0.0f64);
    for (i, v) in seam.plan.views.iter().enumerate() {
        // v360 aimed where the view looks, first checked against the pair's own projection.
        let (off, n) = aim_error(dir, &seam.plan, v, &nominal);
        assert!(
            n > 1000 && off <= 1.0,
            "view {i}: v360's samples {off:.2} px off ({n})"
        );
        worst = worst.max(off);
        let crop =
            |img: &RgbImage| crop_imm(img, v.rect.x, v.rect.y, v.rect.w, v.rect.h).to_image();
        let size = (v.rect.w, v.rect.h);
        let theirs = v360(&input, &aim(&seam.plan, v, &nominal), size, 90.0, "line");
        let truth = crop(&seam.truth);
        let score = |img: &RgbImage| psnr(img, &truth, Rect::new(0, 0, size.0, size.1));
        rows.push([
            score(&crop(&seam.gpu)),
            score(&crop(&blind.gpu)),
            score(&theirs),
        ]);
    }
    eprintln!("against truth, dB: [calibrated pair, uncalibrated pair, v360 dfisheye]");
    for (view, row) in views.iter().zip(&rows) {
        eprintln!("  yaw {:5.1} pitch {:5.1}: {row:.2?}", view.0, view.1);
    }
    (rows, worst)
}

#[test]
fn ffmpegs_v360_on_the_same_uncalibrated_pair_shows_the_seam_the_pair_hides() {
    let gpu = gpu();
    let dir = tempfile::tempdir().unwrap();
    // Away from the seam each lens alone sees the view: v360 draws it as the pair left
    // uncalibrated does (the comparison is like for like).
    let (away, off_away) = scored(
        &gpu,
        dir.path(),
        [(0.0, 90.0), (0.0, -90.0), (90.0, 60.0), (90.0, -60.0)],
    );
    for (i, [_, ours, theirs]) in away.iter().enumerate() {
        assert!(
            (ours - theirs).abs() <= 2.5,
            "view {i}: ours {ours:.2} dB, v360 {theirs:.2} dB"
        );
    }
    // Across the seam v360 shows the twist no one told it of; the calibrated pair does not.
    let (seam, off_seam) = scored(&gpu, dir.path(), ON_THE_SEAM);
    eprintln!(
        "v360's aim within {:.2} px of the pair's projection",
        off_away.max(off_seam)
    );
    for (i, [ours, _, theirs]) in seam.iter().enumerate() {
        assert!(
            ours - theirs >= 3.0,
            "view {i}: ours {ours:.2} dB, v360 {theirs:.2} dB"
        );
    }
}
