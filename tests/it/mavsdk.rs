//! MAVSDK, the C++ core many ground-station apps build on (its `mavsdk` wheel), against a
//! running `serve` on the flying demo: tests/peers/mavsdk_station.py drives its Camera and
//! Gimbal plugins through a relay that counts every command on the wire, while this test
//! watches the view's steering over the DigiView protocol.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::euler;
use common::peers::{CountingRelay, run_peer};
use common::serve::Serve;
use digiview::control::client::Client;
use serde_json::Value;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long MAVSDK stays connected: the span its retries are counted over.
const CONNECTED_S: &str = "30";

#[test]
fn mavsdk_lists_the_cameras_with_their_own_streams_and_named_gimbals_and_rates_start_and_stop() {
    let link = free_udp_port();
    let serve = Serve::start_video(&[
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--size",
        "640x480",
    ]);
    let relay = CountingRelay::start(link);

    // Camera 0's yaw as the DigiView protocol reads it, every 20 ms.
    let yaws = Arc::new(Mutex::new(Vec::<(Instant, f64)>::new()));
    let done = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (yaws, done) = (yaws.clone(), done.clone());
        let addr = serve.addr.to_string();
        std::thread::spawn(move || {
            let mut ctl = Client::connect(&addr, false, Duration::from_secs(2)).unwrap();
            while !done.load(Ordering::Relaxed) {
                let yaw = euler(&mut ctl, 0).0;
                yaws.lock().unwrap().push((Instant::now(), yaw));
                std::thread::sleep(Duration::from_millis(20));
            }
        })
    };
    let (out, log) = run_peer("mavsdk_station.py", &[&relay.port.to_string(), CONNECTED_S]);
    done.store(true, Ordering::Relaxed);
    watcher.join().unwrap();
    let events: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    let event = |name: &str| -> &Value {
        events
            .iter()
            .find(|e| e["event"] == name)
            .unwrap_or_else(|| panic!("no {name} in\n{out}\n{log}"))
    };

    // Four cameras and four gimbals, named, soon after connecting.
    let cameras = event("cameras");
    assert_eq!(cameras["ids"], serde_json::json!([100, 101, 102, 103]));
    assert!(cameras["after_s"].as_f64().unwrap() < 5.0, "{cameras}");
    let gimbals = event("gimbals");
    assert!(gimbals["after_s"].as_f64().unwrap() < 3.0, "{gimbals}");
    for (i, g) in gimbals["gimbals"].as_array().unwrap().iter().enumerate() {
        assert_eq!(g[1], 100 + i as u64, "{gimbals}");
        assert_eq!(g[2], "DigiView");
        assert_eq!(g[3], format!("virtual gimbal {i}"));
    }

    // Each camera's stream is its own view's, and it plays.
    let streams = event("streams");
    assert!(streams["after_s"].as_f64().unwrap() < 5.0, "{streams}");
    for i in 0..4 {
        let uri = streams["uris"][(100 + i).to_string()]
            .as_str()
            .unwrap_or("");
        assert!(uri.ends_with(&format!("/digiview/cam{i}")), "{streams}");
    }
    let first = streams["uris"]["100"].as_str().unwrap();
    let probe = common::probe_rtsp(first, "width,height");
    let size = &streams["sizes"]["100"];
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        format!("{},{}", size[0], size[1]),
        "{first}: {}",
        String::from_utf8_lossy(&probe.stderr)
    );

    // Rates, ONCE (a command) and STREAM (a message): each accepted, the view turning at the
    // rate asked and still within 0.2 s of the zero rate.
    let rates: Vec<&Value> = events.iter().filter(|e| e["event"] == "rate").collect();
    assert_eq!(rates.len(), 4, "{out}");
    for r in &rates {
        assert_eq!(r["result"], "SUCCESS", "{r}");
    }
    let asked = relay.yaw_rates.lock().unwrap().clone();
    let yaws = yaws.lock().unwrap().clone();
    let yaw_at = |t: Instant| -> f64 {
        yaws.iter()
            .find(|(at, _)| *at >= t)
            .map(|y| y.1)
            .expect("the yaw watched past then")
    };
    let turns: Vec<(Instant, Instant)> = asked
        .windows(2)
        .filter(|w| w[0].1 != 0.0 && w[1].1 == 0.0)
        .map(|w| (w[0].0, w[1].0))
        .collect();
    assert_eq!(turns.len(), 2, "a turn and a stop each way: {asked:?}");
    for (start, stop) in turns {
        let turned = wrap(yaw_at(stop) - yaw_at(start));
        let expected = 20.0 * (stop - start).as_secs_f64();
        assert!(
            (turned - expected).abs() < 0.3 * expected,
            "turned {turned:.1} deg in {:?}, expected about {expected:.1}",
            stop - start
        );
        let settled = yaw_at(stop + Duration::from_millis(200));
        let later = yaw_at(stop + Duration::from_millis(800));
        assert!(
            wrap(later - settled).abs() < 0.5,
            "still turning after the stop: {settled:.2} then {later:.2}"
        );
    }

    // After LAYOUT=1 the two cameras that still beat are what an app that connects then
    // lists. (MAVSDK keeps a camera for as long as its system stays connected: one already
    // connected goes on listing four, docs/mavlink.md.)
    let o = common::ctl(
        &serve.addr.to_string(),
        &["set", "video_output", "layout_mode=1"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (listed, later_log) = run_peer("mavsdk_station.py", &[&relay.port.to_string(), "list"]);
    let listed: Value = serde_json::from_str(listed.trim()).unwrap();
    assert_eq!(
        listed["ids"],
        serde_json::json!([100, 101]),
        "{listed}\n{later_log}"
    );

    // Nothing asked more than three times over (counted on the wire), no error in MAVSDK's log.
    let sent = relay.sent.lock().unwrap().clone();
    let retried: Vec<_> = sent.iter().filter(|(_, s)| s.retries > 3).collect();
    assert!(retried.is_empty(), "retried more than 3 times: {retried:?}");
    let errors: Vec<&str> = log.lines().filter(|l| l.contains("|Error]")).collect();
    assert!(
        errors.is_empty(),
        "MAVSDK logged errors:\n{}",
        errors.join("\n")
    );
    drop(serve);
}

/// An angle difference in degrees, into -180..180.
fn wrap(d: f64) -> f64 {
    (d + 540.0).rem_euclid(360.0) - 180.0
}
