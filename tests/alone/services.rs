//! The video head's services survive a panic as the MAVLink link's do (tests/it/services.rs):
//! with `DIGIVIEW_FAULT=detection` the detection thread panics once, is reported under its
//! name in `/api/status` and started again, and the demo's movers are tracked again; with
//! `DIGIVIEW_FAULT=publish` the relay's thread panics once, and the relay gets the stream
//! again. Here, not in `it`: the detection thread runs only on idle CPU time.

use crate::common;

use common::gcs::{http_get, reported};
use common::relay::{Ingest, Relay, wait_count};
use common::serve::Serve;
use serde_json::Value;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Waits for `/api/status` to say `service` was started again once after an injected fault.
fn restarted(http: &str, service: &str) {
    let deadline = Instant::now() + Duration::from_secs(15);
    loop {
        let (code, body) = http_get(&format!("{http}api/status"));
        assert_eq!(code, 200);
        let s: Value = serde_json::from_slice(&body).unwrap();
        let failed = &s["services"][service];
        if failed["restarts"] == 1 {
            assert_eq!(failed["given_up"], false, "{s}");
            let why = failed["last_failure"].as_str().unwrap();
            assert!(why.contains("fault injected"), "{s}");
            return;
        }
        assert!(
            Instant::now() < deadline,
            "{service}: no restart reported: {s}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn detection_and_publishing_are_restarted_after_a_panic() {
    let _alone = crate::one_at_a_time();
    let video = ["--demo-size", "640x480", "--size", "640x480"];

    let mut serve = Serve::start_video_faulty(
        "detection",
        &[&video[..], &["--detector", "motion"]].concat(),
    );
    let http = serve.http.clone().unwrap();
    restarted(&http, "detection");
    let deadline = Instant::now() + Duration::from_secs(20);
    while reported(&http).is_empty() {
        assert!(
            Instant::now() < deadline,
            "no mover tracked after the restart"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        serve.wait_exit(Duration::from_millis(10)).is_none(),
        "serve goes on"
    );
    serve.terminate();
    serve.wait_exit(Duration::from_secs(10));
    let log = serve.log();
    assert!(
        log.contains("the detection service failed (fault injected"),
        "{log}"
    );

    let frames = Arc::new(AtomicUsize::new(0));
    let relay = Relay::start(0, frames.clone());
    let url = relay.url();
    let mut serve =
        Serve::start_video_faulty("publish", &[&video[..], &["--publish", &url]].concat());
    let http = serve.http.clone().unwrap();
    restarted(&http, "publish");
    let after = frames.load(Ordering::Relaxed);
    assert!(
        wait_count(&frames, after + 30, Duration::from_secs(30)),
        "30 frames at the relay after the restart (got {} after {after})",
        frames.load(Ordering::Relaxed)
    );
    serve.terminate();
    serve.wait_exit(Duration::from_secs(10));
    let log = serve.log();
    assert!(
        log.contains("the publish service failed (fault injected"),
        "{log}"
    );
}
