//! `serve --publish`: the stream pushed to a media relay started in the test (RTSP RECORD,
//! and SRT), decoded there; the relay stopped and started again, and the stream back there without
//! restarting `serve`, whose own RTSP server serves on throughout.

use crate::common;

use common::probe_rtsp;
use common::relay::{Ingest, Relay, SrtRelay, wait_count};
use common::serve::Serve;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// `serve` publishing to an `R` started in the test: 30 frames decoded there; the relay
/// stopped for 3 s (`meanwhile` runs then) and started again on its port; 30 more frames
/// there, `serve` untouched.
fn publish_through_a_restart<R: Ingest>(meanwhile: impl FnOnce(&Serve)) {
    let frames = Arc::new(AtomicUsize::new(0));
    let relay = R::start(0, frames.clone());
    let port = relay.port();
    let serve = Serve::start_video(&[
        "--demo-size",
        "640x480",
        "--size",
        "640x480",
        "--publish",
        &relay.url(),
    ]);
    let count = || frames.load(Ordering::Relaxed);
    assert!(
        wait_count(&frames, 30, Duration::from_secs(30)),
        "30 frames decoded at {} (got {})",
        relay.url(),
        count()
    );
    drop(relay);
    std::thread::sleep(Duration::from_secs(3));
    meanwhile(&serve);
    let during = count();
    let relay = R::start(port, frames.clone());
    assert!(
        wait_count(&frames, during + 30, Duration::from_secs(60)),
        "30 more frames at {} restarted (got {} after {during})",
        relay.url(),
        count()
    );
}

#[test]
fn publishing_reaches_an_rtsp_relay_and_resumes_after_it_restarts() {
    publish_through_a_restart::<Relay>(|serve| {
        // The drone's own server serves on while the relay is away.
        let probe = probe_rtsp(serve.rtsp.as_ref().unwrap(), "width,height");
        assert_eq!(
            String::from_utf8_lossy(&probe.stdout).trim(),
            "640,480",
            "{}",
            String::from_utf8_lossy(&probe.stderr)
        );
    });
}

#[test]
fn publishing_over_srt_reaches_a_listener_and_resumes_after_it_restarts() {
    publish_through_a_restart::<SrtRelay>(|_| {});
}
