//! The whole calibration loop through the command line, as a user runs it: `synth --board`
//! draws the board before a shipped lens at poses spread over the circle, the frames are
//! blurred, made noisy, interleaved with frames that lack the board and encoded to an MP4,
//! and `lens calibrate --video` gives the lens back.

use crate::common;

use common::worst_gap;
use image::{GrayImage, Luma};
use std::path::Path;
use std::process::{Command, Output};

const BOARD: &str = "cols=6,rows=6,tag=60mm,spacing=0.3";

fn digiview(args: &[&str]) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(args)
        .output()
        .unwrap();
    println!(
        "$ digiview {}\n{}",
        args.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// A deterministic noise source: uniform in ±`amplitude`.
struct Noise(u64);

impl Noise {
    fn next(&mut self, amplitude: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * amplitude
    }
}

/// `picture` blurred (σ 0.8 px) with ±6 grey levels of noise on each pixel.
fn degrade(picture: &GrayImage, noise: &mut Noise) -> GrayImage {
    let mut out = image::imageops::blur(picture, 0.8);
    for p in out.pixels_mut() {
        p.0[0] = (p.0[0] as f64 + noise.next(6.0)).round().clamp(0.0, 255.0) as u8;
    }
    out
}

/// LN007 as the truth: 24 board frames from `synth --board-sweep`, blurred and noisy, with a
/// frame lacking the board after every two, in an H.264 MP4. `lens calibrate --video` finds
/// the board in (almost) all 24, names the 12 without it, fits 20 spread ones and gives an entry with
/// focal lengths within 0.5%, principal point within 1 px, RMS under 0.3 px and every ray
/// within 1 px of LN007 over 85° off the axis.
#[test]
fn a_noisy_blurred_video_with_frames_lacking_the_board_gives_the_lens_back() {
    let dir = tempfile::tempdir().unwrap();
    let drawn = dir.path().join("drawn");
    std::fs::create_dir(&drawn).unwrap();
    let pattern = format!("{}/%03d.png", drawn.display());
    let common = [
        "synth", "--lens", "LN007", "--size", "1280x720", "--board", BOARD,
    ];
    let o = digiview(&[&common[..], &["--board-sweep", "24", "--out", &pattern]].concat());
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("wrote 24 frames of the board"));

    // One pose by hand; a pose without its distance, and many poses into one file, refused.
    let one = dir.path().join("one.png");
    let pose = "off=70deg,azimuth=200deg,distance=80cm,tilt=20deg,spin=10deg";
    let o = digiview(
        &[
            &common[..],
            &["--board-pose", pose, "--out", one.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success() && one.is_file());
    let o = digiview(
        &[
            &common[..],
            &["--board-pose", "off=10deg,azimuth=0", "--out", "x.png"],
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("off, azimuth and distance are needed"),
        "{err}"
    );
    let o = digiview(&[&common[..], &["--board-sweep", "3", "--out", "x.png"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("number --out's files"),
        "{err}"
    );

    // Blur, noise, and a frame without the board after every two.
    let sequence = dir.path().join("sequence");
    std::fs::create_dir(&sequence).unwrap();
    let mut noise = Noise(7);
    let blank = GrayImage::from_pixel(1280, 720, Luma([115]));
    for i in 0..36 {
        let picture = match i % 3 {
            2 => blank.clone(),
            _ => image::open(drawn.join(format!("{:03}.png", i / 3 * 2 + i % 3)))
                .unwrap()
                .to_luma8(),
        };
        degrade(&picture, &mut noise)
            .save(sequence.join(format!("{i:03}.png")))
            .unwrap();
    }
    let clip = dir.path().join("board.mp4");
    common::encode_sequence(&sequence, &clip, 16);

    let o = digiview(&[
        "lens",
        "calibrate",
        "--video",
        clip.to_str().unwrap(),
        "--board",
        BOARD,
        "--name",
        "MINE",
        "--id",
        "7",
        "--max-frames",
        "20",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // Every blank frame is named; a board at the rim may be lost to the blur now and then.
    let found: usize = err
        .split("board found in ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap();
    assert!((22..=24).contains(&found), "{err}");
    let without = err.lines().find(|l| l.starts_with("no board in")).unwrap();
    assert!(
        without.starts_with(&format!("no board in {} frames:", 36 - found)),
        "{err}"
    );
    for i in (2..36).step_by(3) {
        let name = format!("frame {i} ({:.2} s)", i as f64 / 10.0);
        assert!(without.contains(&name), "{name} not in {without}");
    }
    assert!(err.contains("fitting 20 of them"), "{err}");
    let out = String::from_utf8_lossy(&o.stdout);
    let cal = digiview::lens::LensCal::parse(Path::new("(out)"), &out).unwrap();
    let e = &cal.entries[0];
    let truth = common::lens_cal()
        .find("LN007")
        .unwrap()
        .lens()
        .for_frame(1280, 720, None);
    let got = e.lens();
    let pinhole = |l: &digiview::lens::Lens| {
        let m = l.affine.matrix.to_cols_array();
        (m[0], m[3], l.affine.offset.x, l.affine.offset.y)
    };
    let ((fx, fy, cx, cy), (tfx, tfy, tcx, tcy)) = (pinhole(&got), pinhole(&truth));
    println!(
        "fx {fx:.2} ({tfx:.2}) fy {fy:.2} ({tfy:.2}) cx {cx:.2} ({tcx:.2}) cy {cy:.2} ({tcy:.2})"
    );
    assert!((fx / tfx - 1.0).abs() < 0.005 && (fy / tfy - 1.0).abs() < 0.005);
    assert!((cx - tcx).abs() < 1.0 && (cy - tcy).abs() < 1.0);
    let rms = e.provenance.rms_px.unwrap();
    assert!(rms < 0.3, "RMS {rms}");
    let gap = worst_gap(&got, &truth, 85f64.to_radians());
    println!("RMS {rms:.3} px; within {gap:.3} px of LN007 over 85° off the axis");
    assert!(gap < 1.0, "{gap:.3} px");
}
