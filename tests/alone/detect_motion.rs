//! The built-in motion detector in `digiview serve`, on the demo: the movers it tracks are
//! reported where they are on the ground, and run_ai turns it off.

use crate::common;

use common::ctl;
use digiview::scene::GridWorld;

/// Every known detection, as DETECTED_ROI 255 answers over the control protocol.
fn detections(addr: &str) -> Vec<serde_json::Value> {
    let o = ctl(addr, &["--json", "get", "detected_roi", "index=255"]);
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["values"].clone())
        .filter(|v| v["total_detections"].as_u64() != Some(0))
        .collect()
}

/// `digiview serve` on the demo, hovering: within seconds DETECTED_ROI 255 lists three
/// objects, whose ground points (direction and distance from the vehicle) lie on the three
/// movers' circles, one on each; the published stream's VMTI lists those camera 0 shows,
/// boxed, on their movers' circles too; turning run_ai off over GENERAL_SETTINGS drops them.
#[test]
fn serve_tracks_the_demos_movers_and_reports_where_they_are_on_the_ground() {
    let _alone = crate::one_at_a_time();
    use digiview::geometry::rotation::direction;
    let port = common::autopilot::free_udp_port();
    let url = format!("udp://127.0.0.1:{port}");
    let server = common::serve::Serve::start_video(&[
        "--demo-hover",
        "--detector",
        "motion",
        "--publish",
        &url,
    ]);
    let addr = server.addr.to_string();
    let vehicle = digiview::scene::synth::eye_at(&digiview::state::DEFAULT_POSITION);
    let world = GridWorld::default();
    let start = std::time::Instant::now();
    let mut found = vec![];
    while start.elapsed() < std::time::Duration::from_secs(15) {
        found = detections(&addr);
        if found.len() >= 3 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(250));
    }
    println!("{} objects after {:?}", found.len(), start.elapsed());
    assert_eq!(found.len(), 3, "{found:#?}");
    let mut on = vec![];
    for d in &found {
        let number = |k: &str| d[k].as_f64().unwrap();
        let at = vehicle + direction(number("yaw_abs"), number("pitch_abs")) * number("distance");
        let (m, off) = world
            .movers
            .iter()
            .enumerate()
            .map(|(m, mover)| {
                (
                    m,
                    (at.truncate().distance(mover.centre) - mover.orbit).abs(),
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        println!(
            "object at {:.1} m N, {:.1} m E: {off:.2} m off mover {m}'s circle",
            at.x, at.y
        );
        assert!(off < 1.5, "{d}");
        on.push(m);
    }
    on.sort();
    assert_eq!(on, vec![0, 1, 2]);
    vmti_lists_the_movers(&url, &addr);
    // run_ai off: no detections.
    assert!(
        ctl(&addr, &["set", "general_settings", "run_ai=0"])
            .status
            .success()
    );
    std::thread::sleep(std::time::Duration::from_millis(600));
    assert!(detections(&addr).is_empty());
}

/// The KLV of 3 s of the stream published to `url`, read by stanag4609: its VMTI lists every
/// object the tracker follows (as many as DETECTED_ROI), and boxes those camera 0 (the view
/// the composed stream's KLV describes) shows, each standing on a mover's circle.
fn vmti_lists_the_movers(url: &str, addr: &str) {
    use common::klv::{extract, misb, record_ts};
    let dir = tempfile::tempdir().unwrap();
    let ts = dir.path().join("movers.ts");
    record_ts(url, 3, &ts);
    let packets = misb(&extract(&ts));
    assert!(packets.len() >= 30, "{} packets", packets.len());
    let origin = digiview::scene::synth::world_origin(&digiview::state::DEFAULT_POSITION);
    let total = detections(addr).len() as u64;
    let mut boxed = 0;
    for p in &packets[packets.len() - 10..] {
        assert!(p.get("error").is_none(), "{p}");
        let vmti = &p["vmti"];
        assert_eq!(vmti["fields"]["totalNumTargetsDetected"], total, "{vmti}");
        for t in vmti["targets"].as_array().unwrap() {
            let (c, tl, br) = (
                t["targetCentroid"].as_u64().unwrap(),
                t["boundingBoxTopLeft"].as_u64().unwrap(),
                t["boundingBoxBottomRight"].as_u64().unwrap(),
            );
            assert!(tl < c && c < br, "{t}");
            let l = &t["targetLocation"];
            let point = digiview::geometry::GeoPoint {
                lat: l["lat"].as_f64().unwrap(),
                lon: l["lon"].as_f64().unwrap(),
                alt: l["hae"].as_f64().unwrap(),
            };
            let at = digiview::geometry::ground::to_ned(origin, point).truncate();
            let off = common::off_the_movers_circles(at);
            assert!(
                off < 2.5,
                "object {} is {off:.2} m off every mover's circle",
                t["id"]
            );
            boxed += 1;
        }
    }
    println!("VMTI: {boxed} boxed objects over the last 10 packets, of {total} tracked");
    assert!(boxed >= 10, "camera 0 boxed {boxed} objects over 10 frames");
}
