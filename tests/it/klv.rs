//! The KLV metadata (MISB ST 0601) of a view, read back by klvdata and stanag4609, readers
//! written by others (tests/peers/klv_read.py, misb_read.py): every packet's checksum valid, tag 2 first and tag 1
//! last; the platform's pose, the sensor's position and the view's fields of view as set; the
//! view's pointing relative to the airframe turning back into the camera's own world
//! direction; the frame centre where the camera's boresight meets the ground, worked out here
//! from the camera's angles alone; and a view raised above the horizon without a centre or
//! corners.

use crate::common;
use common::klv::{POSITION, extract, klvdata, metres, misb, pixel, read_ts, record_ts, value};
use common::*;
use digiview::geometry::Euler;
use digiview::geometry::ground::ground_point;
use digiview::geometry::rotation::direction;
use digiview::plan::FramePlan;
use digiview::state::view::Field::{Pitch, Yaw};
use digiview::stream::klv::ViewMetadata;
use glam::DVec3;
use serde_json::Value;
use std::process::Command;

const TIME_US: u64 = 1_764_150_000_123_456;

/// The packets of `metadata`, read back by klvdata: one JSON object each.
fn read_back(metadata: &[ViewMetadata]) -> Vec<Value> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("views.klv");
    let bytes: Vec<u8> = metadata.iter().flat_map(ViewMetadata::packet).collect();
    std::fs::write(&path, bytes).unwrap();
    let packets = klvdata(&path);
    assert_eq!(packets.len(), metadata.len());
    // stanag4609, strict about every field it knows, takes each packet and reads the same.
    for (k, (strict, p)) in misb(&path).iter().zip(&packets).enumerate() {
        assert!(strict.get("error").is_none(), "packet {k}: {strict}");
        for tag in [5, 13, 14, 23, 24, 82, 89] {
            let (a, b) = (
                &strict["values"][tag.to_string()],
                &p["values"][tag.to_string()],
            );
            if let (Some(a), Some(b)) = (a.as_f64(), b.as_f64()) {
                assert!((a - b).abs() < 1e-6, "packet {k}, tag {tag}: {a} and {b}");
            } else {
                assert_eq!(
                    a.is_null(),
                    b.is_null(),
                    "packet {k}, tag {tag}: {a} and {b}"
                );
            }
        }
    }
    packets
}

fn close(what: &str, got: f64, want: f64, tolerance: f64) {
    assert!(
        (got - want).abs() <= tolerance,
        "{what}: read {got}, want {want} (±{tolerance})"
    );
}

