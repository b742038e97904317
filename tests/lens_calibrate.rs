//! Lens calibration from a board: the printed AprilGrid is found again by the detector, every
//! tag at its place, corners to a tenth of a pixel.

use digiview::lens::calibrate::{Board, Finder};
use glam::DVec2;

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
    let cal = digiview::lens::LensCal::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/lens-cal/lens.cal"
    )))
    .unwrap();
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
