//! The stream as the players users have see it. FFmpeg's RTSP client and H.264 decoder
//! (libavformat and libavcodec, which ffplay, VLC and most ground stations' players are
//! built on) pull `serve`'s stream of a still fisheye image over TCP and over UDP, from the
//! start and joining 5 s late; each must decode 90 frames without a complaint on stderr, and
//! its first and last frames must be the offline `digiview render` of the same image.

use crate::common;

use common::serve::{Serve, until_running};
use digiview::image_ops;
use digiview::layout::Rect;
use image::RgbImage;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::thread::JoinHandle;
use std::time::Duration;

pub(crate) const SIZE: (u32, u32) = (640, 480);
const FRAMES: usize = 90;

/// What one FFmpeg client got: its first and last decoded frames, how many, and its stderr.
pub(crate) struct Pulled {
    pub first: RgbImage,
    pub last: RgbImage,
    pub frames: usize,
    pub log: String,
}

/// `ffmpeg` decoding `FRAMES` frames from `url` over `transport`, every decoded frame as it
/// is, as raw RGB on its stdout. The frames keep the stream's own timestamps (no frame rate
/// conversion, the RTP clock's 90 kHz), so a timestamp that does not increase is the
/// stream's, not an artefact of rounding to a coarser output clock.
pub(crate) fn pull(url: String, transport: &'static str) -> JoinHandle<Pulled> {
    std::thread::spawn(move || {
        let mut child = common::ffmpeg_from(&url, transport)
            .args(["-frames:v", &FRAMES.to_string(), "-fps_mode", "passthrough"])
            .args(["-enc_time_base:v", "1:90000"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ffmpeg runs (scripts/setup.sh installs it)");
        let mut stderr = child.stderr.take().unwrap();
        let log = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = stderr.read_to_string(&mut s);
            s
        });
        let mut out = child.stdout.take().unwrap();
        let mut frame = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        let (mut first, mut last, mut frames) = (None, None, 0);
        while out.read_exact(&mut frame).is_ok() {
            let img = RgbImage::from_raw(SIZE.0, SIZE.1, frame.clone()).unwrap();
            first.get_or_insert_with(|| img.clone());
            last = Some(img);
            frames += 1;
        }
        let status = child.wait().unwrap();
        let log = log.join().unwrap();
        assert!(status.success(), "ffmpeg over {transport} failed:\n{log}");
        Pulled {
            first: first.unwrap_or_else(|| panic!("no frame over {transport}:\n{log}")),
            last: last.unwrap(),
            frames,
            log,
        }
    })
}

/// The lines of FFmpeg's log that report damage: a corrupt or undecodable frame, an error of
/// any kind, or timestamps that do not increase.
pub(crate) fn complaints(log: &str) -> Vec<&str> {
    log.split(['\n', '\r'])
        .filter(|l| {
            let l = l.to_lowercase();
            [
                "corrupt",
                "error",
                "non monotonically increasing",
                "non-monotonous",
            ]
            .iter()
            .any(|w| l.contains(w))
        })
        .collect()
}

fn digiview(dir: &Path, args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(args)
        .current_dir(dir)
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "digiview {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A synthetic 1280x720 fisheye still in `dir` as an image source, and the offline render of
/// it at [`SIZE`] that every player must show.
pub(crate) fn still_and_render(dir: &Path) -> (String, RgbImage) {
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    digiview(dir, &["synth", "--out", "fish.png", "--sensor", "1280x720"]);
    digiview(
        dir,
        &[
            "render", "--input", "fish.png", "--out", "want.png", "--size", &size,
        ],
    );
    let want = image::open(dir.join("want.png")).unwrap().to_rgb8();
    (format!("image:{}", dir.join("fish.png").display()), want)
}

#[test]
fn ffmpeg_decodes_every_frame_clean_over_tcp_and_udp_from_the_start_and_joining_late() {
    let dir = tempfile::tempdir().unwrap();
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    let (source, want) = still_and_render(dir.path());
    let serve = Serve::start_video(&["--source", &source, "--size", &size]);
    let url = serve.rtsp.clone().unwrap();
    // "From the start" is from the first frame of the picture: before it the head shows its
    // NO SIGNAL card, as it should.
    until_running(&serve);

    let mut clients = vec![
        ("TCP from the start", pull(url.clone(), "tcp")),
        ("UDP from the start", pull(url.clone(), "udp")),
    ];
    std::thread::sleep(Duration::from_secs(5));
    clients.push(("TCP joining 5 s late", pull(url.clone(), "tcp")));
    clients.push(("UDP joining 5 s late", pull(url, "udp")));

    let whole = Rect::new(0, 0, SIZE.0, SIZE.1);
    for (who, client) in clients {
        let got = client.join().unwrap();
        let bad = complaints(&got.log);
        assert!(bad.is_empty(), "{who}: FFmpeg reports {bad:#?}");
        assert_eq!(got.frames, FRAMES, "{who}: frames decoded");
        for (which, frame) in [("first", &got.first), ("last", &got.last)] {
            let psnr = image_ops::psnr(frame, &want, whole);
            eprintln!("{who}: {which} frame {psnr:.1} dB against the offline render");
            assert!(psnr >= 30.0, "{who}: {which} frame only {psnr:.1} dB");
        }
    }
}