#[test]
fn klvdata_reads_a_views_pose_pointing_and_footprint_as_digiview_sees_them() {
    let lens = small_lens("CIL216");
    let mut state = four_view_state(7);
    state.vehicle.position = POSITION;
    // Flying: yawed, nose down 5°, rolled; then pitched up past tag 6's ±20°.
    let mut metadata = vec![];
    for (pitch, roll) in [(-5.0, 8.0), (35.0, -60.0)] {
        let a = &mut state.vehicle.attitude;
        (a.yaw, a.pitch, a.roll) = (30.0 * DEG, pitch * DEG, roll * DEG);
        // Camera 0 looks 45° east of north, 60° down, earth-locked; camera 1 10° up.
        let cams = &mut state.settings.cameras;
        cams[0] = cams[0]
            .clone()
            .with(&[(Yaw, 45.0 * DEG), (Pitch, -60.0 * DEG)])
            .unwrap();
        cams[1].put(Pitch, 10.0 * DEG).unwrap();
        for cam in [0, 1] {
            let plan = FramePlan::single_view(&state, &lens, cam, 640, 360);
            let source = format!("DigiView cam {cam}");
            metadata.push(
                ViewMetadata::of(
                    &plan,
                    &plan.views[0],
                    &state,
                    (TIME_US, Some((640, 360))),
                    source,
                )
                .unwrap(),
            );
        }
    }
    let packets = read_back(&metadata);
    for (k, (p, m)) in packets.iter().zip(&metadata).enumerate() {
        eprintln!("packet {k}: {p}");
        assert_eq!(p["checksum_ok"], true, "packet {k}");
        let tags: Vec<u64> = p["tags"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t.as_u64().unwrap())
            .collect();
        assert_eq!(
            (tags[0], tags[tags.len() - 1]),
            (2, 1),
            "packet {k}: {tags:?}"
        );
        assert!(tags.contains(&65), "packet {k}: {tags:?}");
        assert_eq!(p["values"]["2"].as_u64(), Some(TIME_US), "packet {k}");
        assert_eq!(p["values"]["11"], format!("DigiView cam {}", k % 2));
        close("heading", value(p, 5), 30.0, 0.01);
        let pitch = [-5.0, 35.0][k / 2];
        match pitch > 20.0 {
            false => close("pitch", value(p, 6), pitch, 0.001),
            true => close("pitch (full)", value(p, 90), pitch, 1e-6),
        }
        close("latitude", value(p, 13), 47.397, 1e-6);
        close("longitude", value(p, 14), 8.546, 1e-6);
        close("altitude", value(p, 15), 620.0, 0.4);
        close("hfov", value(p, 16), m.fov.0, 0.01);
        close("vfov", value(p, 17), m.fov.1, 0.01);
        // The view's pointing relative to the airframe, read back, turned into the world
        // with the platform's angles read back: the camera's own direction.
        let euler =
            |a: f64, b: f64, c: f64| Euler::new(a.to_radians(), b.to_radians(), c.to_radians());
        let platform = euler(value(p, 5), pitch, m.platform.roll);
        let relative = euler(value(p, 18), value(p, 19), value(p, 20));
        let seen = platform.matrix() * relative.matrix() * DVec3::X;
        let cam = &state.settings.cameras[k % 2];
        let want = direction(cam.yaw(), cam.pitch());
        let off = seen.angle_between(want).to_degrees();
        assert!(
            off < 0.01,
            "packet {k}: the boresight read back is {off}° off"
        );
        if k % 2 == 1 {
            // Above the horizon: no frame centre, no corners.
            assert!(
                !tags.iter().any(|t| [21, 23, 24, 25, 82, 89].contains(t)),
                "packet {k}: {tags:?}"
            );
            continue;
        }
        let (centre, range) = ground_point(&state.vehicle.position, want).unwrap();
        let miss = metres((value(p, 23), value(p, 24)), (centre.lat, centre.lon));
        assert!(
            miss < 0.1,
            "packet {k}: the frame centre is {miss:.3} m off"
        );
        close("centre elevation", value(p, 25), 500.0, 0.4);
        close("slant range", value(p, 21), range, 0.01);
        let corners = m.corners.unwrap();
        for (i, c) in corners.iter().enumerate() {
            let at = (value(p, 82 + 2 * i as u32), value(p, 83 + 2 * i as u32));
            let miss = metres(at, (c.lat, c.lon));
            assert!(miss < 0.01, "packet {k}: corner {i} is {miss:.3} m off");
        }
    }
}

/// `ffprobe -show_packets` of `ts`: (stream index, pts in seconds or NaN where it has none)
/// of every packet.
fn packets(ts: &std::path::Path) -> Vec<(u64, f64)> {
    let out = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-show_entries",
            "packet=stream_index,pts_time",
            "-of",
            "json",
        ])
        .arg(ts)
        .output()
        .unwrap();
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v["packets"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| {
            let pts = p["pts_time"].as_str().and_then(|t| t.parse().ok());
            Some((p["stream_index"].as_u64()?, pts.unwrap_or(f64::NAN)))
        })
        .collect()
}

