//! KLV metadata in flight: a simulated autopilot yaws the vehicle 30°/s (and rolls it 4°)
//! while `serve`, on an image source (a camera's frames), publishes MPEG-TS over UDP. FFmpeg records it and klvdata reads it: every
//! packet's platform heading is the autopilot's yaw at that packet's capture time within
//! 0.5°, and camera 0, locked to the earth, keeps its world direction: its angles relative to
//! the airframe, composed with the platform's as read, give it back (they are made with the
//! same attitude sample that rendered the frame).

use crate::common;
use common::autopilot::{SimAutopilot, clock_zero_unix_s, free_udp_port};
use common::klv::{read_ts, record_ts, value};
use common::serve::Serve;
use common::{DEG, four_view_state};
use digiview::geometry::Euler;
use digiview::geometry::rotation::direction;
use digiview::state::view::Field;
use glam::DVec3;

const YAW_RATE: f64 = 30.0 * DEG;

fn yawing(t: f64) -> DVec3 {
    DVec3::new(
        (YAW_RATE * t).rem_euclid(2.0 * std::f64::consts::PI),
        0.0,
        4.0 * DEG,
    )
}

/// The angle from `b` to `a`, degrees, in -180..180.
fn turn(a: f64, b: f64) -> f64 {
    (a - b + 540.0).rem_euclid(360.0) - 180.0
}

#[test]
fn the_klv_heading_follows_a_yawing_autopilot_and_an_earth_locked_view_keeps_its_direction() {
    let _alone = crate::one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let mut state = four_view_state(7);
    let aim = [(Field::Yaw, 50.0 * DEG), (Field::Pitch, -40.0 * DEG)];
    state.settings.cameras[0] = state.settings.cameras[0].clone().with(&aim).unwrap();
    let state_file = dir.path().join("state.toml");
    std::fs::write(&state_file, toml::to_string(&state).unwrap()).unwrap();
    // A camera's frames, as a still: the autopilot is then the vehicle's only attitude (the
    // demo source would report its own flight beside it).
    let fisheye = dir.path().join("fisheye.png");
    common::synth_still(&fisheye);
    let (link, out) = (free_udp_port(), free_udp_port());
    let url = format!("udp://127.0.0.1:{out}");
    let _serve = Serve::start_video(&[
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--state",
        state_file.to_str().unwrap(),
        "--publish",
        &url,
        "--source",
        &format!("image:{}", fisheye.display()),
    ]);
    let _sim = SimAutopilot::start(&format!("udpout:127.0.0.1:{link}"), yawing);
    std::thread::sleep(std::time::Duration::from_secs(3));
    let ts = dir.path().join("flight.ts");
    let zero_before = clock_zero_unix_s();
    record_ts(&url, 6, &ts);
    // Capture times (UNIX µs) back onto the monotonic clock the autopilot's flight is a
    // function of. A system clock stepped meanwhile (NTP) moves the one against the other:
    // said beside a failure, as the cause a heading off by the step's 30°/s would have.
    let offset = clock_zero_unix_s();
    let stepped_ms = (offset - zero_before) * 1e3;
    let packets = read_ts(&ts);
    assert!(packets.len() >= 60, "{} packets", packets.len());
    let (mut worst_heading, mut worst_bearing) = (0.0f64, 0.0f64);
    let (mut worst_at, mut mean_heading) = (0, 0.0);
    for (i, p) in packets.iter().enumerate() {
        assert_eq!(p["checksum_ok"], true, "{p}");
        let t = p["values"]["2"].as_u64().unwrap() as f64 * 1e-6 - offset;
        let want = yawing(t).x.to_degrees();
        let off = turn(value(p, 5), want);
        mean_heading += off / packets.len() as f64;
        if off.abs() > worst_heading {
            (worst_heading, worst_at) = (off.abs(), i);
        }
        // The view's pointing relative to the airframe, turned into the world with the
        // platform's angles as read: camera 0's own direction, whatever the heading.
        let euler = |a: f64, b: f64, c: f64| Euler::new(a * DEG, b * DEG, c * DEG);
        let platform = euler(value(p, 5), value(p, 6), value(p, 7));
        let relative = euler(value(p, 18), value(p, 19), value(p, 20));
        let seen = platform.matrix() * relative.matrix() * DVec3::X;
        let off = seen.angle_between(direction(50.0 * DEG, -40.0 * DEG));
        worst_bearing = worst_bearing.max(off.to_degrees());
    }
    let first = value(&packets[0], 5);
    let last = value(&packets[packets.len() - 1], 5);
    eprintln!(
        "{} packets, heading {first:.1}° to {last:.1}°: off the autopilot by at most \
         {worst_heading:.3}° (packet {worst_at}), {mean_heading:+.3}° on average; camera 0 \
         off its own direction by at most {worst_bearing:.3}°; the system clock moved \
         {stepped_ms:+.1} ms against the monotonic one while recording",
        packets.len()
    );
    assert!(worst_heading <= 0.5, "heading off by {worst_heading:.3}°");
    assert!(worst_bearing <= 0.5, "camera 0 off by {worst_bearing:.3}°");
}
