//! The demo world as a thermal sensor sees it: a cold sky (colder towards the zenith), ground
//! at about 291 K whose large-scale tone is a degree or two of sun and shade, the grid's lines
//! (paths) a little warmer, the landmarks warmer the darker they are (they take more sun), and
//! the movers warm bodies of known temperatures. [`thermal_frame`] draws what a thermal camera
//! mounted beside the fisheye captures of it, in counts: the truth the thermal tests compare
//! with.

use super::grid::{EDGE, GridWorld, line, skyward, tone};
use super::smoothstep;
use super::synth::eye;
use crate::geometry::Euler;
use crate::geometry::rotation::MOUNT_FROM_LENS;
use crate::geometry::view::lens_from_world;
use crate::image_ops::sample_offsets;
use crate::lens::Lens;
use crate::state::State;
use crate::thermal::{Calibration, ThermalFrame};
use glam::{DMat3, DVec2, DVec3};
use rayon::prelude::*;

/// The movers' temperatures, in the order of `GridWorld::movers` (a person, a dog, a car's
/// engine bay), kelvin; a mover past the list is a person.
pub const MOVER_KELVIN: [f64; 3] = [309.65, 311.85, 338.15];
const SKY_ZENITH: f64 = 235.0;
const SKY_HORIZON: f64 = 272.0;
const GROUND: f64 = 291.0;
const PATH: f64 = 294.5;

impl GridWorld {
    /// The temperature seen from `eye` along unit `ray` at `t`, kelvin.
    pub fn kelvin(&self, eye: DVec3, ray: DVec3, t: f64) -> f64 {
        if !(ray.z > 1e-9 && eye.z < 0.0) {
            return SKY_HORIZON + (SKY_ZENITH - SKY_HORIZON) * skyward(ray);
        }
        let hit = eye + ray * (-eye.z / ray.z);
        let p = DVec2::new(hit.x, hit.y);
        let mut k = GROUND + 1.5 * tone(p);
        let path = line(p.x, 10.0, 0.25, 0.0).max(line(p.y, 10.0, 0.25, 0.0));
        k += (PATH - k) * path;
        let disc = |k: f64, centre: DVec2, radius: f64, warm: f64| {
            let d = (p - centre).length();
            k + (warm - k) * smoothstep(radius + EDGE, radius - EDGE, d)
        };
        for l in &self.landmarks {
            let luma = l.colour.dot(DVec3::new(0.299, 0.587, 0.114)) / 255.0;
            k = disc(k, l.position, l.radius, 286.0 + 16.0 * (1.0 - luma));
        }
        for (i, m) in self.movers.iter().enumerate() {
            let warm = MOVER_KELVIN.get(i).copied().unwrap_or(MOVER_KELVIN[0]);
            k = disc(k, m.position(t), m.radius, warm);
        }
        k
    }
}

/// What a thermal camera with `lens`, mounted at `mount` relative to the fisheye's mount
/// (zero: looking where the fisheye looks), captures of `world` at the state's attitude,
/// position and time: each pixel the mean of `samples` × `samples` rays over its area, in counts under
/// `cal`. Pixels the lens does not see are the sky's horizon temperature.
pub fn thermal_frame(
    world: &GridWorld,
    lens: &Lens,
    mount: Euler,
    state: &State,
    cal: &Calibration,
    samples: u32,
) -> ThermalFrame {
    let world_from_thermal = world_from_thermal(state, mount);
    let (eye, t) = (eye(state), state.time);
    let offsets: Vec<DVec2> = sample_offsets(samples).collect();
    let (w, h) = (lens.width, lens.height);
    let mut counts = vec![0u16; (w * h) as usize];
    counts
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, c) in row.iter_mut().enumerate() {
                let corner = DVec2::new(x as f64, y as f64) - DVec2::splat(0.5);
                let sum: f64 = offsets
                    .iter()
                    .map(|o| match lens.unproject(corner + *o) {
                        Some(ray) => world.kelvin(eye, world_from_thermal * ray, t),
                        None => SKY_HORIZON,
                    })
                    .sum();
                *c = cal.counts(sum / offsets.len() as f64);
            }
        });
    ThermalFrame::new(w, h, counts).expect("a frame of the lens's size")
}

