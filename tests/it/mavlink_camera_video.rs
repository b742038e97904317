//! What the MAVLink cameras show, end to end: each camera's own stream is the offline render
//! of its view and follows zoom and gimbal commands; angular rates turn it; image and video
//! capture record the view alone; DO_SET_ROI_LOCATION keeps a landmark of the demo's world
//! centred while the vehicle flies past it. A ground station written with the `mavlink`
//! crate (tests/common/gcs.rs) against `digiview serve`.

use crate::common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, REQUEST, accepted, cameras, euler, fov, http_get, image_capture, params};
use common::serve::Serve;
use common::viewer::Viewer;
use digiview::control::client::Client;
use digiview::image_ops;
use digiview::layout::Rect;
use digiview::protocol::Param;
use digiview::protocol::params::CamEuler;
use image::RgbImage;
use mavlink::dialects::common::*;
use std::f64::consts::PI;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const DEG: f64 = PI / 180.0;

/// The offline render of camera `cam` of serve's default state alone at `size`x`size`
/// (layout 0 is one centred square: the whole frame), from `fish`.
fn offline_view(dir: &Path, cam: &str, size: u32, out: &str) -> RgbImage {
    let size = format!("{size}x{size}");
    let run = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "render", "--input", "fish.png", "--out", out, "--size", &size,
        ])
        .args(["--layout", "0", "--overlay", "0", "--cam", cam])
        .current_dir(dir)
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    image::open(dir.join(out)).unwrap().to_rgb8()
}

fn psnr(a: &RgbImage, b: &RgbImage) -> f64 {
    image_ops::psnr(a, b, Rect::new(0, 0, a.width(), a.height()))
}

