//! The rate a ground station is told is the rate a view's stream really has. On a small
//! machine the watched views are drawn less often than the composed frame (the composed stream
//! comes first); VIDEO_STREAM_INFORMATION then says so, rather than the configured 30 fps.
//! Four FFmpeg clients watch the four views' streams of `serve` on a still; what a ground
//! station is told twice a second against each stream's rate by its own timestamps over the
//! same two seconds the head measures over. Alone: other tests starting and stopping beside
//! it change the views' rate within its seconds.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, cameras, params};
use common::serve::{Serve, until_running};
use mavlink::dialects::common::*;
use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The span the head measures a view's rate over, seconds.
const RATE_SPAN: f64 = 2.0;

/// The frames FFmpeg decodes from `url` in its first `seconds`: each one's stream timestamp
/// and when its line came out, both in seconds, the latter since `started`.
fn timestamps(url: String, seconds: u32, started: Instant) -> JoinHandle<Vec<(f64, f64)>> {
    std::thread::spawn(move || {
        let mut ffmpeg = common::ffmpeg_from(&url, "tcp")
            .args(["-t", &seconds.to_string(), "-fps_mode", "passthrough"])
            .args(["-enc_time_base:v", "1:90000", "-flush_packets", "1"])
            .args(["-f", "framemd5", "-"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("ffmpeg runs");
        // Lines "stream, dts, pts, duration, size, md5" in 1/90000 s.
        let lines = BufReader::new(ffmpeg.stdout.take().unwrap()).lines();
        let frames = lines
            .map_while(Result::ok)
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| l.split(',').nth(2)?.trim().parse::<f64>().ok())
            .map(|pts| (pts / 90_000.0, started.elapsed().as_secs_f64()))
            .collect();
        ffmpeg.wait().expect("ffmpeg ends");
        frames
    })
}

/// A stream's rate over the two seconds up to `at` (seconds since the clients started), by
/// its own timestamps, as the head counts it: frames but one over the time they span. The
/// stream's clock is set against ours by the frame that came out soonest after its time (a
/// frame cannot come out before it is made; a busy machine decodes some late). None where
/// the stream does not cover the two seconds.
fn rate_before(frames: &[(f64, f64)], at: f64) -> Option<f64> {
    let offset = frames
        .iter()
        .map(|(pts, out)| out - pts)
        .min_by(f64::total_cmp)?;
    let times: Vec<f64> = frames.iter().map(|(pts, _)| pts + offset).collect();
    // The stream covers the two seconds.
    if times.first()? > &(at - RATE_SPAN) || times.last()? < &at {
        return None;
    }
    let within: Vec<f64> = times
        .into_iter()
        .filter(|&t| t > at - RATE_SPAN && t <= at)
        .collect();
    let span = within.last()? - within.first()?;
    (span > 0.0).then(|| (within.len() - 1) as f64 / span)
}

/// What VIDEO_STREAM_INFORMATION says of camera `c`'s own stream (stream 1).
fn advertised(gcs: &Gcs, system: u8, c: u8) -> f32 {
    gcs.forget();
    gcs.send_command(system, c, REQUEST, params(&[269.0, 1.0]));
    gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::VIDEO_STREAM_INFORMATION(v) if h.component_id == c && v.stream_id == 1 => {
            Some(v.framerate)
        }
        MavMessage::COMMAND_ACK(a) if h.component_id == c && a.command == REQUEST => {
            assert_eq!(a.result, MavResult::MAV_RESULT_ACCEPTED, "camera {c}");
            None
        }
        _ => None,
    })
    .unwrap_or_else(|| panic!("camera {c} sent no stream information"))
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
    let started = Instant::now();
    let clients: Vec<_> = (0..4)
        .map(|i| timestamps(format!("{rtsp}/cam{i}"), 11, started))
        .collect();
    // What the ground station is told twice a second while the clients watch, past their
    // first seconds (the encoders starting).
    std::thread::sleep(Duration::from_secs(4));
    let mut told = vec![];
    while !clients.iter().all(JoinHandle::is_finished) {
        let at = started.elapsed().as_secs_f64();
        let said: Vec<f64> = (100..104)
            .map(|c| advertised(&gcs, system, c) as f64)
            .collect();
        told.push((at, said));
        std::thread::sleep(Duration::from_millis(500));
    }
    let streams: Vec<Vec<(f64, f64)>> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    for (i, frames) in streams.iter().enumerate() {
        assert!(
            frames.len() > 11,
            "view {i}'s stream did not play ({} frames)",
            frames.len()
        );
        // Each report against the stream's rate over the two seconds it covers, where the
        // stream covers them; averaged.
        let pairs: Vec<(f64, f64)> = told
            .iter()
            .filter_map(|(at, said)| Some((said[i], rate_before(frames, *at)?)))
            .collect();
        assert!(
            pairs.len() >= 8,
            "view {i}: {} reports in its stream",
            pairs.len()
        );
        let n = pairs.len() as f64;
        let said = pairs.iter().map(|p| p.0).sum::<f64>() / n;
        let counted = pairs.iter().map(|p| p.1).sum::<f64>() / n;
        eprintln!(
            "view {i}: advertised {said:.1} fps, counted by FFmpeg {counted:.1} ({n} reports)"
        );
        let off = (said - counted).abs();
        assert!(
            off <= 0.1 * counted + 1.0 && pairs.iter().all(|p| p.0 <= 30.0),
            "view {i}: VIDEO_STREAM_INFORMATION says {said:.1} fps on average, FFmpeg counts {counted:.1}"
        );
    }
}