/// `serve --publish udp://…`: FFmpeg receives MPEG-TS with the H.264 and a KLV data stream
/// (KLVA), one packet per picture (asynchronous carriage, as GStreamer 1.22's mpegtsmux
/// writes it: FFmpeg reads no PTS on them, so tag 2 is what ties a packet to its frame);
/// klvdata reads each packet
/// with a valid checksum, tag 2 first (the capture times a frame apart, on the UNIX clock)
/// and tag 1 last; the frame centre is where DigiView's own CAM_TARGET puts camera 0's centre
/// pixel on the ground.
#[test]
fn serve_publishes_mpegts_over_udp_whose_klv_ffmpeg_and_klvdata_read() {
    let port = common::autopilot::free_udp_port();
    let url = format!("udp://127.0.0.1:{port}");
    let view_url = format!("udp://127.0.0.1:{}", common::autopilot::free_udp_port());
    let serve = common::serve::Serve::start_video(&[
        "--size",
        "640x480",
        "--demo-hover",
        "--track",
        "yaw=5deg,pitch=-35deg,size=6deg,score=70,id=4",
        "--publish",
        &url,
        "--publish-view",
        &format!("2={view_url}"),
    ]);
    let dir = tempfile::tempdir().unwrap();
    let ts = dir.path().join("out.ts");
    let view_ts = dir.path().join("cam2.ts");
    let view = {
        let (url, ts) = (view_url.clone(), view_ts.clone());
        std::thread::spawn(move || record_ts(&url, 5, &ts))
    };
    record_ts(&url, 5, &ts);
    view.join().unwrap();
    let probe = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-show_entries",
            "stream=codec_name,codec_tag_string",
        ])
        .args(["-of", "csv=p=0"])
        .arg(&ts)
        .output()
        .unwrap();
    let streams = String::from_utf8_lossy(&probe.stdout).to_string();
    assert!(
        streams.contains("h264") && streams.contains("klv,KLVA"),
        "{streams}"
    );
    // One KLV packet a picture, counted live over 4 s.
    let live = Command::new("timeout")
        .args(["15", "ffprobe", "-v", "error", "-read_intervals", "%+4"])
        .args([
            "-show_entries",
            "packet=stream_index",
            "-of",
            "csv=p=0",
            &url,
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&live.stdout);
    let count = |i: &str| {
        text.lines()
            .filter(|l| l.trim_end_matches(',') == i)
            .count()
    };
    let (pictures, klv_packets) = (count("0"), count("1"));
    eprintln!("live, 4 s: {pictures} pictures, {klv_packets} KLV packets");
    assert!(pictures >= 30, "{pictures} pictures");
    assert!(
        pictures.abs_diff(klv_packets) <= 2,
        "{klv_packets} KLV packets for {pictures} pictures"
    );
    // The KLV packets carry no PTS as FFmpeg reads them (asynchronous carriage).
    let all = packets(&ts);
    let data: Vec<f64> = all.iter().filter(|p| p.0 == 1).map(|p| p.1).collect();
    assert!(data.len() >= 30, "{} KLV packets", data.len());
    eprintln!(
        "{} KLV packets, {} with a PTS",
        data.len(),
        data.iter().filter(|d| d.is_finite()).count()
    );
    // The KLV itself, through klvdata.
    let read = read_ts(&ts);
    assert_eq!(read.len(), data.len(), "packets klvdata read");
    let mut times = vec![];
    for p in &read {
        assert_eq!(p["checksum_ok"], true, "{p}");
        let tags = p["tags"].as_array().unwrap();
        assert_eq!(
            (&tags[0], &tags[tags.len() - 1]),
            (&Value::from(2), &Value::from(1))
        );
        times.push(p["values"]["2"].as_u64().unwrap());
    }
    let gaps: Vec<u64> = times
        .windows(2)
        .map(|w| w[1].saturating_sub(w[0]))
        .collect();
    assert!(
        times.windows(2).all(|w| w[1] > w[0]),
        "capture times go back"
    );
    let mut sorted = gaps.clone();
    sorted.sort();
    let median = sorted[sorted.len() / 2];
    assert!(
        (20_000..=100_000).contains(&median),
        "a frame apart: {median} µs"
    );
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_micros() as u64;
    let age = now.saturating_sub(*times.last().unwrap());
    assert!(age < 10_000_000, "the last capture time is {age} µs ago");
    // The frame centre, against CAM_TARGET's ground point for camera 0's centre pixel (a
    // hair below it: x = y = 0 asks for the set target).
    let reply = ctl(
        &serve.addr.to_string(),
        &["--json", "get", "cam_target", "cam_id=0", "x=0", "y=0.0001"],
    );
    let t: Value = serde_json::from_slice(&reply.stdout).unwrap();
    let (lat, lon) = (
        t["values"]["t_latitude"].as_f64().unwrap(),
        t["values"]["t_longitude"].as_f64().unwrap(),
    );
    let last = read.last().unwrap();
    let miss = metres((value(last, 23), value(last, 24)), (lat, lon));
    eprintln!(
        "frame centre {:.6}, {:.6}; CAM_TARGET {lat}, {lon}: {miss:.2} m",
        value(last, 23),
        value(last, 24)
    );
    assert!(
        miss < 2.0,
        "the frame centre is {miss:.2} m from CAM_TARGET's"
    );
    // The web API's status shows the last frame's metadata field by field.
    let status = format!("{}api/status", serve.http.as_ref().unwrap());
    let (code, body) = common::gcs::http_get(&status);
    assert_eq!(code, 200);
    let klv: Value = serde_json::from_slice::<Value>(&body).unwrap()["video"]["klv"].clone();
    assert_eq!(klv["source"], "DigiView cam 0", "{klv}");
    let centre = &klv["centre"]["point"];
    let at = (
        centre["lat"].as_f64().unwrap(),
        centre["lon"].as_f64().unwrap(),
    );
    assert!(metres(at, (lat, lon)) < 2.0, "{klv}");
    assert!(
        klv["time_us"].as_u64().unwrap() > *times.last().unwrap(),
        "{klv}"
    );
    // The tracked object, in the same stream's VMTI as stanag4609 reads it: where DETECTED_ROI
    // puts it on the ground and the web API (what the page draws) in the composed frame.
    let strict = misb(&extract(&ts));
    assert_eq!(strict.len(), read.len());
    assert!(
        strict.iter().all(|p| p.get("error").is_none()),
        "{strict:?}"
    );
    let vmti = &strict.last().unwrap()["vmti"];
    let t = vmti["targets"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["id"] == 4);
    let t = t.unwrap_or_else(|| panic!("object 4 is not in {vmti}"));
    let params = format!("{}api/params", serve.http.as_ref().unwrap());
    let (_, body) = common::gcs::http_get(&params);
    let roi = &serde_json::from_slice::<Value>(&body).unwrap()["DETECTED_ROI"][0];
    let seen = roi["views"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["cam"] == 0);
    let seen = seen.unwrap_or_else(|| panic!("camera 0 does not show object 4: {roi}"));
    let at = glam::DVec2::new(seen["x"].as_f64().unwrap(), seen["y"].as_f64().unwrap());
    let width = vmti["fields"]["frameWidth"].as_u64().unwrap();
    assert_eq!(width, 640, "{vmti}");
    let px = |tag: &str| pixel(&t[tag], width);
    let (centre, tl, br) = (
        px("targetCentroid"),
        px("boundingBoxTopLeft"),
        px("boundingBoxBottomRight"),
    );
    eprintln!(
        "VMTI object 4: {t}; the page's ring at {at}, radius {}",
        seen["radius"]
    );
    assert!(centre.distance(at) < 2.0, "centroid {centre}, ring {at}");
    let radius = seen["radius"].as_f64().unwrap();
    assert!(
        ((br - tl).x - 2.0 * radius).abs() < 2.5,
        "box {tl}..{br}, radius {radius}"
    );
    let ground = (
        t["targetLocation"]["lat"].as_f64().unwrap(),
        t["targetLocation"]["lon"].as_f64().unwrap(),
    );
    let want = (
        roi["latitude"].as_f64().unwrap(),
        roi["longitude"].as_f64().unwrap(),
    );
    let miss = metres(ground, want);
    assert!(
        miss < 2.0,
        "object 4 is {miss:.2} m from DETECTED_ROI's point"
    );
    // Camera 2's own stream, published beside it (--publish-view), describes camera 2: its
    // frame centre 173 m from camera 0's (north and south, 30° down from 50 m), its VMTI
    // frame the view's own size.
    let view = misb(&extract(&view_ts));
    assert!(
        view.len() >= 10,
        "{} packets from camera 2's relay",
        view.len()
    );
    let p = view.last().unwrap();
    assert!(p.get("error").is_none(), "{p}");
    assert_eq!(p["values"]["11"], "DigiView cam 2", "{p}");
    assert_eq!(p["vmti"]["fields"]["frameWidth"], 1280, "{p}");
    let centre = |p: &Value| (value(p, 23), value(p, 24));
    let apart = metres(centre(p), centre(strict.last().unwrap()));
    eprintln!(
        "camera 2's relay: {} packets; frame centres {apart:.1} m apart",
        view.len()
    );
    assert!((apart - 173.2).abs() < 2.0, "{apart:.1} m apart");
}