#[test]
fn a_cameras_stream_is_its_view_and_follows_zoom_gimbal_and_capture() {
    const SIZE: u32 = 640;
    let dir = tempfile::tempdir().unwrap();
    let synth = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["synth", "--out", "fish.png", "--sensor", "1280x720"])
        .current_dir(dir.path())
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .output()
        .unwrap();
    assert!(synth.status.success());
    let captures = dir.path().join("captures");
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        format!(
            "[cameras]\nwidth = {SIZE}\nheight = {SIZE}\npublic_host = \"127.0.0.1\"\n\
             [capture]\ndir = {:?}\nmin_free_mb = 1\n",
            captures.to_str().unwrap()
        ),
    )
    .unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let source = format!("image:{}", dir.path().join("fish.png").display());
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--mavlink",
        &link,
        "--source",
        &source,
    ]);
    let rtsp = serve.rtsp.clone().unwrap();
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert!(seen.contains(&102));

    // Every camera's stream 1 plays, its view at the configured size.
    for c in [100, 101, 103] {
        let then = accepted(
            gcs.command(system, c, REQUEST, params(&[269.0, 1.0])),
            "stream",
        );
        let uri = match &then[..] {
            [MavMessage::VIDEO_STREAM_INFORMATION(v), ..] => v.uri.to_str().unwrap().to_string(),
            other => panic!("{other:?}"),
        };
        assert_eq!(uri, format!("{rtsp}/cam{}", c - 100));
        let frame = Viewer::open(&uri).frame().0;
        assert_eq!(frame.dimensions(), (SIZE, SIZE), "{uri}");
    }
    // FFmpeg, a second RTSP client, sees a view's stream too.
    let probe = common::probe_rtsp(&format!("{rtsp}/cam1"), "codec_name,width,height");
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        format!("h264,{SIZE},{SIZE}"),
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );

    // Camera 2's stream 1: its view alone, the offline render of that view.
    let then = accepted(
        gcs.command(system, 102, REQUEST, params(&[269.0, 1.0])),
        "stream 1",
    );
    let uri = match &then[..] {
        [MavMessage::VIDEO_STREAM_INFORMATION(v), ..] => {
            assert_eq!((v.resolution_h, v.resolution_v), (SIZE as u16, SIZE as u16));
            assert_eq!(v.hfov, 90);
            v.uri.to_str().unwrap().to_string()
        }
        other => panic!("{other:?}"),
    };
    assert_eq!(uri, format!("{rtsp}/cam2"));
    let viewer = Viewer::open(&uri);
    let got = viewer.frame_after(Duration::from_secs(1));
    assert_eq!(got.dimensions(), (SIZE, SIZE));
    let want = offline_view(dir.path(), "0:yaw=180deg,pitch=-30deg", SIZE, "cam2.png");
    let db = psnr(&want, &got);
    eprintln!("camera 2's own stream: {db:.1} dB against the offline render of its view");
    assert!(db >= 30.0, "{db:.1} dB");

    // Zoom to a 40° fov and point the gimbal at yaw 60°, pitch -50° (earth frame): the
    // control protocol reads both back and the picture is the render of the new view.
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let then = accepted(
        gcs.command(
            system,
            102,
            MavCmd::MAV_CMD_SET_CAMERA_ZOOM,
            params(&[4.0, 40.0]),
        ),
        "zoom",
    );
    assert!(matches!(then[..], [MavMessage::CAMERA_SETTINGS(_), ..]));
    // CAM_EULER and CAM_FOV carry angles to about 0.02° on the wire.
    assert!((fov(&mut ctl, 2) - 40.0).abs() < 0.05);
    let locks = (GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_ROLL_LOCK
        | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_PITCH_LOCK
        | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_LOCK)
        .bits() as f32;
    accepted(
        gcs.command(
            system,
            102,
            MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            params(&[-50.0, 60.0, f32::NAN, f32::NAN, locks, 0.0, 0.0]),
        ),
        "pitch and yaw",
    );
    let (yaw, pitch, _) = euler(&mut ctl, 2);
    assert!(
        (yaw - 60.0).abs() < 0.05 && (pitch + 50.0).abs() < 0.05,
        "{yaw} {pitch}"
    );
    let got = viewer.frame_after(Duration::from_secs(1));
    let want = offline_view(
        dir.path(),
        "0:yaw=60deg,pitch=-50deg,fov=40deg",
        SIZE,
        "aimed.png",
    );
    let db = psnr(&want, &got);
    eprintln!("after zoom and gimbal: {db:.1} dB against the offline render");
    assert!(db >= 30.0, "{db:.1} dB");

    // A CAM_EULER over the DigiView protocol shows in the gimbal's attitude within 0.2 s.
    gcs.forget();
    ctl.set(Param::CamEuler(CamEuler {
        cam_id: 2,
        is_delta: 0,
        yaw: -45.0 * DEG,
        pitch: -20.0 * DEG,
        roll: 0.0,
    }))
    .unwrap();
    let set_at = Instant::now();
    let seen_at = gcs.wait_for(Duration::from_secs(2), |h, m| match m {
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(a) if h.component_id == 102 => {
            let [w, x, y, z] = a.q.map(f64::from);
            let q = glam::DQuat::from_xyzw(x, y, z, w);
            let (yaw, pitch, _) = q.to_euler(glam::EulerRot::ZYX);
            ((yaw / DEG + 45.0).abs() < 0.1 && (pitch / DEG + 20.0).abs() < 0.1).then(Instant::now)
        }
        _ => None,
    });
    let lag = seen_at.expect("the new attitude reported") - set_at;
    eprintln!(
        "CAM_EULER to GIMBAL_DEVICE_ATTITUDE_STATUS: {} ms",
        lag.as_millis()
    );
    assert!(lag < Duration::from_millis(200), "{lag:?}");

    // An angular rate turns the view at that rate, until a zero rate stops it.
    let yaw_rate = |rate: f64| {
        gcs.send(&MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(
            GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                flags: GimbalManagerFlags::from_bits_truncate(locks as u32),
                pitch: f32::NAN,
                yaw: f32::NAN,
                pitch_rate: 0.0,
                yaw_rate: (rate * DEG) as f32,
                target_system: system,
                target_component: 102,
                gimbal_device_id: 0,
            },
        ))
    };
    yaw_rate(20.0);
    let t0 = Instant::now();
    std::thread::sleep(Duration::from_millis(300));
    let (a, ta) = (euler(&mut ctl, 2).0, t0.elapsed());
    std::thread::sleep(Duration::from_secs(2));
    let (b, tb) = (euler(&mut ctl, 2).0, t0.elapsed());
    let rate = (b - a) / (tb - ta).as_secs_f64();
    eprintln!("yaw rate asked 20°/s, turned at {rate:.2}°/s");
    assert!((rate - 20.0).abs() < 2.0, "{rate}");
    yaw_rate(0.0);
    std::thread::sleep(Duration::from_millis(200));
    let stopped = euler(&mut ctl, 2).0;
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(euler(&mut ctl, 2).0, stopped, "a zero rate stops it");

    // Image capture of camera 2's view: two images, each a file of the view's size,
    // announced with its index.
    let images = image_capture(&gcs, (system, 102), 2, 0.5);
    for (i, c) in images.iter().enumerate() {
        assert_eq!(c.image_index, i as i32);
        assert_eq!(c.capture_result, MavBool::MAV_BOOL_TRUE);
        // The file's URL is on the head's HTTP server: the JPEG of the view's size.
        let url = c.file_url.to_str().unwrap();
        let (status, jpeg) = http_get(url);
        assert_eq!(status, 200, "{url}");
        let img = image::load_from_memory(&jpeg).unwrap();
        assert_eq!((img.width(), img.height()), (SIZE, SIZE));
    }
    // Asked for again by index.
    let then = accepted(
        gcs.command(system, 102, REQUEST, params(&[263.0, 1.0])),
        "image 1",
    );
    match &then[..] {
        [MavMessage::CAMERA_IMAGE_CAPTURED(c), ..] => assert_eq!(c.image_index, 1),
        other => panic!("{other:?}"),
    }

    // Nothing but DigiView's stills is served from there.
    let url = images[0].file_url.to_str().unwrap();
    let captures_url = &url[..url.rfind('/').unwrap()];
    for other in [
        "..%2Fdigiview.toml",
        "digiview-..%2F..%2Fdigiview.toml",
        "notes.txt",
    ] {
        let (status, _) = http_get(&format!("{captures_url}/{other}"));
        assert_eq!(status, 404, "{other}");
    }
    // Video capture starts and stops the recording; CAMERA_CAPTURE_STATUS says which.
    let video_status = |then: Vec<MavMessage>| match &then[..] {
        [MavMessage::CAMERA_CAPTURE_STATUS(c), ..] => c.video_status,
        other => panic!("{other:?}"),
    };
    let start = MavCmd::MAV_CMD_VIDEO_START_CAPTURE;
    let stop = MavCmd::MAV_CMD_VIDEO_STOP_CAPTURE;
    assert_eq!(
        video_status(accepted(
            gcs.command(system, 102, start, params(&[])),
            "video"
        )),
        1
    );
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!(
        video_status(accepted(
            gcs.command(system, 102, stop, params(&[])),
            "stop"
        )),
        0
    );
    let ours = || -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&captures)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    // The view's own stream, at its size, was recorded.
    let videos: Vec<String> = ours().into_iter().filter(|n| n.ends_with(".mp4")).collect();
    assert_eq!(videos.len(), 1, "{videos:?}");
    assert!(videos[0].ends_with("-cam2.mp4"), "{videos:?}");
    let probe = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .args(["stream=width,height", "-of", "csv=p=0"])
        .arg(captures.join(&videos[0]))
        .output()
        .unwrap();
    let size = String::from_utf8_lossy(&probe.stdout).trim().to_string();
    assert_eq!(size, format!("{SIZE},{SIZE}"));

    // STORAGE_FORMAT: tests/it/trust_mavlink.rs (a signed link's only).
    drop(viewer);
}

