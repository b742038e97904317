//! Lens calibration from a board, against known truth: the printed AprilGrid is found again
//! by the detector with every corner in place, in fisheye frames too; corners a known lens
//! projects are fitted back to it; and the whole loop (render, find, fit) recovers each
//! shipped lens.

use crate::common;

use common::worst_gap;
use digiview::lens::calibrate::{Board, Finder};
use glam::DVec2;

/// The shipped lens.cal.
fn shipped() -> digiview::lens::LensCal {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/lens-cal/lens.cal");
    digiview::lens::LensCal::load(std::path::Path::new(path)).unwrap()
}

#[test]
fn the_printed_board_is_found_with_every_corner_in_place() {
    let board = Board::parse("cols=6,rows=5,tag=88mm,spacing=0.3").unwrap();
    let dots = 1500.0; // 132 px a tag
    let picture = board.picture(dots);
    let (low, high) = board.extent();
    let found = Finder::new(board).find(&image::DynamicImage::ImageLuma8(picture));
    assert_eq!(
        found.len(),
        30,
        "tags found: {:?}",
        found.iter().map(|s| s.id).collect::<Vec<_>>()
    );
    let mut worst: f64 = 0.0;
    for s in &found {
        for (img, on_board) in s.image.iter().zip(s.board) {
            let want =
                DVec2::new(on_board.x - low.x, high.y - on_board.y) * dots - DVec2::splat(0.5);
            worst = worst.max(img.distance(want));
        }
    }
    println!("worst corner error {worst:.3} px");
    assert!(worst < 0.2, "worst corner {worst:.3} px off");
}

/// The board as a fisheye lens sees it, straight ahead and far off the axis: the tags found
/// have their corners where the lens projects the board's corners.
#[test]
fn the_board_is_found_in_fisheye_frames_where_the_lens_puts_it() {
    use digiview::scene::board::{BoardPose, board_fisheye};
    let cal = shipped();
    let lens = cal
        .find("CIL216")
        .unwrap()
        .lens()
        .for_frame(1920, 1080, None);
    let board = Board::parse("cols=6,rows=6,tag=60mm,spacing=0.3").unwrap();
    let finder = Finder::new(board);
    // Partly past the image circle at 70° and beyond: fewer tags, still where they belong.
    for (off_axis, distance, least) in [
        (0.0f64, 0.6, 36),
        (50.0, 0.5, 36),
        (70.0, 0.8, 30),
        (85.0, 1.0, 12),
    ] {
        let a = off_axis.to_radians();
        let direction = glam::DVec3::new(a.sin(), 0.0, a.cos());
        let pose = BoardPose::facing(&board, direction, distance, glam::DVec2::ZERO, 0.2);
        let frame = board_fisheye(&board, &pose, &lens, 3);
        let found = finder.find(&image::DynamicImage::ImageRgb8(frame));
        let mut worst: f64 = 0.0;
        for s in &found {
            for (img, on_board) in s.image.iter().zip(s.board) {
                let want = lens.project(pose.to_lens(on_board)).unwrap();
                worst = worst.max(img.distance(want));
            }
        }
        println!(
            "{off_axis}° off the axis: {} tags, worst corner {worst:.3} px",
            found.len()
        );
        assert!(found.len() >= least, "{off_axis}°: {} tags", found.len());
        assert!(worst < 0.5, "{off_axis}°: worst corner {worst:.3} px off");
    }
}