/// `[capture] container = "ts"`: the composed stream's recording and camera 2's own (started
/// over MAVLink, as a ground station does) are MPEG-TS whose KLV klvdata reads (whole, with
/// `klv_objects = false`: no tag 74), a packet with every frame over the 4 s recorded, each
/// describing its own view: the composed one camera 0 (`klv_camera`), camera 2's itself,
/// their frame centres as far apart as the two cameras look.
#[test]
fn ts_recordings_carry_each_views_own_klv() {
    use common::gcs::{Gcs, accepted, cameras, params};
    use common::serve::CaptureConfig;
    use mavlink::dialects::common::MavCmd;
    let config = CaptureConfig::new(
        "klv_objects = false\n[cameras]\nwidth = 640\nheight = 480\n",
        "min_free_mb = 1\ncontainer = \"ts\"\n",
    );
    let port = common::autopilot::free_udp_port();
    let serve = common::serve::Serve::start_video(&[
        "--config",
        config.path(),
        "--mavlink",
        &format!("udpin:127.0.0.1:{port}"),
        "--size",
        "640x480",
        "--demo-hover",
    ]);
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);
    let addr = serve.addr.to_string();
    let start = MavCmd::MAV_CMD_VIDEO_START_CAPTURE;
    accepted(
        gcs.command(system, 102, start, params(&[])),
        "camera 2 records",
    );
    let o = ctl(&addr, &["set", "capture", "flags=2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::thread::sleep(std::time::Duration::from_secs(4));
    let o = ctl(&addr, &["set", "capture", "flags=0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stop = MavCmd::MAV_CMD_VIDEO_STOP_CAPTURE;
    accepted(
        gcs.command(system, 102, stop, params(&[])),
        "camera 2 stops",
    );
    std::thread::sleep(std::time::Duration::from_millis(500));
    let files: Vec<_> = std::fs::read_dir(&config.captures)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ts"))
        .collect();
    let find = |cam2: bool| {
        let f = files
            .iter()
            .find(|p| p.to_string_lossy().ends_with("-cam2.ts") == cam2);
        f.unwrap_or_else(|| panic!("no recording (camera 2: {cam2}) in {files:?}"))
    };
    let mut centres = vec![];
    for (path, name) in [
        (find(false), "DigiView cam 0"),
        (find(true), "DigiView cam 2"),
    ] {
        let packets = read_ts(path);
        let (frames, _) = common::probe_frames(path);
        let time = |p: &serde_json::Value| p["values"]["2"].as_u64().unwrap_or(0);
        let span_s = packets
            .last()
            .map_or(0, time)
            .saturating_sub(packets.first().map_or(0, time)) as f64
            * 1e-6;
        eprintln!(
            "{}: {} KLV packets, {frames} frames, over {span_s:.2} s",
            path.display(),
            packets.len()
        );
        // Every frame with its packet (the recording's first and last may part at its ends),
        // from the start of the 4 s to their end: whatever rate the machine draws the view at.
        assert!(
            (packets.len() as i64 - frames as i64).abs() <= 1,
            "{}: {} packets for {frames} frames",
            path.display(),
            packets.len()
        );
        assert!(
            span_s >= 3.5,
            "{}: packets over {span_s:.2} s",
            path.display()
        );
        for p in &packets {
            assert_eq!(p["checksum_ok"], true, "{p}");
            assert_eq!(p["values"]["11"], name, "{}", path.display());
            // klv_objects = false: no tag 74, so klvdata 0.0.3 reads them whole.
            assert_eq!(p["skipped"], serde_json::json!([]), "{p}");
        }
        let last = packets.last().unwrap();
        centres.push((value(last, 23), value(last, 24)));
    }
    // Camera 0 looks north and camera 2 south, 30° down from 50 m: 173 m apart.
    let (a, b) = (centres[0], centres[1]);
    let apart = metres(a, b);
    eprintln!("frame centres {a:?} and {b:?}: {apart:.1} m apart");
    assert!((apart - 173.2).abs() < 2.0, "{apart:.1} m apart");
}