/// The centroid of the red landmark's pixels in `img` (red far above green and blue, as
/// nothing else in the synthetic world is), when there are enough of them.
fn red(img: &RgbImage) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy) = (0usize, 0.0, 0.0);
    for (x, y, p) in img.enumerate_pixels() {
        let [r, g, b] = p.0.map(i32::from);
        if r > 150 && r - g > 90 && r - b > 90 {
            n += 1;
            sx += x as f64 + 0.5;
            sy += y as f64 + 0.5;
        }
    }
    (n >= 30).then(|| (sx / n as f64, sy / n as f64))
}

/// The yaw (degrees, world) of camera `component`'s next reported attitude.
fn gimbal_yaw(gcs: &Gcs, component: u8) -> f64 {
    gcs.forget();
    gcs.wait_for(Duration::from_secs(2), |h, m| match m {
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(a) if h.component_id == component => {
            let [w, x, y, z] = a.q.map(f64::from);
            let q = glam::DQuat::from_xyzw(x, y, z, w);
            Some(q.to_euler(glam::EulerRot::ZYX).0 / DEG)
        }
        _ => None,
    })
    .expect("the gimbal's attitude")
}

#[test]
fn roi_location_keeps_a_landmark_centred_while_the_vehicle_flies_past() {
    use digiview::geometry::ground::from_ned;
    use digiview::scene::GridWorld;
    use digiview::scene::synth::world_origin;
    const W: u32 = 640;
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        format!("[cameras]\nwidth = {W}\nheight = 480\npublic_host = \"127.0.0.1\"\n"),
    )
    .unwrap();
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    // The demo flies its circle and is the autopilot on the link: system 1.
    let serve = Serve::start_video(&["--config", config.to_str().unwrap(), "--mavlink", &link]);
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert!(seen.contains(&100));
    let t = Instant::now();
    while system_of_autopilot(&serve) != 1 {
        assert!(
            t.elapsed() < Duration::from_secs(10),
            "the demo's autopilot is not heard"
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    // The red landmark, on the ground: altitude 0 above home.
    let state = digiview::state::State::default();
    let red_ned = GridWorld::default()
        .landmarks
        .iter()
        .find(|l| l.name == "red")
        .unwrap()
        .position;
    let place = from_ned(
        world_origin(&state.vehicle.position),
        glam::DVec3::new(red_ned.x, red_ned.y, 0.0),
    );
    accepted(
        gcs.command(
            system,
            100,
            MavCmd::MAV_CMD_SET_CAMERA_ZOOM,
            params(&[4.0, 30.0]),
        ),
        "zoom",
    );
    gcs.send(&MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        target_system: system,
        target_component: 100,
        command: MavCmd::MAV_CMD_DO_SET_ROI_LOCATION,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        x: (place.lat * 1e7).round() as i32,
        y: (place.lon * 1e7).round() as i32,
        z: 0.0,
        ..Default::default()
    }));
    let acked = gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::COMMAND_ACK(a)
            if h.component_id == 100 && a.command == MavCmd::MAV_CMD_DO_SET_ROI_LOCATION =>
        {
            Some(a.result)
        }
        _ => None,
    });
    assert_eq!(acked, Some(MavResult::MAV_RESULT_ACCEPTED));

    let uri = format!("{}/cam0", serve.rtsp.clone().unwrap());
    let viewer = Viewer::open(&uri);
    let _ = viewer.frame_after(Duration::from_secs(1));
    let yaw_before = gimbal_yaw(&gcs, 100);
    let mut worst: f64 = 0.0;
    for _ in 0..12 {
        let img = viewer.frame_after(Duration::from_millis(500));
        let (x, y) = red(&img).expect("the red landmark in camera 0's view");
        let off = (x - W as f64 / 2.0).hypot(y - 240.0);
        worst = worst.max(off);
    }
    let turned = (gimbal_yaw(&gcs, 100) - yaw_before).abs();
    eprintln!(
        "ROI: the landmark at most {worst:.1} px ({:.2}% of the width) from the centre while \
         the view turned {turned:.1}° to follow it",
        100.0 * worst / W as f64
    );
    assert!(
        turned > 3.0,
        "the vehicle did not fly past: the view turned {turned:.1}°"
    );
    assert!(worst < 0.02 * W as f64, "{worst:.1} px off centre");

    // ROI_NONE: steered by its angles again, pointing where it pointed.
    let before = gimbal_yaw(&gcs, 100);
    let none = MavCmd::MAV_CMD_DO_SET_ROI_NONE;
    accepted(gcs.command(system, 100, none, params(&[])), "ROI none");
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    match ctl
        .get_one(Param::CamControlMode(
            digiview::protocol::params::CamControlMode {
                cam_id: 0,
                ..Default::default()
            },
        ))
        .unwrap()
    {
        Param::CamControlMode(c) => assert_eq!(c.mode, 1),
        other => panic!("{other:?}"),
    }
    let after = gimbal_yaw(&gcs, 100);
    assert!(
        (after - before).abs() < 2.0,
        "the view jumped from {before:.1}° to {after:.1}°"
    );
}

/// The autopilot's system id as `serve` knows it (AUTOPILOT over the control protocol).
fn system_of_autopilot(serve: &Serve) -> u8 {
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    match ctl
        .get_one(digiview::protocol::ParamType::Autopilot.zeroed())
        .unwrap()
    {
        Param::Autopilot(a) => a.system_id,
        other => panic!("{other:?}"),
    }
}
