//! The built-in motion detector on the synthetic world, whose moving objects' places are
//! known: fisheye frames of the demo's world, the scan views rendered from them on the GPU
//! (lavapipe), the detector and the seed's tracker. Every mover in view is tracked, where it
//! is, with no other track, while the vehicle turns and flies.

mod common;

use common::ctl;
use common::gpu::{as_format, renderer};
use digiview::detect::scan::{MOTION_VIEWS, visible};
use digiview::detect::{MotionDetector, Tracker};
use digiview::frame::PixelFormat;
use digiview::geometry::view::lens_from_world;
use digiview::render::Filter;
use digiview::scene::GridWorld;
use digiview::scene::synth::{eye, fisheye};
use digiview::state::State;
use glam::DVec3;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Scans at 4 Hz for 3.5 s with the vehicle yawing 30°/s, rolling ±8°, and (when `speed` is
/// not 0) flying north at `speed` m/s, over `world`: each mover in view at the end is tracked
/// within half its size of where it is, and nothing else is tracked. Returns the tracker.
fn tracks_every_mover(world: GridWorld, speed: f64) -> Tracker {
    let lens = common::small_lens("CIL216");
    let mut gpu = renderer(PixelFormat::I420, Filter::Mip);
    let mut detector = MotionDetector::new();
    let mut tracker = Tracker::new();
    let settings = digiview::state::DetectionSettings::default();
    let mut state = State::default();
    let start = state.vehicle.position;
    let mut last = None;
    let mut spent = vec![];
    for k in 0..14 {
        let t = k as f64 * 0.25;
        state.time = t;
        state.vehicle.attitude.yaw = 30.0 * DEG * t;
        state.vehicle.attitude.roll = 8.0 * DEG * (t * 2.0).sin();
        state.vehicle.position.lat = start.lat + speed * t / 111_320.0;
        let picture = fisheye(&world, &lens, &state);
        let (data, layout) = as_format(&picture, PixelFormat::Rgba);
        let to_lens = lens_from_world(state.vehicle.attitude.euler(), state.mount.euler());
        let (views, plan) = visible(&lens, to_lens, MOTION_VIEWS);
        let out = gpu.render(&data, &layout, &plan).unwrap();
        let t0 = std::time::Instant::now();
        let found = detector.detect(
            &views,
            &plan,
            &out.data,
            out.layout.stride as usize,
            eye(&state),
        );
        let covered = |b: &digiview::detect::AngularBox| {
            plan.views
                .iter()
                .any(|v| plan.view_point(v, b.centre).is_some())
        };
        spent.push(t0.elapsed());
        let changes = tracker.scan(&settings, t, found.clone(), covered);
        println!(
            "t {t:.2}: {} views, {} boxes, {:?}",
            views.len(),
            found.len(),
            changes
        );
        for d in &found {
            let (yaw, pitch) = d.bbox.yaw_pitch();
            println!(
                "  box at {:.1}° {:.1}°, {:.1}° x {:.1}°, {:.2}",
                yaw / DEG,
                pitch / DEG,
                d.bbox.width / DEG,
                d.bbox.height / DEG,
                d.confidence
            );
        }
        last = Some(state.clone());
    }
    spent.sort();
    println!(
        "detector: {:?} a scan (median), {:?} at most",
        spent[spent.len() / 2],
        spent.last().unwrap()
    );
    let state = last.unwrap();
    let eye = eye(&state);
    let to_lens = lens_from_world(state.vehicle.attitude.euler(), state.mount.euler());
    let mut matched = vec![false; tracker.objects().len()];
    for (m, mover) in world.movers.iter().enumerate() {
        let at = mover.position(state.time);
        let ray = (DVec3::new(at.x, at.y, 0.0) - eye).normalize();
        let Some(q) = lens.project(to_lens * ray).filter(|q| lens.in_frame(*q)) else {
            println!("mover {m} out of view");
            continue;
        };
        let size = 2.0 * (mover.radius / (DVec3::new(at.x, at.y, 0.0) - eye).length()).atan();
        let best = tracker
            .objects()
            .iter()
            .enumerate()
            .map(|(i, o)| (i, o.bbox.centre.angle_between(ray)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let (yaw, pitch) = digiview::geometry::rotation::yaw_pitch(ray);
        println!(
            "mover {m} at yaw {:.1}° pitch {:.1}°, fisheye {q:.0}, {:.1}° across: nearest track {:?}",
            yaw / DEG,
            pitch / DEG,
            size / DEG,
            best.map(|(i, a)| (i, a / DEG))
        );
        let (i, angle) = best.expect("a track");
        assert!(angle < size / 2.0, "mover {m}: {:.2}° off", angle / DEG);
        matched[i] = true;
    }
    let false_tracks: Vec<_> = tracker
        .objects()
        .iter()
        .zip(&matched)
        .filter(|(_, hit)| !**hit)
        .map(|(o, _)| {
            let (yaw, pitch) = o.bbox.yaw_pitch();
            (
                o.id,
                o.score,
                yaw / DEG,
                pitch / DEG,
                o.bbox.width / DEG,
                o.bbox.height / DEG,
            )
        })
        .collect();
    assert!(
        false_tracks.is_empty(),
        "tracks where no mover is: {false_tracks:.1?}"
    );
    tracker
}

#[test]
fn movers_are_tracked_while_the_vehicle_hovers_and_turns() {
    let tracker = tracks_every_mover(GridWorld::default(), 0.0);
    assert_eq!(tracker.objects().len(), 3);
}

#[test]
fn movers_are_tracked_while_the_vehicle_flies_and_turns() {
    let tracker = tracks_every_mover(GridWorld::default(), 5.0);
    assert_eq!(tracker.objects().len(), 3);
}

/// The same world with nothing moving in it, flown over and turned in: no track at all.
#[test]
fn a_still_world_flown_over_gives_no_track() {
    let world = GridWorld {
        movers: vec![],
        ..GridWorld::default()
    };
    assert!(tracks_every_mover(world, 5.0).objects().is_empty());
}

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