/// World (NED) rays from the thermal camera's lens frame.
pub fn world_from_thermal(state: &State, mount: Euler) -> DMat3 {
    let fisheye = state.settings.mount.euler();
    let vehicle = state.vehicle.attitude.euler();
    lens_from_world(vehicle, fisheye).transpose() * thermal_in_lens(mount)
}

/// The thermal lens frame in the fisheye's lens frame: the mount's rotation (about the mount
/// frame's axes, as the fisheye's own mount is given), carried into the lens frame.
pub fn thermal_in_lens(mount: Euler) -> DMat3 {
    MOUNT_FROM_LENS.transpose() * mount.matrix() * MOUNT_FROM_LENS
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::GeoPosition;
    use crate::geometry::ground::from_ned;
    use crate::lens::PixelAffine;
    use crate::lens::models::{Model, Pinhole};
    use crate::scene::synth::world_origin;

    /// A Boson 640 with its 8.7 mm lens (50° across), a little barrel distortion.
    fn boson() -> Lens {
        let model = Model::Pinhole(Pinhole {
            k: [-0.08, 0.01, 0.0],
        });
        let affine = PixelAffine::pinhole(725.0, 725.0, 319.5, 255.5);
        Lens::new("BOSON", 9, model, affine, (640, 512), 70f64.to_radians())
    }

    #[test]
    fn the_engine_is_the_hottest_point_where_the_thermal_camera_sees_it() {
        let world = GridWorld::default();
        let mut state = State {
            time: 10.0,
            ..State::default()
        };
        // Hover 50 m up, 6 m north and 4 m west of the engine, nose east, the thermal camera
        // turned 5° in yaw from the fisheye.
        let engine = world.movers[2].position(state.time);
        let origin = world_origin(&state.vehicle.position);
        let above = from_ned(origin, DVec3::new(engine.x + 6.0, engine.y - 4.0, -50.0));
        state.vehicle.position = GeoPosition {
            lat: above.lat,
            lon: above.lon,
            alt: above.alt,
            relative_alt: 50.0,
        };
        state.vehicle.attitude.yaw = 90f64.to_radians();
        let mount = Euler {
            yaw: 5f64.to_radians(),
            pitch: 0.0,
            roll: 0.0,
        };
        let cal = Calibration::default();
        let lens = boson();
        let frame = thermal_frame(&world, &lens, mount, &state, &cal, 3);
        // Where the engine's centre lands (pixel centres at +0.5 in the frame's spots).
        let ray = (DVec3::new(engine.x, engine.y, 0.0) - eye(&state)).normalize();
        let at = lens
            .project(world_from_thermal(&state, mount).transpose() * ray)
            .expect("the engine is in sight")
            + DVec2::splat(0.5);
        assert!(
            at.x > 50.0 && at.x < 590.0 && at.y > 50.0 && at.y < 462.0,
            "{at}"
        );
        let hottest = frame.extremes(&cal).hottest;
        assert!(
            (hottest.kelvin - MOVER_KELVIN[2]).abs() <= 0.2,
            "{hottest:?}"
        );
        let off = (hottest.x - at.x).hypot(hottest.y - at.y);
        assert!(off <= 1.0, "{off:.2} px from {at}: {hottest:?}");
        // Turned the other way, the same engine lands elsewhere: the mount counts.
        let other = Euler {
            yaw: -5f64.to_radians(),
            ..mount
        };
        let moved = thermal_frame(&world, &lens, other, &state, &cal, 3)
            .extremes(&cal)
            .hottest;
        assert!(
            (moved.x - hottest.x).hypot(moved.y - hottest.y) > 50.0,
            "{moved:?}"
        );
    }
}
