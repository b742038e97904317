//! `serve --thermal demo` read over the web API as a script reads it and over MAVLink as
//! pymavlink reads it (CAMERA_THERMAL_RANGE): the demo's thermal camera, mounted to look at
//! the car whose engine bay is 338.15 K (the movers standing where they start, the vehicle
//! hovering), gives the hottest point of what a view shows in the view's own pixels, within
//! 0.2 K and 1 px of where the engine's centre is, while the view is turned across it; the
//! temperature at any of its pixels; and clear refusals.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::LinePeer;
use common::serve::Serve;
use common::thermal::{aimed, engine_ray, engine_serve, mount_towards};
use digiview::geometry::Euler;
use digiview::lens::Lenses;
use digiview::plan::FramePlan;
use digiview::scene::thermal::{MOVER_KELVIN, world_from_thermal};
use digiview::state::State;
use digiview::state::view::{Camera, Field};
use serde_json::Value;
use std::time::{Duration, Instant};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// One request, `Connection: close`: the status and the JSON body.
pub(crate) fn request(host: &str, method: &str, path: &str, body: &str) -> (u16, Value) {
    let (status, body) = common::raw_request(host, method, path, &[("Host", host)], body).unwrap();
    (status, serde_json::from_str(&body).unwrap_or(Value::Null))
}

#[test]
fn the_hottest_point_follows_the_engine_in_the_view_s_pixels_as_the_view_turns() {
    let state = State::default();
    let ray = engine_ray(&state);
    let mount = mount_towards(&state, ray);
    let (yaw, pitch) = (ray.y.atan2(ray.x), -ray.z.asin());
    let (serve, mut station, ready) = engine_serve(mount, (yaw, pitch));
    // CAMERA_CAP_FLAGS_HAS_THERMAL_RANGE.
    let flags = ready["flags"].as_u64().unwrap_or(0);
    assert_ne!(flags & 4096, 0, "{ready}");
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    // The first thermal frame.
    let end = Instant::now() + Duration::from_secs(20);
    while request(host, "GET", "/api/thermal?camera=0", "").0 != 200 {
        assert!(Instant::now() < end, "no thermal frame in 20 s");
        std::thread::sleep(Duration::from_millis(100));
    }
    let fisheye = Lenses::new(&common::lens_cal())
        .for_frame(0, (1280, 720), None)
        .unwrap();
    // The view turned across the engine, 6° at a time, each aim read back.
    for turn in [-12.0, -6.0, 0.0, 6.0, 12.0] {
        let view_yaw = yaw + turn * DEG;
        let body = format!("{{\"cam_id\": 0, \"yaw\": {view_yaw}, \"pitch\": {pitch}}}");
        let (code, set) = request(host, "PUT", "/api/params/CAM_EULER", &body);
        assert_eq!(code, 200, "{set}");
        let s = aimed(&state, view_yaw, pitch);
        let plan = FramePlan::single_view(&s, &fisheye, 0, 1280, 720);
        let truth = plan
            .view_point(&plan.views[0], ray)
            .expect("the engine in view");
        let (code, read) = request(host, "GET", "/api/thermal?camera=0", "");
        assert_eq!(code, 200, "{read}");
        let hot = &read["hottest"];
        let at = |k: &str| hot[k].as_f64().unwrap_or(f64::NAN);
        let off = (at("x") - truth.x).hypot(at("y") - truth.y);
        assert!(
            off <= 1.0,
            "turned {turn}°: {off:.2} px from {truth}: {read}"
        );
        assert!(
            (at("kelvin") - MOVER_KELVIN[2]).abs() <= 0.2,
            "turned {turn}°: {read}"
        );
        assert_eq!(
            (read["width"].as_u64(), read["height"].as_u64()),
            (Some(1280), Some(720))
        );
        // The temperature at the engine's centre, asked by its pixel.
        let path = format!("/api/thermal?camera=0&x={}&y={}", truth.x, truth.y);
        let (code, read) = request(host, "GET", &path, "");
        assert_eq!(code, 200, "{read}");
        let spot = read["spot"]["kelvin"].as_f64().unwrap();
        assert!((spot - MOVER_KELVIN[2]).abs() <= 0.2, "{read}");
        // The same over MAVLink: °C, the point normalized to the view's picture.
        let heard = station.ask(&serde_json::json!({"camera": 100}));
        assert_eq!(heard["result"], "MAV_RESULT_ACCEPTED", "{heard}");
        let range = &heard["range"];
        let f = |k: &str| range[k].as_f64().unwrap_or(f64::NAN);
        let (x, y) = (f("max_point_x") * 1280.0, f("max_point_y") * 720.0);
        let off = (x - truth.x).hypot(y - truth.y);
        assert!(
            off <= 1.0,
            "MAVLink, turned {turn}°: {off:.2} px from {truth}: {heard}"
        );
        let celsius = MOVER_KELVIN[2] - 273.15;
        assert!((f("max") - celsius).abs() <= 0.2, "{heard}");
        assert!(f("min") < f("max"), "{heard}");
        assert_eq!(range["stream_id"], 1, "{heard}");
    }
    // Refusals in words: a view that is not one, a pixel that is not the view's, half a
    // pixel, a pixel the thermal camera does not see.
    for (path, words) in [
        (
            "/api/thermal?camera=7",
            "camera 7 is not a view: give 0 to 3",
        ),
        (
            "/api/thermal?camera=0&x=2000&y=10",
            "is not a pixel of camera 0's 1280x720",
        ),
        ("/api/thermal?camera=0&x=10", "x, y: give both"),
        ("/api/thermal?camera=0&x=nan&y=1", "x, y: give both"),
        (
            "/api/thermal?camera=2&x=640&y=360",
            "outside what the thermal camera sees",
        ),
    ] {
        let (code, read) = request(host, "GET", path, "");
        assert_eq!(code, 400, "{path}: {read}");
        let error = read["error"].as_str().unwrap_or_default();
        assert!(error.contains(words), "{path}: {error}");
    }
    // The status says what the sensor is doing.
    let (_, status) = request(host, "GET", "/api/status", "");
    let thermal = &status["video"]["thermal"];
    assert_eq!(thermal["source"], "demo", "{status}");
    assert_eq!(thermal["size"], serde_json::json!([320, 256]), "{status}");
    assert!(thermal["frames"].as_u64().unwrap() > 0, "{status}");
}

