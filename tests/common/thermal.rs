//! The demo's thermal camera as the thermal tests set it up: mounted to look at the demo car
//! whose engine bay is the hottest thing it sees (the movers standing, the vehicle hovering),
//! and `serve --thermal demo` so, with a pymavlink ground station (tests/peers/
//! thermal_station.py) on its MAVLink port.

use super::autopilot::free_udp_port;
use super::peers::LinePeer;
use super::serve::Serve;
use digiview::geometry::Euler;
use digiview::lens::Lenses;
use digiview::modes::ThermalShow;
use digiview::plan::FramePlan;
use digiview::plan::thermal::ThermalLayer;
use digiview::scene::GridWorld;
use digiview::scene::synth::eye;
use digiview::scene::thermal::{thermal_frame, thermal_in_lens, world_from_thermal};
use digiview::state::view::{Camera, Field};
use digiview::state::{State, ThermalLook};
use digiview::thermal::{Calibration, GainTable};
use glam::DVec3;
use image::RgbImage;
use serde_json::Value;
use std::io::Read;
use std::process::Stdio;
use std::sync::Arc;

const DEG: f64 = std::f64::consts::PI / 180.0;
/// The views' own streams' size.
pub const SIZE: (u32, u32) = (1280, 720);

/// The world ray from the hovering vehicle to the engine bay's centre (the movers stand).
pub fn engine_ray(state: &State) -> DVec3 {
    let engine = GridWorld::demo(false).movers[2].position(0.0);
    (DVec3::new(engine.x, engine.y, 0.0) - eye(state)).normalize()
}

/// The thermal mount (whole degrees) that points the thermal camera's axis nearest `ray`.
pub fn mount_towards(state: &State, ray: DVec3) -> Euler {
    let mut best = (f64::MAX, Euler::default());
    for yaw in -180..180 {
        for pitch in -90..=90 {
            let mount = Euler::new(yaw as f64 * DEG, pitch as f64 * DEG, 0.0);
            let off = (world_from_thermal(state, mount) * DVec3::Z).angle_between(ray);
            if off < best.0 {
                best = (off, mount);
            }
        }
    }
    best.1
}

/// View 0 as the head holds it: world-locked at `yaw`, `pitch`, 90° across.
pub fn aimed(state: &State, yaw: f64, pitch: f64) -> State {
    let mut s = state.clone();
    let fields = [
        (Field::Yaw, yaw),
        (Field::Pitch, pitch),
        (Field::Fov, 90.0 * DEG),
    ];
    s.settings.cameras[0] = Camera::numbered(0).with(&fields).unwrap();
    s
}

/// `serve --thermal demo` with the thermal camera at `mount` (whole degrees), the movers
/// standing, the vehicle hovering, view 0 world-locked at `(yaw, pitch)` 90° across, and the
/// pymavlink station on its MAVLink port: the head, the station and the station's first line.
pub fn engine_serve(mount: Euler, (yaw, pitch): (f64, f64)) -> (Serve, LinePeer, Value) {
    let config = tempfile::NamedTempFile::new().unwrap();
    let m = |v: f64| v.to_degrees().round();
    let text = format!(
        "[demo]\nmovers = false\n[thermal]\nsource = \"demo\"\n\
         mount = {{ yaw = \"{}deg\", pitch = \"{}deg\" }}\n",
        m(mount.yaw),
        m(mount.pitch)
    );
    std::fs::write(config.path(), text).unwrap();
    let cam = format!("0:yaw={yaw},pitch={pitch},fov=90deg,lock=7");
    let link = free_udp_port();
    let serve = Serve::start_video(&[
        "--config",
        config.path().to_str().unwrap(),
        "--demo-hover",
        "--cam",
        &cam,
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
    ]);
    let (station, ready) = LinePeer::start("thermal_station.py", &[&link.to_string()]);
    assert_eq!(ready["ready"], true, "the station heard camera 100");
    (serve, station, ready)
}

/// The layer over `plan`'s view 0 `show`'s way as the CPU reference draws it from the thermal
/// frame the head's demo draws (the same world, lens, mount and state), coloured as `look`
/// says.
pub fn reference_layer(
    plan: &FramePlan,
    state: &State,
    show: ThermalShow,
    mount: Euler,
    look: &ThermalLook,
) -> ThermalLayer {
    let lens = Lenses::new(&super::lens_cal())
        .named("BOSON320")
        .unwrap()
        .clone();
    let cal = Calibration::default();
    let frame = thermal_frame(&GridWorld::demo(false), &lens, mount, state, &cal, 2);
    let gain = GainTable::new(&frame, look.gain_mode(), &cal).unwrap();
    let mut layer = ThermalLayer::new(Arc::new(frame), Arc::new(gain), look.palette, lens);
    (layer.blend, layer.zoom) = (look.blend, look.zoom as f64);
    layer.add(plan, &plan.views[0], show, thermal_in_lens(mount));
    layer
}

/// The last of 8 frames FFmpeg decodes from `url` (RTSP over TCP), as RGB.
pub fn decoded(url: &str) -> RgbImage {
    let mut child = super::ffmpeg_from(url, "tcp")
        .args(["-frames:v", "8", "-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("ffmpeg runs (scripts/setup.sh installs it)");
    let mut bytes = Vec::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_end(&mut bytes)
        .unwrap();
    assert!(
        child.wait().unwrap().success(),
        "ffmpeg could not decode {url}"
    );
    let frame = (SIZE.0 * SIZE.1 * 3) as usize;
    assert!(bytes.len() >= frame, "no frame from {url}");
    let last = bytes[bytes.len() - frame..].to_vec();
    RgbImage::from_raw(SIZE.0, SIZE.1, last).unwrap()
}

pub fn luma(img: &RgbImage, x: u32, y: u32) -> f64 {
    let p = img.get_pixel(x, y).0;
    0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64
}
