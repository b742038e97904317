//! `digiview render` on videos and image sequences: a synthetic fisheye clip (the grid world
//! with its moving objects, encoded to H.264 MP4 by GStreamer) is dewarped to an MP4 and to a
//! PNG sequence; frame counts, sizes and the picture against ground truth are checked, and
//! missing or corrupt inputs give clear errors.

use crate::common;

use common::{four_view_state, landmark_matches, probe_frames, small_lens};
use digiview::image_ops::psnr;
use digiview::layout::Rect;
use digiview::plan::FramePlan;
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use image::RgbImage;
use std::path::Path;
use std::process::{Command, Output};

const FRAMES: u32 = 6;

fn digiview(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(args)
        .env(
            "DIGIVIEW_LENS_CAL",
            Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal"),
        )
        .output()
        .unwrap()
}

#[test]
fn a_fisheye_clip_renders_to_mp4_and_to_an_image_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let state = four_view_state(7);
    let lens = small_lens("CIL216");
    // The clip: the world at 1 s steps (its objects move), 1280x720, 10 fps.
    let seq = dir.path().join("fish");
    std::fs::create_dir_all(&seq).unwrap();
    for i in 0..FRAMES {
        let mut s = state.clone();
        s.time = i as f64;
        fisheye(&GridWorld::default(), &lens, &s)
            .save(seq.join(format!("{i:03}.png")))
            .unwrap();
    }
    let clip = dir.path().join("fisheye.mp4");
    common::encode_sequence(&seq, &clip, 12);
    assert_eq!(probe_frames(&clip), (FRAMES as u64, "1280x720".into()));

    // Fisheye MP4 → dewarped MP4, four views at 640x480.
    let out = dir.path().join("out.mp4");
    let common_flags = [
        "--size",
        "640x480",
        "--layout",
        "4",
        "--overlay",
        "0",
        "--cam",
        "0:yaw=0,pitch=0,fov=90deg,crop=1",
        "--cam",
        "1:yaw=0,pitch=-45deg,fov=90deg,crop=1",
        "--cam",
        "2:yaw=0,pitch=-90deg,fov=90deg,crop=1",
        "--cam",
        "3:yaw=180deg,pitch=-45deg,fov=90deg,crop=1",
    ];
    let r = digiview(
        &[
            &[
                "render",
                "--input",
                clip.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ][..],
            &common_flags,
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains(&format!("{FRAMES} frames")), "{err}");
    assert_eq!(probe_frames(&out), (FRAMES as u64, "640x480".into()));

    // The picture, in the MP4 and in a PNG sequence rendered from the clip's frames: the
    // last frame against the ground truth at its time.
    let mut s = state.clone();
    s.time = (FRAMES - 1) as f64;
    let plan = FramePlan::new(&s, &lens).unwrap();
    let want = truth(&GridWorld::default(), &plan, &s);
    let check = |got: &RgbImage, floor: f64, what: &str| {
        let db = psnr(&want, got, Rect::new(0, 0, 640, 480));
        let m = landmark_matches(&plan, &s, &want, got);
        eprintln!("{what}: {db:.1} dB, {} landmarks", m.len());
        assert!(db > floor, "{what}: {db:.1} dB against the truth");
        assert!(
            m.len() >= 3 && m.iter().all(|m| m.error() < 1.5),
            "{what}: {m:?}"
        );
    };
    let last_png = dir.path().join("last.png");
    let extracted = Command::new("ffmpeg")
        .args(["-v", "error", "-i", out.to_str().unwrap()])
        .args([
            "-vf",
            &format!("select=eq(n\\,{})", FRAMES - 1),
            "-frames:v",
            "1",
        ])
        .arg(&last_png)
        .status()
        .unwrap();
    assert!(extracted.success());
    check(&image::open(&last_png).unwrap().to_rgb8(), 28.0, "mp4");
    let seq_out = dir.path().join("views");
    let pattern = format!("{}/%03d.png", seq_out.display());
    let input = format!("{}/%03d.png", seq.display());
    let r = digiview(
        &[
            &["render", "--input", &input, "--out", &pattern][..],
            &common_flags,
        ]
        .concat(),
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let last = image::open(seq_out.join(format!("{:03}.png", FRAMES - 1)))
        .unwrap()
        .to_rgb8();
    check(&last, 30.0, "png sequence");
    let n = std::fs::read_dir(&seq_out).unwrap().count();
    assert_eq!(n, FRAMES as usize);
}

#[test]
fn missing_and_corrupt_inputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mp4");
    let r = digiview(&[
        "render",
        "--input",
        "no/such.mp4",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("no such file"));
    let bad = dir.path().join("bad.mp4");
    std::fs::write(&bad, b"this is not a video, whatever its name says").unwrap();
    let r = digiview(&[
        "render",
        "--input",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("cannot read"), "{err}");
    assert!(!out.exists(), "nothing written for a bad input");
    let r = digiview(&["render", "--input", bad.to_str().unwrap(), "--out", "x.gif"]);
    assert!(!r.status.success());
}

/// A test-pattern clip of `frames` frames, 320x240 at 30 fps (fragmented MP4 as DigiView
/// records, so a cut copy still plays up to the cut).
fn test_clip(path: &Path, frames: u32) {
    let made = Command::new("gst-launch-1.0")
        .args(["-q", "videotestsrc", &format!("num-buffers={frames}")])
        .args(["!", "video/x-raw,width=320,height=240,framerate=30/1"])
        .args(["!", "x264enc", "speed-preset=ultrafast", "key-int-max=30"])
        .args([
            "!",
            "h264parse",
            "!",
            "mp4mux",
            "fragment-duration=1000",
            "streamable=true",
        ])
        .args(["!", "filesink", &format!("location={}", path.display())])
        .status()
        .unwrap();
    assert!(made.success());
}

/// Every file in `dir`, hidden ones too.
fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn an_output_that_is_the_input_is_refused_and_the_input_kept() {
    let dir = tempfile::tempdir().unwrap();
    let clip = dir.path().join("same.mp4");
    test_clip(&clip, 30);
    let before = std::fs::read(&clip).unwrap();
    let link = dir.path().join("link.mp4");
    std::os::unix::fs::symlink(&clip, &link).unwrap();
    let hard = dir.path().join("hard.mp4");
    std::fs::hard_link(&clip, &hard).unwrap();
    let other = format!("{}/./same.mp4", dir.path().display());
    for out in [
        clip.to_str().unwrap(),
        link.to_str().unwrap(),
        hard.to_str().unwrap(),
        &other,
    ] {
        let r = digiview(&["render", "--input", clip.to_str().unwrap(), "--out", out]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{out}: {err}");
        assert!(err.contains("would destroy the input"), "{out}: {err}");
    }
    assert_eq!(
        std::fs::read(&clip).unwrap(),
        before,
        "the input is untouched"
    );
    assert_eq!(files(dir.path()), ["hard.mp4", "link.mp4", "same.mp4"]);
}

#[test]
fn a_stopped_render_leaves_no_file_and_a_cut_input_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let clip = dir.path().join("long.mp4");
    test_clip(&clip, 900);
    let out = dir.path().join("out.mp4");
    // Ctrl-C into a render of 30 s of video, once it has written something (its partial
    // file, or its first image): how long that takes depends on the machine.
    let interrupted = |out: &Path| {
        let child = Command::new(env!("CARGO_BIN_EXE_digiview"))
            .args(["render", "--input", clip.to_str().unwrap(), "--out"])
            .arg(out)
            .args(["--size", "640x480"])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let written = || {
            let entries = std::fs::read_dir(out.parent().unwrap())
                .into_iter()
                .flatten();
            entries.flatten().any(|e| {
                e.file_name() != "long.mp4"
                    && e.metadata().is_ok_and(|m| m.is_file() && m.len() > 0)
            })
        };
        let start = std::time::Instant::now();
        while !written() {
            assert!(
                start.elapsed() < std::time::Duration::from_secs(60),
                "render wrote nothing in 60 s"
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        // SAFETY: a signal to the child this test started and has not waited for yet.
        let sent = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
        assert_eq!(sent, 0);
        let r = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(!r.status.success(), "{err}");
        err
    };
    let err = interrupted(&out);
    assert!(
        err.contains("interrupted after") && err.contains("was not written"),
        "{err}"
    );
    assert_eq!(
        files(dir.path()),
        ["long.mp4"],
        "no output, no partial file"
    );
    // Into an image sequence: as many frames on disk as it says, none partial.
    let seq = dir.path().join("seq");
    let err = interrupted(&seq.join("%04d.png"));
    let said: usize = err
        .split("interrupted after ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{err}"));
    let on_disk = files(&seq);
    assert!(said > 0, "{err}");
    assert_eq!(on_disk.len(), said, "{err}: {on_disk:?}");
    assert_eq!(on_disk.last().unwrap(), &format!("{:04}.png", said - 1));

    // The first third of a clip: rendered as far as it goes, and the exit status says so.
    let cut = dir.path().join("cut.mp4");
    let whole = std::fs::read(&clip).unwrap();
    std::fs::write(&cut, &whole[..whole.len() / 3]).unwrap();
    let r = digiview(&[
        "render",
        "--input",
        cut.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--size",
        "640x480",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "{err}");
    assert!(
        err.contains("of the 30.00 s its container announces"),
        "{err}"
    );
    let (n, size) = probe_frames(&out);
    assert!(n > 100 && n < 800 && size == "640x480", "{n} frames {size}");
    assert!(
        err.contains(&format!("the {n} frames decoded were rendered")),
        "{err}"
    );
}

/// `render --klv` to MPEG-TS: FFmpeg finds the H.264 and a KLV stream, and stanag4609 reads
/// one packet per frame, each stamped with its frame's capture time (--klv-start plus the
/// frame's time in the clip), the state's vehicle and camera 0's frame centre where its
/// boresight meets the ground, and the tracked object in the VMTI. Asked of an MP4, --klv
/// is a clear error and writes nothing.
#[test]
fn render_klv_writes_mpegts_with_each_frames_metadata() {
    use digiview::geometry::ground::ground_point;
    use digiview::geometry::rotation::direction;
    let dir = tempfile::tempdir().unwrap();
    let clip = dir.path().join("clip.mp4");
    test_clip(&clip, 30);
    let out = dir.path().join("out.ts");
    let flags = [
        "render",
        "--input",
        clip.to_str().unwrap(),
        "--size",
        "640x480",
        "--attitude",
        "yaw=30deg",
        "--position",
        "lat=47.397,lon=8.546,alt=620,rel=120",
        "--cam",
        "0:yaw=45deg,pitch=-60deg,lock=7",
        "--track",
        "yaw=45deg,pitch=-60deg,size=5deg,id=9",
        "--klv",
        "--klv-start",
        "1764150000.25",
        "--out",
    ];
    let mp4 = dir.path().join("out.mp4");
    let r = digiview(&[&flags[..], &[mp4.to_str().unwrap()]].concat());
    let why = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && why.contains("MPEG-TS"), "{why}");
    assert!(!mp4.exists());
    let r = digiview(&[&flags[..], &[out.to_str().unwrap()]].concat());
    let why = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{why}");
    let packets = common::klv::misb(&common::klv::extract(&out));
    assert_eq!(packets.len(), 30, "one packet a frame");
    let position = common::klv::POSITION;
    let (centre, _) = ground_point(
        &position,
        direction(45f64.to_radians(), -60f64.to_radians()),
    )
    .unwrap();
    for (k, p) in packets.iter().enumerate() {
        assert!(p.get("error").is_none(), "packet {k}: {p}");
        let v = &p["values"];
        let time = v["2"].as_u64().unwrap_or_else(|| panic!("{p}")) as i64;
        let want = 1_764_150_000_250_000 + k as i64 * 1_000_000 / 30;
        assert!(
            (time - want).abs() <= 1000,
            "packet {k}: {time}, want {want}"
        );
        assert!((v["5"].as_f64().unwrap() - 30.0).abs() < 0.01, "{v}");
        assert_eq!(v["11"], "DigiView cam 0");
        let at = (v["23"].as_f64().unwrap(), v["24"].as_f64().unwrap());
        let miss = common::klv::metres(at, (centre.lat, centre.lon));
        assert!(
            miss < 0.5,
            "packet {k}: the frame centre is {miss:.2} m off"
        );
        let targets = p["vmti"]["targets"].as_array().unwrap();
        assert_eq!(targets.len(), 1, "{p}");
        assert_eq!(targets[0]["id"], 9);
    }
}
