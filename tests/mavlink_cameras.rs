//! The views as MAVLink cameras and gimbals, end to end: a ground station written with the
//! `mavlink` crate (tests/common/gcs.rs) against `digiview serve` on its autopilot link.
//! Cameras are discovered by their heartbeats and answer both REQUEST_MESSAGE and the older
//! commands; zoom and gimbal commands steer the views, as the control protocol reads them
//! back and as the picture shows; a view's own stream is the offline render of that view;
//! image capture writes the view's still and says so; hostile commands change nothing.

mod common;

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, text};
use common::serve::Serve;
use common::viewer::Viewer;
use digiview::control::client::Client;
use digiview::image_ops;
use digiview::layout::Rect;
use digiview::protocol::Param;
use digiview::protocol::params::{CamEuler, CamFov};
use image::RgbImage;
use mavlink::dialects::common::*;
use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const DEG: f64 = PI / 180.0;
const REQUEST: MavCmd = MavCmd::MAV_CMD_REQUEST_MESSAGE;

/// The system and component ids of the cameras heard within 5 s.
fn cameras(gcs: &Gcs) -> (u8, BTreeSet<u8>) {
    let mut seen = BTreeSet::new();
    let mut system = 0;
    gcs.wait_for(Duration::from_secs(5), |h, m| {
        if let MavMessage::HEARTBEAT(b) = m
            && b.mavtype == MavType::MAV_TYPE_CAMERA
        {
            seen.insert(h.component_id);
            system = h.system_id as u8;
        }
        (seen.len() == 4).then_some(())
    });
    (system, seen)
}

fn params(p: &[f32]) -> [f32; 7] {
    let mut all = [0.0; 7];
    all[..p.len()].copy_from_slice(p);
    all
}

/// CAM_EULER (yaw, pitch, roll) of camera `cam`, degrees.
fn euler(ctl: &mut Client, cam: u8) -> (f64, f64, f64) {
    match ctl
        .get_one(Param::CamEuler(CamEuler {
            cam_id: cam,
            ..Default::default()
        }))
        .unwrap()
    {
        Param::CamEuler(e) => (e.yaw / DEG, e.pitch / DEG, e.roll / DEG),
        other => panic!("{other:?}"),
    }
}

fn fov(ctl: &mut Client, cam: u8) -> f64 {
    match ctl
        .get_one(Param::CamFov(CamFov {
            cam_id: cam,
            ..Default::default()
        }))
        .unwrap()
    {
        Param::CamFov(f) => f.fov / DEG,
        other => panic!("{other:?}"),
    }
}

fn accepted(answer: Option<(MavResult, Vec<MavMessage>)>, what: &str) -> Vec<MavMessage> {
    let (result, then) = answer.unwrap_or_else(|| panic!("{what}: no COMMAND_ACK"));
    assert_eq!(result, MavResult::MAV_RESULT_ACCEPTED, "{what}");
    then
}

