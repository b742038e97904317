//! The demo's thermal camera as the thermal tests set it up: mounted to look at the demo car
//! whose engine bay is the hottest thing it sees (the movers standing, the vehicle hovering),
//! and `serve --thermal demo` so, with a pymavlink ground station (tests/peers/
//! thermal_station.py) on its MAVLink port.

use super::autopilot::free_udp_port;
use super::peers::LinePeer;
use super::serve::Serve;
use digiview::geometry::Euler;
use digiview::scene::GridWorld;
use digiview::scene::synth::eye;
use digiview::scene::thermal::world_from_thermal;
use digiview::state::State;
use digiview::state::view::{Camera, Field};
use glam::DVec3;
use serde_json::Value;

const DEG: f64 = std::f64::consts::PI / 180.0;

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
