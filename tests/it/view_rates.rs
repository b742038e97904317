//! The rate a ground station is told is the rate a view's stream really has. On a small
//! machine the watched views are drawn less often than the composed frame (the composed stream
//! comes first); VIDEO_STREAM_INFORMATION then says so, rather than the configured 30 fps.
//! Four FFmpeg clients watch the four views' streams of `serve` on a still; the frames each
//! decoded in the 2 s before a ground station asks are its rate, against what MAVLink says.

use crate::common;

use crate::players::{still_and_render, until_running};
use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, accepted, cameras, params};
use common::serve::Serve;
use mavlink::dialects::common::*;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// When FFmpeg decoded each frame of `url`, for `seconds` of the stream's own time.
fn decoded_at(url: String, seconds: u32) -> std::thread::JoinHandle<Vec<Instant>> {
    std::thread::spawn(move || {
        let mut ffmpeg = Command::new("ffmpeg")
            .args([
                "-hide_banner",
                "-nostdin",
                "-rtsp_transport",
                "tcp",
                "-i",
                &url,
            ])
            .args(["-t", &seconds.to_string(), "-fps_mode", "passthrough"])
            .args(["-flush_packets", "1", "-f", "framemd5", "-"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("ffmpeg runs");
        let lines = BufReader::new(ffmpeg.stdout.take().unwrap()).lines();
        let at = lines
            .map_while(Result::ok)
            .filter(|l| !l.starts_with('#'))
            .map(|_| Instant::now())
            .collect();
        let _ = ffmpeg.wait();
        at
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
    let (source, _) = still_and_render(dir.path());
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start_video(&["--source", &source, "--mavlink", &link]);
    until_running(&serve);
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);
    // Nobody watches yet: the configured rate.
    assert_eq!(advertised(&gcs, system, 100), 30.0);

    let rtsp = serve.rtsp.clone().unwrap();
    let clients: Vec<_> = (0..4)
        .map(|i| decoded_at(format!("{rtsp}/cam{i}"), 9))
        .collect();
    // Well into the clients' time, past their start; the frames each decoded in the 2 s
    // before the question are its rate then, as the head measures it.
    std::thread::sleep(Duration::from_secs(6));
    let asked = Instant::now();
    let said: Vec<f32> = (100..104).map(|c| advertised(&gcs, system, c)).collect();
    let counted: Vec<f64> = clients
        .into_iter()
        .map(|c| {
            let at = c.join().unwrap();
            let span = asked - Duration::from_secs(2)..asked;
            at.iter().filter(|&&t| span.contains(&t)).count() as f64 / 2.0
        })
        .collect();
    eprintln!("views' rates: advertised {said:?}, counted by FFmpeg {counted:?}");
    for (i, (&said, &counted)) in said.iter().zip(&counted).enumerate() {
        assert!(
            counted > 1.0,
            "view {i}'s stream did not play ({counted} fps)"
        );
        let off = (said as f64 - counted).abs() / counted;
        assert!(
            off <= 0.10 && said <= 30.0,
            "view {i}: VIDEO_STREAM_INFORMATION says {said} fps, FFmpeg counts {counted:.1}"
        );
    }
}