/// Without a sensor: the web API says how to start one, the DigiView protocol refuses to
/// colour or show a thermal picture (saying so), and the cameras neither claim a thermal
/// range nor answer for one, nor take IR as their source (pymavlink).
#[test]
fn without_a_thermal_sensor_the_api_says_how_to_start_one() {
    let link = free_udp_port();
    let serve = Serve::start_video(&["--mavlink", &format!("udpin:127.0.0.1:{link}")]);
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let (code, read) = request(host, "GET", "/api/thermal?camera=0", "");
    assert_eq!(code, 404, "{read}");
    assert!(
        read["error"].as_str().unwrap().contains("--thermal SOURCE"),
        "{read}"
    );
    let addr = serve.addr.to_string();
    for (args, taken) in [
        (&["set", "thermal", "palette=2"][..], false),
        (&["set", "cam_thermal", "cam=0", "show=2"], false),
        (&["set", "cam_thermal", "cam=0", "show=0"], true),
    ] {
        let out = common::ctl(&addr, args);
        let said = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.success(), taken, "{args:?}: {said}");
        assert!(
            taken || said.contains("no thermal sensor"),
            "{args:?}: {said}"
        );
    }
    let (mut station, ready) = LinePeer::start("thermal_station.py", &[&link.to_string()]);
    assert_eq!(ready["ready"], true, "the station heard camera 100");
    assert_eq!(ready["flags"].as_u64().unwrap() & 4096, 0, "{ready}");
    let heard = station.ask(&serde_json::json!({"camera": 100}));
    assert_eq!(heard["result"], "MAV_RESULT_UNSUPPORTED", "{heard}");
    assert_eq!(heard["range"], Value::Null, "{heard}");
    // No IR source to pick; the fisheye alone still is.
    for (sources, result) in [
        ([2, 0], "MAV_RESULT_DENIED"),
        ([1, 0], "MAV_RESULT_ACCEPTED"),
    ] {
        let heard = station.ask(&serde_json::json!({"camera": 100, "source": sources}));
        assert_eq!(heard["result"], result, "{sources:?}: {heard}");
    }
}

