//! The rate a ground station is told is the rate a view's stream really has. On a small
//! machine the watched views are drawn less often than the composed frame (the composed stream
//! comes first); VIDEO_STREAM_INFORMATION then says so, rather than the configured 30 fps.
//! Four FFmpeg clients watch the four views' streams of `serve` on a still; each stream's
//! rate by its own timestamps against what a ground station is told meanwhile. Alone: other
//! tests starting and stopping beside it change the views' rate within its seconds.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, accepted, cameras, params};
use common::serve::{Serve, until_running};
use mavlink::dialects::common::*;
use std::process::Stdio;
use std::time::{Duration, Instant};

/// The stream's own timestamps (seconds) of the frames FFmpeg decodes from `url` in its
/// first `seconds`: the rate a view's stream has is in them, however late FFmpeg decodes on
/// a busy machine.
fn timestamps(url: String, seconds: u32) -> std::thread::JoinHandle<Vec<f64>> {
    std::thread::spawn(move || {
        let out = common::ffmpeg_from(&url, "tcp")
            .args(["-t", &seconds.to_string(), "-fps_mode", "passthrough"])
            .args(["-enc_time_base:v", "1:90000", "-f", "framemd5", "-"])
            .stderr(Stdio::null())
            .output()
            .expect("ffmpeg runs");
        // Lines "stream, dts, pts, duration, size, md5" in 1/90000 s.
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| l.split(',').nth(2)?.trim().parse::<f64>().ok())
            .map(|pts| pts / 90_000.0)
            .collect()
    })
}

/// What VIDEO_STREAM_INFORMATION says of camera `c`'s own stream (stream 1).
fn advertised(gcs: &Gcs, system: u8, c: u8) -> f32 {
    let said = accepted(
        gcs.command(system, c, REQUEST, params(&[269.0, 1.0])),
        "stream information",
    );
    match &said[..] {
        [MavMessage::VIDEO_STREAM_INFORMATION(v), ..] => v.framerate,
        other => panic!("{other:?}"),
    }
}

#[test]
fn video_stream_information_says_the_rate_each_watched_views_stream_really_has() {
    let dir = tempfile::tempdir().unwrap();
    let still = dir.path().join("fish.png");
    common::synth_still(&still);
    let source = format!("image:{}", still.display());
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start_video(&["--source", &source, "--size", "640x480", "--mavlink", &link]);
    until_running(&serve);
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);
    // Nobody watches yet: the configured rate.
    assert_eq!(advertised(&gcs, system, 100), 30.0);

    let rtsp = serve.rtsp.clone().unwrap();
    let seconds = 11;
    let started = Instant::now();
    let clients: Vec<_> = (0..4)
        .map(|i| timestamps(format!("{rtsp}/cam{i}"), seconds))
        .collect();
    // From the fifth second of the clients' time on (past their start and the first 2 s the
    // head measures over), what the ground station is told twice a second, averaged; and
    // each stream's frames over the same stretch of its own time (its first frame comes
    // about a second after its client starts).
    std::thread::sleep(Duration::from_secs(5));
    let mut told = vec![vec![]; 4];
    while started.elapsed() < Duration::from_secs(seconds as u64 - 1) {
        for (c, told) in (100..104).zip(&mut told) {
            told.push(advertised(&gcs, system, c) as f64);
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    let said: Vec<f64> = told
        .iter()
        .map(|t| t.iter().sum::<f64>() / t.len() as f64)
        .collect();
    let counted: Vec<f64> = clients
        .into_iter()
        .map(|c| {
            let pts = c.join().unwrap();
            let first = pts.first().copied().unwrap_or(0.0);
            let late: Vec<f64> = pts.into_iter().filter(|&t| t >= first + 4.0).collect();
            match (late.first(), late.last()) {
                (Some(a), Some(b)) if b > a => (late.len() - 1) as f64 / (b - a),
                _ => 0.0,
            }
        })
        .collect();
    eprintln!("views' rates: advertised {said:.1?}, counted by FFmpeg {counted:.1?}");
    for (i, (&said, &counted)) in said.iter().zip(&counted).enumerate() {
        assert!(
            counted > 1.0,
            "view {i}'s stream did not play ({counted} fps)"
        );
        // The two cover the same seconds, give or take the clients' start.
        let off = (said - counted).abs();
        assert!(
            off <= 0.1 * counted + 1.0 && said <= 30.0,
            "view {i}: VIDEO_STREAM_INFORMATION says {said:.1} fps on average, FFmpeg counts {counted:.1}"
        );
    }
}