#[test]
fn four_cameras_are_discovered_both_ways_and_bad_commands_change_nothing() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    // On the demo (layout 4), whose simulated autopilot on the link is system 1.
    let serve = Serve::start_video(&["--mavlink", &link, "--demo-size", "640x480"]);
    let gcs = Gcs::connect(port);
    let (system, seen) = cameras(&gcs);
    assert_eq!(seen, (100..=103).collect(), "layout 4's cameras");

    for c in 100..=103u8 {
        for (how, cmd, p) in [
            ("REQUEST_MESSAGE", REQUEST, params(&[259.0])),
            (
                "REQUEST_CAMERA_INFORMATION",
                #[allow(deprecated)]
                MavCmd::MAV_CMD_REQUEST_CAMERA_INFORMATION,
                params(&[1.0]),
            ),
        ] {
            let then = accepted(gcs.command(system, c, cmd, p), how);
            let info = then
                .iter()
                .find_map(|m| match m {
                    MavMessage::CAMERA_INFORMATION(i) => Some(i.clone()),
                    _ => None,
                })
                .unwrap_or_else(|| panic!("camera {c} by {how}: no CAMERA_INFORMATION"));
            assert_eq!(text(&info.vendor_name), "DigiView");
            assert_eq!(
                text(&info.model_name),
                format!("virtual camera {}", c - 100)
            );
            assert_eq!((info.resolution_h, info.resolution_v), (1280, 720));
            // The default 90° view: an 18 mm lens on a 36 mm wide frame.
            assert!(
                (info.focal_length - 18.0).abs() < 0.01,
                "{}",
                info.focal_length
            );
            assert_eq!(info.sensor_size_h, 36.0);
            use CameraCapFlags as F;
            for f in [
                F::CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM,
                F::CAMERA_CAP_FLAGS_HAS_BASIC_ZOOM,
                F::CAMERA_CAP_FLAGS_CAPTURE_IMAGE,
                F::CAMERA_CAP_FLAGS_CAPTURE_VIDEO,
            ] {
                assert!(info.flags.contains(f), "{f:?}");
            }
            assert_eq!(info.gimbal_device_id, 1);
        }
    }

    // The rest of what a ground station asks a camera, the new way.
    let one = |id: f32, p2: f32| {
        accepted(
            gcs.command(system, 101, REQUEST, params(&[id, p2])),
            "request",
        )
    };
    match &one(260.0, 0.0)[..] {
        [MavMessage::CAMERA_SETTINGS(s), ..] => {
            assert!((0.0..=100.0).contains(&s.zoomLevel), "{}", s.zoomLevel)
        }
        other => panic!("{other:?}"),
    }
    let streams = one(269.0, 0.0);
    let ids: Vec<u8> = streams
        .iter()
        .filter_map(|m| match m {
            MavMessage::VIDEO_STREAM_INFORMATION(v) => {
                assert_eq!(v.count, 2);
                Some(v.stream_id)
            }
            _ => None,
        })
        .collect();
    assert_eq!(ids, [1, 2], "the view's own stream and the composed frame");
    assert!(matches!(
        one(261.0, 0.0)[..],
        [MavMessage::STORAGE_INFORMATION(_), ..]
    ));
    assert!(matches!(
        one(262.0, 0.0)[..],
        [MavMessage::CAMERA_CAPTURE_STATUS(_), ..]
    ));
    match &one(280.0, 0.0)[..] {
        [MavMessage::GIMBAL_MANAGER_INFORMATION(g), ..] => {
            assert_eq!(g.gimbal_device_id, 1);
            assert!(g.pitch_min < -1.5 && g.pitch_max > 1.5);
        }
        other => panic!("{other:?}"),
    }

    // Zoom by range (100 %: the narrowest fov, 0.1 rad) and by steps (-4: twice as wide).
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    let zoom = MavCmd::MAV_CMD_SET_CAMERA_ZOOM;
    accepted(
        gcs.command(system, 100, zoom, params(&[2.0, 100.0])),
        "zoom range",
    );
    assert!(
        (fov(&mut ctl, 0) - 0.1 / DEG).abs() < 0.05,
        "{}",
        fov(&mut ctl, 0)
    );
    accepted(
        gcs.command(system, 100, zoom, params(&[0.0, -4.0])),
        "zoom steps",
    );
    assert!(
        (fov(&mut ctl, 0) - 0.2 / DEG).abs() < 0.05,
        "{}",
        fov(&mut ctl, 0)
    );

    // A gimbal with a primary controller takes pointing commands from it alone.
    let configure = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE;
    let pitch_yaw = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW;
    // Every axis held in the world (ROLL_LOCK | PITCH_LOCK | YAW_LOCK): the demo flies.
    let aim = params(&[-10.0, 20.0, f32::NAN, f32::NAN, 28.0]);
    accepted(
        gcs.command(system, 100, configure, params(&[42.0, 1.0, -1.0, -1.0])),
        "configure",
    );
    let taken = gcs.command(system, 100, pitch_yaw, aim).map(|a| a.0);
    assert_eq!(
        taken,
        Some(MavResult::MAV_RESULT_DENIED),
        "42/1 is in control"
    );
    accepted(
        gcs.command(system, 100, configure, params(&[-3.0, 0.0, -1.0, -1.0])),
        "release",
    );
    accepted(gcs.command(system, 100, pitch_yaw, aim), "after release");
    let (yaw, pitch, _) = euler(&mut ctl, 0);
    assert!(
        (yaw - 20.0).abs() < 0.05 && (pitch + 10.0).abs() < 0.05,
        "{yaw} {pitch}"
    );

    // Hostile and foreign commands: answered DENIED or UNSUPPORTED, or not at all, and the
    // views stay as they were.
    let before = (euler(&mut ctl, 1), fov(&mut ctl, 1));
    let result = |a: Option<(MavResult, Vec<MavMessage>)>| a.map(|a| a.0);
    let cmd = |cmd, p: &[f32]| result(gcs.command(system, 101, cmd, params(p)));
    use MavCmd::*;
    let denied = MavResult::MAV_RESULT_DENIED;
    for (command, p, want, what) in [
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[4.0, f32::NAN][..],
            denied,
            "a NaN fov",
        ),
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[4.0, -20.0],
            denied,
            "a negative fov",
        ),
        (
            MAV_CMD_SET_CAMERA_ZOOM,
            &[9.0, 1.0],
            denied,
            "no such zoom type",
        ),
        (
            MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            &[f32::INFINITY, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            denied,
            "an infinite pitch",
        ),
        (
            MAV_CMD_DO_SET_ROI_LOCATION,
            &[0.0, 0.0, 0.0, 0.0, 123.0, 8.0, 100.0],
            denied,
            "latitude 123°",
        ),
        (
            MAV_CMD_DO_SET_SERVO,
            &[1.0, 1500.0],
            MavResult::MAV_RESULT_UNSUPPORTED,
            "not a camera's command",
        ),
    ] {
        assert_eq!(cmd(command, p), Some(want), "{what}");
    }
    let other_system = system.wrapping_add(1);
    let zoom_in = params(&[4.0, 30.0]);
    assert!(
        gcs.command(other_system, 101, MAV_CMD_SET_CAMERA_ZOOM, zoom_in)
            .is_none(),
        "a command for another system is not answered"
    );
    assert!(
        gcs.command(system, 105, MAV_CMD_SET_CAMERA_ZOOM, zoom_in)
            .is_none(),
        "nor one for a camera the layout does not show"
    );
    // A flood of commands to every camera with values that are no numbers or far out of any
    // range, and of gimbal messages with random bits to camera 3: camera 1 stays as it was
    // and nothing stops answering.
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    for _ in 0..2000 {
        let hostile = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e30,
            -1e30,
            f32::MAX,
        ];
        let p: [f32; 7] = std::array::from_fn(|_| hostile[next() as usize % hostile.len()]);
        let bits: [f32; 7] = std::array::from_fn(|_| f32::from_bits(next() as u32));
        let pick = next();
        let msg = match pick % 3 {
            0 => MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                target_system: system,
                target_component: 100 + (pick >> 8) as u8 % 6,
                command: [
                    MAV_CMD_SET_CAMERA_ZOOM,
                    MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
                    MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
                    MAV_CMD_DO_SET_ROI_LOCATION,
                    MAV_CMD_REQUEST_MESSAGE,
                    MAV_CMD_STORAGE_FORMAT,
                ][(pick >> 16) as usize % 6],
                param1: p[0],
                param2: p[1],
                param3: p[2],
                param4: p[3],
                param5: p[4],
                param6: p[5],
                param7: p[6],
                confirmation: 0,
            }),
            1 => MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(GIMBAL_MANAGER_SET_PITCHYAW_DATA {
                flags: GimbalManagerFlags::from_bits_truncate(next() as u32),
                pitch: bits[0],
                yaw: bits[1],
                pitch_rate: bits[2],
                yaw_rate: bits[3],
                target_system: system,
                target_component: 103,
                gimbal_device_id: (pick >> 8) as u8 % 3,
            }),
            _ => MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(GIMBAL_MANAGER_SET_ATTITUDE_DATA {
                flags: GimbalManagerFlags::from_bits_truncate(next() as u32),
                q: [bits[0], bits[1], bits[2], bits[3]],
                angular_velocity_x: bits[4],
                angular_velocity_y: bits[5],
                angular_velocity_z: bits[6],
                target_system: system,
                target_component: 103,
                gimbal_device_id: 0,
            }),
        };
        gcs.send(&msg);
    }
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(
        (euler(&mut ctl, 1), fov(&mut ctl, 1)),
        before,
        "camera 1 changed"
    );
    // Still alive and answering.
    accepted(
        gcs.command(system, 100, REQUEST, params(&[259.0])),
        "after the flood",
    );
    let e = euler(&mut ctl, 3);
    assert!(
        e.0.is_finite() && e.1.abs() <= 90.05 && e.2.abs() <= 90.05,
        "{e:?}"
    );
}

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
    let then = accepted(
        gcs.command(
            system,
            102,
            MavCmd::MAV_CMD_IMAGE_START_CAPTURE,
            params(&[0.0, 0.5, 2.0]),
        ),
        "image capture",
    );
    let mut images: Vec<_> = then
        .into_iter()
        .filter_map(|m| match m {
            MavMessage::CAMERA_IMAGE_CAPTURED(c) => Some(c),
            _ => None,
        })
        .collect();
    gcs.wait_for(Duration::from_secs(10), |h, m| {
        if let MavMessage::CAMERA_IMAGE_CAPTURED(c) = m
            && h.component_id == 102
        {
            images.push(c.clone());
        }
        (images.len() == 2).then_some(())
    });
    assert_eq!(images.len(), 2, "two CAMERA_IMAGE_CAPTURED");
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

    // STORAGE_FORMAT removes DigiView's captures and nothing else.
    std::fs::write(captures.join("notes.txt"), "the pilot's").unwrap();
    let format = MavCmd::MAV_CMD_STORAGE_FORMAT;
    let then = accepted(
        gcs.command(system, 102, format, params(&[1.0, 1.0, 1.0])),
        "format",
    );
    assert!(matches!(then[..], [MavMessage::STORAGE_INFORMATION(_), ..]));
    assert_eq!(ours(), ["notes.txt"]);
    let gone = gcs
        .command(system, 102, REQUEST, params(&[263.0, 0.0]))
        .map(|a| a.0);
    assert_eq!(
        gone,
        Some(MavResult::MAV_RESULT_DENIED),
        "image indices start again"
    );
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