/// A 16-bit source through a real GStreamer pipeline (a raw GRAY16_LE file looped and parsed
/// by `rawvideoparse`, as a recorded core's output is replayed) runs beside the fisheye: its
/// frames arrive at its size and rate while the composed stream keeps coming, and the temperature at a
/// view's pixel is the file's counts where the two mounts put that pixel.
#[test]
fn a_16_bit_gstreamer_source_runs_beside_the_fisheye() {
    let (w, h) = (160u32, 120u32);
    // A ramp: 2.5 K a row down, 0.1 K a column across, from 200 K.
    let counts = |x: f64, y: f64| 20_000.0 + 250.0 * y + 10.0 * x;
    let dir = tempfile::tempdir().unwrap();
    let raw = dir.path().join("ramp.raw");
    let bytes: Vec<u8> = (0..w * h)
        .flat_map(|i| (counts((i % w) as f64, (i / w) as f64) as u16).to_le_bytes())
        .collect();
    std::fs::write(&raw, bytes).unwrap();
    let source = format!(
        "gst:multifilesrc location={} loop=true ! rawvideoparse format=gray16-le width={w} \
         height={h} framerate=9/1",
        raw.display()
    );
    let view = [
        (Field::Yaw, 0.0),
        (Field::Pitch, -90.0 * DEG),
        (Field::Fov, 90.0 * DEG),
    ];
    let started = Instant::now();
    let serve = Serve::start_video(&[
        "--thermal",
        &source,
        "--demo-hover",
        "--cam",
        "0:yaw=0,pitch=-90deg,fov=90deg",
    ]);
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let end = Instant::now() + Duration::from_secs(20);
    let status = loop {
        let (_, status) = request(host, "GET", "/api/status", "");
        // The fisheye's frames and the stream's, each over the last second, both going: read
        // from one status, as the test's other tests ran beside it on two cores.
        let frames = status["video"]["thermal"]["frames"].as_u64();
        let going = |k: &str| status["video"][k].as_f64() > Some(5.0);
        if frames >= Some(18) && going("fps_out") && going("fps_in") {
            break status;
        }
        assert!(
            Instant::now() < end,
            "in 20 s, not 18 thermal frames and the fisheye and the stream going: {status}"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    let thermal = &status["video"]["thermal"];
    assert_eq!(thermal["size"], serde_json::json!([w, h]), "{status}");
    assert_eq!(thermal["error"], Value::Null, "{status}");
    // Paced at the file's 9 frames a second, not read as fast as the CPU goes (twice that
    // at most, whatever the machine).
    let most = 18.0 * started.elapsed().as_secs_f64();
    let frames = thermal["frames"].as_u64().unwrap() as f64;
    assert!(
        frames <= most,
        "{frames} thermal frames, {most} at most: {status}"
    );
    // Where the mounts put view pixels in the thermal frame (the default mount: looking where
    // the fisheye looks, straight down), and the file's counts there.
    let mut state = State::default();
    state.settings.cameras[0] = Camera::numbered(0).with(&view).unwrap();
    let fisheye = Lenses::new(&common::lens_cal())
        .for_frame(0, (1280, 720), None)
        .unwrap();
    let plan = FramePlan::single_view(&state, &fisheye, 0, 1280, 720);
    let cal = common::lens_cal();
    let lens = cal.find("BOSON320").unwrap().lens().for_frame(w, h, None);
    let to_thermal = world_from_thermal(&state, Euler::default()).transpose();
    for (x, y) in [
        (640.0, 360.0),
        (640.0, 300.0),
        (640.0, 420.0),
        (700.0, 330.0),
    ] {
        let ray = plan
            .view_ray(&plan.views[0], glam::DVec2::new(x, y))
            .unwrap();
        // OpenCV's pixel centres are whole: the file's pixel (i, j) is there.
        let q = lens.project(to_thermal * ray).unwrap();
        let want = counts(q.x, q.y) * 0.01;
        let path = format!("/api/thermal?camera=0&x={x}&y={y}");
        let (code, read) = request(host, "GET", &path, "");
        assert_eq!(code, 200, "{read}");
        let got = read["spot"]["kelvin"].as_f64().unwrap();
        assert!(
            (got - want).abs() < 0.05,
            "({x}, {y}): {got} K, the file {want} K"
        );
    }
}
