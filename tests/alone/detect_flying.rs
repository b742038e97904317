//! What the operator sees is true while the demo flies its circle, on an idle machine and with
//! one core kept busy by a load generator (so the scans run late): the head scores its own
//! tracker and rings against the demo's movers (`/api/status`, `video.demo_score`), and the
//! objects DETECTED_ROI reports stand on the movers' circles, checked here from the world's
//! own description.

use crate::common;

use common::Load;
use common::gcs::http_get;
use common::serve::Serve;
use serde_json::Value;
use std::time::Duration;

/// Seconds each condition flies (DIGIVIEW_FLIGHT_S; the figures in docs/detection.md are of
/// 120).
fn flight() -> Duration {
    let s = std::env::var("DIGIVIEW_FLIGHT_S").ok();
    Duration::from_secs(s.and_then(|s| s.parse().ok()).unwrap_or(18))
}

fn status(serve: &Serve) -> Value {
    let url = format!("{}api/status", serve.http.as_ref().unwrap());
    let (code, body) = http_get(&url);
    assert_eq!(code, 200);
    serde_json::from_slice(&body).unwrap()
}

/// The demo's score now (`null` before the first scan).
fn score(serve: &Serve) -> Value {
    status(serve)["video"]["demo_score"].clone()
}

/// The rings scored so far: (count, within the limit).
fn rings(s: &Value) -> (u64, u64) {
    let r = &s["rings"];
    (
        r["count"].as_u64().unwrap_or(0),
        r["within"].as_u64().unwrap_or(0),
    )
}

/// The rings scored over the next `flying` (count, within 10 px of their mover), and the
/// demo's score at its end.
pub(crate) fn rings_over(serve: &Serve, flying: Duration) -> (u64, u64, Value) {
    let before = rings(&score(serve));
    std::thread::sleep(flying);
    let last = score(serve);
    let (count, within) = rings(&last);
    (count - before.0, within - before.1, last)
}

/// Flies the demo for [`flight`] in each of layouts 4, 5 and 6 (a third each) and checks the
/// score: 95% of the objects in the scans' fields on a mover, no entry later than 1 s, no
/// tile on empty ground for more than 1 s, 95% of each layout's rings within 10 px of their
/// mover at 1280x720; then every object DETECTED_ROI lists stands on a mover's circle.
fn fly_and_score(loaded: bool) {
    let _alone = crate::one_at_a_time();
    let _load = loaded.then(Load::start);
    let serve = Serve::start_video(&["--detector", "motion", "--size", "1280x720"]);
    let addr = serve.addr.to_string();
    let what = if loaded { "one core busy" } else { "idle" };
    let mut last = Value::Null;
    for layout in [4, 5, 6] {
        let o = common::ctl(
            &addr,
            &["set", "video_output", &format!("layout_mode={layout}")],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::thread::sleep(Duration::from_millis(500));
        let (count, within, score) = rings_over(&serve, flight() / 3);
        last = score;
        println!("{what}, layout {layout}: {within} of {count} rings within 10 px");
        assert!(count >= 30, "{what}, layout {layout}: {count} rings");
        assert!(
            within as f64 >= 0.95 * count as f64,
            "{what}, layout {layout}: {within} of {count} rings within 10 px"
        );
    }
    let health = &status(&serve)["video"];
    println!("{what}: {last}");
    println!("{what}: health {}", health["scans"]);
    let scans = last["scans"].as_u64().unwrap();
    assert!(
        scans as f64 >= flight().as_secs_f64(),
        "{what}: {scans} scans"
    );
    let precision = last["precision"].as_f64().unwrap();
    assert!(precision >= 0.95, "{what}: precision {precision}: {last}");
    assert_eq!(last["late_entries"], 0, "{what}: {last}");
    let false_tile = last["longest_false_tile"].as_f64().unwrap();
    assert!(
        false_tile <= 1.0,
        "{what}: a tile on no mover for {false_tile} s"
    );
    // From outside: every object listed stands on a mover's circle (wherever on it the
    // mover is now), its ground point from DETECTED_ROI's direction and distance.
    let vehicle = &health["klv"]["sensor"];
    let origin = digiview::scene::synth::world_origin(&digiview::state::DEFAULT_POSITION);
    let eye = digiview::geometry::ground::to_ned(
        origin,
        digiview::geometry::GeoPoint {
            lat: vehicle["lat"].as_f64().unwrap(),
            lon: vehicle["lon"].as_f64().unwrap(),
            alt: vehicle["alt"].as_f64().unwrap(),
        },
    );
    let o = common::ctl(&addr, &["--json", "get", "detected_roi", "index=255"]);
    for line in String::from_utf8_lossy(&o.stdout).lines() {
        let d = &serde_json::from_str::<Value>(line).unwrap()["values"];
        if d["total_detections"] == 0 {
            continue;
        }
        let n = |k: &str| d[k].as_f64().unwrap();
        let ray = digiview::geometry::rotation::direction(n("yaw_abs"), n("pitch_abs"));
        let at = (eye + ray * n("distance")).truncate();
        let off = common::off_the_movers_circles(at);
        // The vehicle moved on a little between the two replies.
        assert!(
            off < 3.0,
            "{what}: an object {off:.1} m off every mover's circle: {d}"
        );
    }
}

#[test]
fn flying_idle_the_tracks_tiles_and_rings_are_on_the_movers() {
    fly_and_score(false);
}

#[test]
fn flying_with_a_core_kept_busy_the_tracks_tiles_and_rings_are_on_the_movers() {
    fly_and_score(true);
}