/// An HTTP GET of `url` (`http://HOST:PORT/PATH`) with std alone: the status and the body.
fn http_get(url: &str) -> (u16, Vec<u8>) {
    use std::io::{Read, Write};
    let rest = url.strip_prefix("http://").unwrap();
    let (host, path) = rest.split_at(rest.find('/').unwrap());
    let mut s = std::net::TcpStream::connect(host).unwrap_or_else(|e| panic!("{url}: {e}"));
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = vec![];
    s.read_to_end(&mut reply).unwrap();
    let status = String::from_utf8_lossy(&reply[9..12]).parse().unwrap();
    let head = reply.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    (status, reply[head + 4..].to_vec())
}

/// CAMERA_INFORMATION's definition URI and version, and the file there.
fn definition(gcs: &Gcs, system: u8) -> (String, u16, String) {
    let then = accepted(gcs.command(system, 100, REQUEST, params(&[259.0])), "info");
    let info = match &then[..] {
        [MavMessage::CAMERA_INFORMATION(i), ..] => i.clone(),
        other => panic!("{other:?}"),
    };
    let uri = info.cam_definition_uri.to_str().unwrap().to_string();
    let (status, xml) = http_get(&uri);
    assert_eq!(status, 200, "{uri}");
    (
        uri,
        info.cam_definition_version,
        String::from_utf8(xml).unwrap(),
    )
}

