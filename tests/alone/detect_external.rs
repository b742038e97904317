//! The external detector: a process that sends JSON lines over `serve`'s detections socket,
//! as a DeepStream or Hailo pipeline would. Boxes given as angles and as fisheye pixels are
//! tracked where they point, with their class names; a bad line is answered with why and
//! changes nothing; when the sender stops, its objects fade and go.

use crate::common;

use common::gcs::reported;
use digiview::geometry::rotation::direction;
use digiview::geometry::view::lens_from_world;
use digiview::lens::Lenses;
use digiview::state::State;
use glam::{DVec2, DVec3};
use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

const DEG: f64 = std::f64::consts::PI / 180.0;

#[test]
fn an_external_detectors_lines_are_tracked_where_they_point() {
    let _alone = crate::one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("detections.sock");
    let server = common::serve::Serve::start_video(&[
        "--demo-hover",
        "--detector",
        "external",
        "--detections-socket",
        socket.to_str().unwrap(),
    ]);
    let http = server.http.clone().unwrap();
    let stream = UnixStream::connect(&socket).expect("serve listens on its detections socket");
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let mut replies = BufReader::new(stream.try_clone().unwrap());
    let mut send = stream;

    // A car as angles; a person as fisheye pixels, where the demo's lens (the default state's,
    // on the demo's 1280x720 frames, looking down, the vehicle level) images 60° W, 50° down.
    let car = direction(30.0 * DEG, -40.0 * DEG);
    let person = direction(-60.0 * DEG, -50.0 * DEG);
    let state = State::default();
    let lens = Lenses::new(&common::lens_cal())
        .for_frame(state.settings.lens, (1280, 720), None)
        .unwrap();
    let to_lens = lens_from_world(state.vehicle.attitude.euler(), state.settings.mount.euler());
    let p = lens.project(to_lens * person).unwrap();
    let half = DVec2::new(6.0, 12.0);
    let line = serde_json::json!({
        "t": 0.0,
        "boxes": [
            {"yaw": 30.0, "pitch": -40.0, "width": 4.0, "height": 3.0, "confidence": 0.9, "class": "car"},
            {"x0": p.x - half.x, "y0": p.y - half.y, "x1": p.x + half.x, "y1": p.y + half.y,
             "confidence": 0.8, "class": "person"},
        ]
    });
    let start = Instant::now();
    let mut got = vec![];
    for i in 0..25 {
        let mut l = line.clone();
        l["t"] = serde_json::json!(i as f64 * 0.2);
        writeln!(send, "{l}").unwrap();
        std::thread::sleep(Duration::from_millis(200));
        got = reported(&http);
        if got.len() == 2 && i >= 5 {
            break;
        }
    }
    println!("after {:.1?}: {got:?}", start.elapsed());
    let off = |label: &str, truth: DVec3| {
        got.iter()
            .filter(|(l, _, _)| l == label)
            .map(|(_, d, _)| d.angle_between(truth) / DEG)
            .next()
    };
    let (car_off, person_off) = (off("car", car), off("person", person));
    println!("car {car_off:?}°, person {person_off:?}°");
    assert!(car_off.is_some_and(|o| o < 0.05), "{got:?}");
    assert!(person_off.is_some_and(|o| o < 0.1), "{got:?}");
    assert_eq!(got.len(), 2, "{got:?}");

    // Bad lines: each answered with why, and nothing changes.
    for (bad, says) in [
        (
            "{\"boxes\": [{\"yaw\": 0, \"pitch\": 100, \"width\": 1, \"height\": 1, \"confidence\": 0.5}]}",
            "pitch 100",
        ),
        ("not json at all", "error: line"),
        (
            "{\"boxes\": [{\"x0\": 5, \"y0\": 5, \"confidence\": 0.5}]}",
            "give x0",
        ),
    ] {
        writeln!(send, "{bad}").unwrap();
        let mut answer = String::new();
        replies.read_line(&mut answer).unwrap();
        assert!(
            answer.starts_with("error: line") && answer.contains(says),
            "{answer}"
        );
    }
    let long = format!("{{\"boxes\": [], \"pad\": \"{}\"}}", "x".repeat(70_000));
    writeln!(send, "{long}").unwrap();
    let mut answer = String::new();
    replies.read_line(&mut answer).unwrap();
    assert!(answer.contains("longer than"), "{answer}");
    assert_eq!(reported(&http).len(), 2);

    // The sender stops: every scan-less second the objects are missed, their scores fall
    // and they are dropped.
    drop(send);
    drop(replies);
    let gone = Instant::now();
    // Empty lines from a new sender: the detector looks and finds nothing.
    let mut again = UnixStream::connect(&socket).unwrap();
    while gone.elapsed() < Duration::from_secs(20) && !reported(&http).is_empty() {
        writeln!(again, "{{\"boxes\": []}}").unwrap();
        std::thread::sleep(Duration::from_millis(100));
    }
    println!("dropped after {:.1?}", gone.elapsed());
    assert!(reported(&http).is_empty());
}