/// `digiview lens board` writes a board the detector reads back whole, says how big it prints,
/// and refuses a spec it cannot draw with the reason.
#[test]
fn lens_board_draws_a_board_to_print_and_refuses_bad_specs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("board.png");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
            .args(["lens", "board"])
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&[
        "--board",
        "cols=5,rows=4,tag=40mm",
        "--dpi",
        "150",
        "--out",
        out.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // 5 tags and 5 gaps of 12 mm and a 24 mm margin and 12 mm: 5 x 52 + 12 + 24 = 296 mm.
    assert!(said.contains("296.0 x 244.0 mm"), "{said}");
    let picture = image::open(&out).unwrap();
    let board = Board::parse("cols=5,rows=4,tag=40mm").unwrap();
    assert_eq!(
        Finder::new(board).find(&picture).len(),
        20,
        "every tag read back"
    );
    // Another format is refused, not written as PNG under its name.
    let bmp = dir.path().join("board.bmp");
    let o = run(&[
        "--board",
        "cols=5,rows=4,tag=40mm",
        "--out",
        bmp.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains(".png"), "{err}");
    assert!(!bmp.exists());
    for (spec, why) in [
        ("cols=5,rows=4", "cols, rows and tag are needed"),
        ("cols=5,rows=1,tag=40mm", "at least 2x2"),
        ("cols=30,rows=30,tag=40mm", "at most 587 tags"),
        ("cols=5,rows=4,tag=-4mm", "is not a length"),
        ("cols=5,rows=4,tag=4mm,spacing=3", "spacing 3 is outside"),
        ("cols=5,rows=4,tag=4mm,size=3", "no field `size`"),
    ] {
        let o = run(&["--board", spec, "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(why), "{spec}: {err}");
    }
    let o = run(&[
        "--board",
        "cols=5,rows=4,tag=4m",
        "--dpi",
        "1200",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("lower --dpi"));
}

/// The truth: the Kannala-Brandt sample lens (non-zero k1..k4, 195°, 1280x960).
fn kb_truth() -> digiview::lens::Lens {
    use digiview::lens::models::KannalaBrandt;
    use digiview::lens::{Model, PixelAffine};
    digiview::lens::Lens::new(
        "truth",
        9,
        Model::KannalaBrandt(KannalaBrandt {
            k: [0.0423, -0.0126, 0.0031, -0.0004],
        }),
        PixelAffine::pinhole(290.0, 290.58, 641.3, 479.2),
        (1280, 960),
        195f64.to_radians(),
    )
}

/// Board poses spread over the image circle: the centre, then rings 35°, 60° and 80° off the
/// axis, tilted and spun differently each.
fn spread_poses(board: &Board) -> Vec<digiview::scene::board::BoardPose> {
    use digiview::scene::board::BoardPose;
    let mut poses = vec![];
    for (ring, (off, count, distance)) in [
        (0.0f64, 2, 0.6),
        (35.0, 6, 0.7),
        (60.0, 8, 0.8),
        (80.0, 8, 1.0),
    ]
    .into_iter()
    .enumerate()
    {
        for i in 0..count {
            let azimuth = (i as f64 + 0.5 * ring as f64) * std::f64::consts::TAU / count as f64;
            let a = off.to_radians();
            let direction =
                glam::DVec3::new(a.sin() * azimuth.cos(), a.sin() * azimuth.sin(), a.cos());
            let tilt =
                glam::DVec2::new(0.35 * (i as f64 * 1.7).sin(), 0.35 * (i as f64 * 2.3).cos());
            poses.push(BoardPose::facing(
                board,
                direction,
                distance,
                tilt,
                0.4 * i as f64,
            ));
        }
    }
    poses
}

/// The corners of boards at spread poses as `truth` projects them, with ±0.15 px of
/// deterministic jitter, and the widest angle off the axis they reach.
fn jittered_corners(
    truth: &digiview::lens::Lens,
    board: &Board,
) -> (Vec<digiview::lens::calibrate::fit::Frame>, f64) {
    let mut seed = 12345u64;
    let mut jitter = move |noise: f64| {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * noise
    };
    let mut frames = vec![];
    let mut widest: f64 = 0.0;
    for pose in spread_poses(board) {
        let mut frame = digiview::lens::calibrate::fit::Frame::default();
        for id in 0..board.tags() {
            for corner in board.corners(id).unwrap() {
                let x = pose.to_lens(corner);
                let theta = x.truncate().length().atan2(x.z);
                let Some(q) = truth.project(x).filter(|q| truth.in_frame(*q)) else {
                    continue;
                };
                widest = widest.max(theta);
                frame.board.push(corner);
                frame
                    .image
                    .push(q + glam::DVec2::new(jitter(0.15), jitter(0.15)));
            }
        }
        if frame.board.len() >= 8 {
            frames.push(frame);
        }
    }
    (frames, widest)
}

/// Fits `model` to jittered corners of `truth` (1280x960, pinhole `fx, fy, cx, cy`): focal
/// lengths within 0.5%, principal point within 1 px, RMS under 0.3 px, every ray within 1 px
/// of the truth over the corners' field of view. Returns the fit.
fn fitted_back(
    truth: &digiview::lens::Lens,
    model: digiview::lens::calibrate::fit::FitModel,
    (fx, fy, cx, cy): (f64, f64, f64, f64),
) -> digiview::lens::calibrate::fit::Fit {
    use digiview::lens::calibrate::fit::fit;
    let board = Board::parse("cols=6,rows=6,tag=60mm,spacing=0.3").unwrap();
    let (frames, widest) = jittered_corners(truth, &board);
    let t = std::time::Instant::now();
    let got = fit(model, &frames, (1280, 960), |_| {}).unwrap();
    println!(
        "{} frames: fx {:.3} fy {:.3} cx {:.3} cy {:.3} {:?}; RMS {:.3} px, worst {:.3}, {} dropped, {:?}",
        frames.len(),
        got.fx,
        got.fy,
        got.cx,
        got.cy,
        got.model,
        got.rms,
        got.worst,
        got.dropped,
        t.elapsed()
    );
    assert!((got.fx / fx - 1.0).abs() < 0.005 && (got.fy / fy - 1.0).abs() < 0.005);
    assert!((got.cx - cx).abs() < 1.0 && (got.cy - cy).abs() < 1.0);
    assert!(got.rms < 0.3, "RMS {:.3}", got.rms);
    let fitted = got.lens("fitted", 9, (1280, 960), 195f64.to_radians());
    let gap = worst_gap(&fitted, truth, widest);
    println!(
        "worst gap to the truth within {:.1}° of the axis: {gap:.3} px",
        widest.to_degrees()
    );
    assert!(gap < 1.0, "{gap:.3} px");
    got
}

#[test]
fn a_kannala_brandt_lens_is_fitted_back_from_board_corners() {
    use digiview::lens::calibrate::fit::FitModel;
    fitted_back(
        &kb_truth(),
        FitModel::KannalaBrandt,
        (290.0, 290.58, 641.3, 479.2),
    );
}

/// The same with the Double Sphere model, truth and fit alike: ξ and α come back too.
#[test]
fn a_double_sphere_lens_is_fitted_back_from_board_corners() {
    use digiview::lens::calibrate::fit::FitModel;
    use digiview::lens::models::DoubleSphere;
    use digiview::lens::{Model, PixelAffine};
    let (xi, alpha) = (-0.2, 0.59);
    let truth = digiview::lens::Lens::new(
        "truth",
        9,
        Model::DoubleSphere(DoubleSphere { xi, alpha }),
        PixelAffine::pinhole(245.0, 245.4, 641.3, 479.2),
        (1280, 960),
        195f64.to_radians(),
    );
    let got = fitted_back(&truth, FitModel::DoubleSphere, (245.0, 245.4, 641.3, 479.2));
    let Model::DoubleSphere(ds) = got.model else {
        panic!("{:?}", got.model)
    };
    assert!(
        (ds.xi - xi).abs() < 0.01 && (ds.alpha - alpha).abs() < 0.01,
        "{ds:?}"
    );
}

/// The whole loop on each shipped fisheye lens as the truth: boards rendered at poses spread over the
/// image circle, found by the detector, fitted with Kannala-Brandt: focal lengths within 0.5%,
/// principal point within 1 px, RMS under 0.3 px, and within 1 px of the truth lens over the
/// field of view the corners cover.
#[test]
fn the_shipped_lenses_are_calibrated_back_from_rendered_boards() {
    use digiview::lens::calibrate::fit::{FitModel, Frame, fit};
    use digiview::scene::board::board_fisheye;
    let cal = shipped();
    let board = Board::parse("cols=6,rows=6,tag=60mm,spacing=0.3").unwrap();
    let finder = Finder::new(board);
    // The fisheyes of the 16:9 frames this draws: the thermal core's narrow lens (a pinhole)
    // is no Kannala-Brandt fit's, and the dual rig's lenses map into a 2:1 frame.
    let fisheyes = cal.entries.iter().filter(|e| {
        let pinhole = matches!(
            e.lens().radial.model,
            digiview::lens::models::Model::Pinhole(_)
        );
        !pinhole && e.width * 9 == e.height * 16
    });
    for entry in fisheyes {
        let truth = entry.lens().for_frame(1280, 720, None);
        let t = std::time::Instant::now();
        let mut frames = vec![];
        let mut widest: f64 = 0.0;
        for pose in spread_poses(&board) {
            let picture = board_fisheye(&board, &pose, &truth, 2);
            let found = finder.find(&image::DynamicImage::ImageRgb8(picture));
            for s in &found {
                for b in s.board {
                    let x = pose.to_lens(b);
                    widest = widest.max(x.truncate().length().atan2(x.z));
                }
            }
            if found.len() >= 2 {
                frames.push(Frame::from_sightings(&found));
            }
        }
        let found_in = t.elapsed();
        let got = fit(FitModel::KannalaBrandt, &frames, (1280, 720), |_| {}).unwrap();
        let (fx, fy, cx, cy) = match truth.affine.matrix.to_cols_array() {
            [fx, 0.0, 0.0, fy] => (fx, fy, truth.affine.offset.x, truth.affine.offset.y),
            m => panic!("{}: not a pinhole affine {m:?}", entry.name),
        };
        let fitted = got.lens("fitted", 9, (1280, 720), truth.half_fov * 2.0);
        let gap = worst_gap(&fitted, &truth, widest);
        println!(
            "{}: {} frames found in {found_in:?}; fx {:.2} ({fx:.2}) fy {:.2} ({fy:.2}) cx {:.2} ({cx:.2}) \
             cy {:.2} ({cy:.2}); RMS {:.3} px, worst {:.3}, {} dropped; within {:.1}°: {gap:.3} px off",
            entry.name,
            frames.len(),
            got.fx,
            got.fy,
            got.cx,
            got.cy,
            got.rms,
            got.worst,
            got.dropped,
            widest.to_degrees()
        );
        assert!(
            (got.fx / fx - 1.0).abs() < 0.005 && (got.fy / fy - 1.0).abs() < 0.005,
            "{}",
            entry.name
        );
        assert!(
            (got.cx - cx).abs() < 1.0 && (got.cy - cy).abs() < 1.0,
            "{}",
            entry.name
        );
        assert!(got.rms < 0.3, "{}: RMS {:.3}", entry.name, got.rms);
        assert!(gap < 1.0, "{}: {gap:.3} px", entry.name);
    }
}

/// `digiview lens calibrate` on a directory of frames: the entry it prints is the truth lens
/// (LN007) to within a pixel, frames without the board are named and skipped, and two frames
/// are refused as too few.
#[test]
fn lens_calibrate_turns_a_directory_of_frames_into_an_entry() {
    use digiview::scene::board::{BoardPose, board_fisheye};
    let truth = shipped()
        .find("LN007")
        .unwrap()
        .lens()
        .for_frame(1280, 720, None);
    let board = Board::parse("cols=6,rows=6,tag=60mm,spacing=0.3").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut poses = spread_poses(&board);
    // Three frames with the board behind the camera: nothing to find.
    for _ in 0..3 {
        poses.push(BoardPose::facing(
            &board,
            -glam::DVec3::Z,
            1.0,
            glam::DVec2::ZERO,
            0.0,
        ));
    }
    for (i, pose) in poses.iter().enumerate() {
        let picture = board_fisheye(&board, pose, &truth, 2);
        picture
            .save(dir.path().join(format!("frame{i:03}.png")))
            .unwrap();
    }
    let run = |dir: &std::path::Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
            .args([
                "lens",
                "calibrate",
                "--board",
                "cols=6,rows=6,tag=60mm",
                "--name",
                "MINE",
            ])
            .args(["--id", "7", "--images", dir.to_str().unwrap()])
            .output()
            .unwrap()
    };
    let o = run(dir.path());
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    println!("{err}");
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("no board in 3 frames: frame024.png, frame025.png, frame026.png"),
        "{err}"
    );
    let cal = digiview::lens::LensCal::parse(std::path::Path::new("(out)"), &out).unwrap();
    let e = &cal.entries[0];
    assert_eq!(
        (e.name.as_str(), e.lens_id, e.provenance.kind.as_str()),
        ("MINE", 7, "calibrated")
    );
    assert!(
        e.provenance.rms_px.is_some_and(|r| r < 0.3),
        "{:?}",
        e.provenance
    );
    let gap = worst_gap(&e.lens(), &truth, 85f64.to_radians());
    println!("the entry is within {gap:.3} px of LN007 over 85° off the axis");
    assert!(gap < 1.0, "{gap:.3} px");

    // Boards only near the middle: an entry, with warnings naming what is not covered.
    let middle = tempfile::tempdir().unwrap();
    for i in 0..8 {
        let name = format!("frame{i:03}.png");
        std::fs::copy(dir.path().join(&name), middle.path().join(&name)).unwrap();
    }
    let o = run(middle.path());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: no corners in the outer third of the circle at azimuths 0-45°"),
        "{err}"
    );
    assert!(err.contains("the lens is extrapolated"), "{err}");

    // Two frames are too few.
    let few = tempfile::tempdir().unwrap();
    for i in 0..2 {
        std::fs::copy(
            dir.path().join(format!("frame{i:03}.png")),
            few.path().join(format!("{i}.png")),
        )
        .unwrap();
    }
    let o = run(few.path());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("2 frames with the board: at least 3"),
        "{err}"
    );
}