fn ext_value(m: &MavMessage) -> Option<(String, u8, u16)> {
    match m {
        MavMessage::PARAM_EXT_VALUE(v) => Some((
            v.param_id.to_str().unwrap().to_string(),
            v.param_value[0],
            v.param_count,
        )),
        _ => None,
    }
}

fn ext_set(gcs: &Gcs, system: u8, name: &str, v: u8) -> ParamAck {
    let mut value = [0u8; 128];
    value[0] = v;
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_SET(PARAM_EXT_SET_DATA {
        target_system: system,
        target_component: 101,
        param_id: name.into(),
        param_value: value.into(),
        param_type: MavParamExtType::MAV_PARAM_EXT_TYPE_UINT8,
    }));
    gcs.wait_for(Duration::from_secs(3), |h, m| match m {
        MavMessage::PARAM_EXT_ACK(a) if h.component_id == 101 => Some(a.param_result),
        _ => None,
    })
    .expect("PARAM_EXT_ACK")
}

#[test]
fn settings_are_parameters_described_by_a_definition_file_served_over_http() {
    let port = free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let serve = Serve::start(&["--mavlink", &link]);
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);

    // The file: the protocol's XML, its version the one CAMERA_INFORMATION gives, a
    // parameter for each setting, the lenses of lens.cal as LENS's options.
    let (uri, version, xml) = definition(&gcs, system);
    assert!(
        uri.starts_with("http://127.0.0.1:") && uri.ends_with("/camera.xml"),
        "{uri}"
    );
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "mavlinkcamera");
    let def = root
        .children()
        .find(|n| n.has_tag_name("definition"))
        .unwrap();
    assert_eq!(def.attribute("version"), Some(version.to_string().as_str()));
    assert_ne!(version, 0);
    let names: Vec<&str> = root
        .descendants()
        .filter(|n| n.has_tag_name("parameter"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    let want = [
        "LAYOUT",
        "OVERLAY",
        "LENS",
        "CROP",
        "LOCK",
        "CONTROL",
        "SORTING",
        "DETECTION",
    ];
    assert_eq!(names, want);
    let lens = root
        .descendants()
        .find(|n| n.attribute("name") == Some("LENS"))
        .unwrap();
    let lenses: Vec<&str> = lens
        .descendants()
        .filter(|n| n.has_tag_name("option"))
        .map(|n| n.attribute("name").unwrap())
        .collect();
    assert_eq!(lenses, ["CIL216", "CIL018", "LN007"]);

    // Every parameter listed with its value from the live state.
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_REQUEST_LIST(
        PARAM_EXT_REQUEST_LIST_DATA {
            target_system: system,
            target_component: 101,
        },
    ));
    let mut listed = vec![];
    gcs.wait_for(Duration::from_secs(3), |h, m| {
        if h.component_id == 101
            && let Some(v) = ext_value(m)
        {
            assert_eq!(v.2 as usize, want.len());
            listed.push((v.0, v.1));
        }
        (listed.len() == want.len()).then_some(())
    });
    let names: Vec<&str> = listed.iter().map(|l| l.0.as_str()).collect();
    assert_eq!(names, want);
    assert_eq!(listed[0].1, 4, "layout 4");
    assert_eq!(listed[4].1, 7, "camera 1 locks every axis");

    // A SET here is a SET there, and the other way round.
    let mut ctl = Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();
    assert_eq!(
        ext_set(&gcs, system, "LOCK", 3),
        ParamAck::PARAM_ACK_ACCEPTED
    );
    assert_eq!(listed_lock(&mut ctl), 3);
    ctl.set(Param::CamCropMode(
        digiview::protocol::params::CamCropMode { cam_id: 1, mode: 2 },
    ))
    .unwrap();
    gcs.forget();
    gcs.send(&MavMessage::PARAM_EXT_REQUEST_READ(
        PARAM_EXT_REQUEST_READ_DATA {
            target_system: system,
            target_component: 101,
            param_id: "CROP".into(),
            param_index: -1,
        },
    ));
    let crop = gcs.wait_for(Duration::from_secs(3), |h, m| {
        (h.component_id == 101).then(|| ext_value(m)).flatten()
    });
    assert_eq!(crop.map(|c| (c.0, c.1)), Some(("CROP".to_string(), 2)));

    // What is not an option, and what the state cannot take, changes nothing.
    let unsupported = ParamAck::PARAM_ACK_VALUE_UNSUPPORTED;
    assert_eq!(ext_set(&gcs, system, "LOCK", 9), unsupported);
    assert_eq!(
        ext_set(&gcs, system, "CONTROL", 2),
        unsupported,
        "no target yet"
    );
    assert_eq!(
        ext_set(&gcs, system, "NOSUCH", 1),
        ParamAck::PARAM_ACK_FAILED
    );
    assert_eq!(listed_lock(&mut ctl), 3);

    // LAYOUT 2 has two views: cameras 102 and 103 go quiet.
    assert_eq!(
        ext_set(&gcs, system, "LAYOUT", 2),
        ParamAck::PARAM_ACK_ACCEPTED
    );
    std::thread::sleep(Duration::from_millis(200));
    let beats: BTreeSet<u8> = gcs
        .collect(Duration::from_millis(2500))
        .iter()
        .filter(
            |(_, m)| matches!(m, MavMessage::HEARTBEAT(b) if b.mavtype == MavType::MAV_TYPE_CAMERA),
        )
        .map(|(h, _)| h.component_id)
        .collect();
    assert_eq!(beats, [100, 101].into());

    // Another lens.cal, another file: another version.
    let dir = tempfile::tempdir().unwrap();
    let cal = dir.path().join("lens.cal");
    let shipped = std::fs::read_to_string(common::lens_cal_path()).unwrap();
    let start = shipped.find("\n[[lens]]").unwrap() + 1;
    let end = start + shipped[start..].find("\n[[lens]]").unwrap();
    let first = &shipped[start..end];
    let extra = first
        .replace("name = \"CIL216\"", "name = \"SPARE\"")
        .replace("lens_id = 0", "lens_id = 7");
    std::fs::write(&cal, format!("{shipped}\n{extra}\n")).unwrap();
    let port2 = free_udp_port();
    let link2 = format!("udpin:127.0.0.1:{port2}");
    let _serve2 = Serve::start(&["--mavlink", &link2, "--lens-cal", cal.to_str().unwrap()]);
    let gcs2 = Gcs::connect(port2);
    let (system2, _) = cameras(&gcs2);
    let (_, version2, xml2) = definition(&gcs2, system2);
    assert!(xml2.contains("name=\"SPARE\" value=\"7\""), "{xml2}");
    assert_ne!(version2, version, "the version follows the content");
}

fn listed_lock(ctl: &mut Client) -> u8 {
    match ctl
        .get_one(Param::CamLockFlags(
            digiview::protocol::params::CamLockFlags {
                cam_id: 1,
                ..Default::default()
            },
        ))
        .unwrap()
    {
        Param::CamLockFlags(l) => l.flags,
        other => panic!("{other:?}"),
    }
}
