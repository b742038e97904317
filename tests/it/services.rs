//! Every supervised service of `serve` survives a panic: with `DIGIVIEW_FAULT=NAME` the
//! service of that thread name panics once; the panic is logged with its message,
//! `/api/status` says which service failed and that it was started again, the process goes
//! on, and a ground station hears the cameras' heartbeats again within 3 s. The HTTP server
//! (`DIGIVIEW_FAULT=http`) is served again on its address; a control client whose task panics
//! (`DIGIVIEW_FAULT=control`) is dropped while every other client is served.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, cameras, http_get, params};
use common::serve::Serve;
use digiview::control::client::Client;
use mavlink::dialects::common::*;
use serde_json::Value;
use std::time::{Duration, Instant};

fn status(http: &str) -> Value {
    let (code, body) = http_get(&format!("{http}api/status"));
    assert_eq!(code, 200);
    serde_json::from_slice(&body).unwrap()
}

#[test]
fn each_mavlink_service_is_restarted_after_a_panic_and_said_to_have_failed() {
    for service in ["mavlink-components", "mavlink-rx", "mavlink-tx"] {
        let port = free_udp_port();
        let link = format!("udpin:127.0.0.1:{port}");
        let mut serve = Serve::start_logging("info", Some(service), &["--mavlink", &link]);
        let http = serve.http.clone().unwrap();
        let gcs = Gcs::connect(port);
        let (system, seen) = cameras(&gcs);
        assert_eq!(seen.len(), 4, "{service}: {seen:?}");

        // The fault fires half a second in; the status says so once it is started again.
        let deadline = Instant::now() + Duration::from_secs(10);
        let restarted = loop {
            let s = status(&http);
            let failed = &s["services"][service];
            if failed["restarts"] == 1 {
                assert_eq!(failed["given_up"], false, "{service}: {s}");
                assert!(
                    failed["last_failure"]
                        .as_str()
                        .unwrap()
                        .contains("fault injected"),
                    "{service}: {s}"
                );
                break Instant::now();
            }
            assert!(Instant::now() < deadline, "{service}: no restart seen: {s}");
            std::thread::sleep(Duration::from_millis(100));
        };

        // The cameras beat again within 3 s, and answer.
        gcs.forget();
        let beat = gcs.wait_for(Duration::from_secs(3), |h, m| match m {
            MavMessage::HEARTBEAT(b) if b.mavtype == MavType::MAV_TYPE_CAMERA => {
                Some(h.component_id)
            }
            _ => None,
        });
        assert!(beat.is_some(), "{service}: no camera heartbeat within 3 s");
        println!(
            "{service}: a camera heartbeat {:.2} s after the restart was seen",
            restarted.elapsed().as_secs_f64()
        );
        let answer = gcs.command(system, 100, REQUEST, params(&[259.0]));
        if answer.as_ref().map(|a| a.0) != Some(MavResult::MAV_RESULT_ACCEPTED) {
            serve.terminate();
            serve.wait_exit(Duration::from_secs(10));
            panic!("{service}: {:?}\n{}", answer.map(|a| a.0), serve.log());
        }
        assert!(
            serve.wait_exit(Duration::from_millis(100)).is_none(),
            "{service}: serve goes on"
        );
        serve.terminate();
        let code = serve.wait_exit(Duration::from_secs(10));
        assert_eq!(code.and_then(|c| c.code()), Some(0), "{service}");
        let log = serve.log();
        assert!(
            log.contains(&format!("the {service} service failed (fault injected")),
            "{service}: {log}"
        );
    }
}

/// `/api/status` from `http`, or None while nothing answers there.
fn try_status(http: &str) -> Option<Value> {
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let (_, body) = common::raw_request(host, "GET", "/api/status", &[("Host", host)], "").ok()?;
    serde_json::from_str(&body).ok()
}

#[test]
fn the_http_server_is_served_again_after_a_failure() {
    let mut serve = Serve::start_logging("error", Some("http"), &[]);
    let http = serve.http.clone().unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    let s = loop {
        if let Some(s) = try_status(&http)
            && s["services"]["http"]["restarts"] == 1
        {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "no restart of the http server seen"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let why = s["services"]["http"]["last_failure"].as_str().unwrap();
    assert!(why.contains("fault injected"), "{s}");
    // On the same address, and the page is there.
    let (code, page) = http_get(&http);
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("<html"));
    serve.terminate();
    let code = serve.wait_exit(Duration::from_secs(10));
    assert_eq!(code.and_then(|c| c.code()), Some(0));
    assert!(
        serve
            .log()
            .contains("the http service failed (fault injected")
    );
}

#[test]
fn a_control_task_that_panics_is_reported_and_everyone_else_is_served() {
    // Once a TCP client's task panics (that client is dropped), once the UDP task (it is
    // started again on the same port).
    for udp in [false, true] {
        let mut serve = Serve::start_logging("error", Some("control"), &[]);
        let http = serve.http.clone().unwrap();
        let addr = serve.addr.to_string();
        // The fault fires on the first frame a task handles half a second after it started:
        // that frame is not answered.
        let mut first = Client::connect(&addr, udp, Duration::from_secs(2)).unwrap();
        std::thread::sleep(Duration::from_millis(700));
        assert!(
            first.ping().is_err(),
            "udp {udp}: the frame that panicked is answered"
        );
        let deadline = Instant::now() + Duration::from_secs(5);
        let s = loop {
            let s = status(&http);
            if s["services"]["control"]["restarts"] == 1 {
                break s;
            }
            assert!(Instant::now() < deadline, "udp {udp}: no restart seen: {s}");
            std::thread::sleep(Duration::from_millis(100));
        };
        let why = s["services"]["control"]["last_failure"].as_str().unwrap();
        assert!(why.contains("fault injected"), "{s}");
        // Everyone is served, over TCP and over UDP.
        for udp in [false, true] {
            let mut c = Client::connect(&addr, udp, Duration::from_secs(2)).unwrap();
            c.ping().unwrap_or_else(|e| panic!("udp {udp}: {e}"));
        }
        serve.terminate();
        let code = serve.wait_exit(Duration::from_secs(10));
        assert_eq!(code.and_then(|c| c.code()), Some(0));
        let told = [
            "the control service failed (a client's task: fault",
            "the control service failed (udp: fault",
        ];
        assert!(serve.log().contains(told[udp as usize]), "udp {udp}");
    }
}
