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
/// movers' circles, one on each; turning run_ai off over GENERAL_SETTINGS drops them.
#[test]
fn serve_tracks_the_demos_movers_and_reports_where_they_are_on_the_ground() {
    let _alone = crate::one_at_a_time();
    use digiview::geometry::rotation::direction;
    let server = common::serve::Serve::start_video(&["--demo-hover", "--detector", "motion"]);
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
    // run_ai off: no detections.
    assert!(
        ctl(&addr, &["set", "general_settings", "run_ai=0"])
            .status
            .success()
    );
    std::thread::sleep(std::time::Duration::from_millis(600));
    assert!(detections(&addr).is_empty());
}
