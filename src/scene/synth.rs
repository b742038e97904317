//! Rendering straight from a world: the anti-aliased fisheye frame a lens would capture, the
//! exact output frame for a DigiView state (ground truth), and equirectangular panoramas.

use super::World;
use crate::geometry::ground::to_ned;
use crate::geometry::shutter::Readout;
use crate::geometry::view::lens_from_world;
use crate::geometry::{Euler, GeoPoint, GeoPosition};
use crate::image_ops::{sample_offsets, to_rgb8};
use crate::lens::Lens;
use crate::plan::FramePlan;
use crate::plan::paint::render_with;
use crate::state::State;
use glam::{DVec2, DVec3};
use image::RgbImage;
use rayon::prelude::*;

/// Supersampling per axis for synthesised frames.
pub const SYNTH_SAMPLES: u32 = 3;
/// The least supersampling the ground truth uses per axis, whatever the view's footprint.
pub const TRUTH_SAMPLES: u32 = 4;

/// The synthetic world's origin: the home under the default vehicle position, on the ground.
pub fn world_origin(position: &GeoPosition) -> GeoPoint {
    GeoPoint {
        lat: crate::state::DEFAULT_POSITION.lat,
        lon: crate::state::DEFAULT_POSITION.lon,
        alt: position.home_alt(),
    }
}

/// The eye (vehicle) position in the world's NED frame.
pub fn eye(state: &State) -> DVec3 {
    eye_at(&state.vehicle.position)
}

/// The eye at vehicle position `p` in the world's NED frame.
pub fn eye_at(p: &GeoPosition) -> DVec3 {
    to_ned(world_origin(p), p.point())
}

/// Renders `f(x, y)` for every pixel of a w × h image, n × n samples a pixel, rows in parallel.
pub(crate) fn supersample<F: Fn(DVec2) -> Option<DVec3> + Sync>(
    w: u32,
    h: u32,
    n: u32,
    f: F,
) -> RgbImage {
    let offsets: Vec<DVec2> = sample_offsets(n).collect();
    let mut buf = vec![0u8; (w * h * 3) as usize];
    buf.par_chunks_mut((w * 3) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let base = DVec2::new(x as f64, y as f64);
                let sum: DVec3 = offsets.iter().filter_map(|o| f(base + *o)).sum();
                row[(x * 3) as usize..(x * 3 + 3) as usize]
                    .copy_from_slice(&to_rgb8(sum / offsets.len() as f64));
            }
        });
    RgbImage::from_raw(w, h, buf).expect("sized buffer")
}

/// The fisheye frame `lens` captures of `world` at the state's attitude, position, mount and
/// time: black outside the image circle, each pixel the mean of 3 × 3 rays over its area.
pub fn fisheye(world: &dyn World, lens: &Lens, state: &State) -> RgbImage {
    let world_from_lens =
        lens_from_world(state.vehicle.attitude.euler(), state.settings.mount.euler()).transpose();
    let (eye, t) = (eye(state), state.time);
    // Sample points measured from the top-left corner; OpenCV pixel coordinates are 0.5 less.
    supersample(lens.width, lens.height, SYNTH_SAMPLES, |p| {
        let ray = lens.unproject(p - DVec2::splat(0.5))?;
        Some(world.colour(eye, world_from_lens * ray, t))
    })
}

/// The fisheye frame a rolling-shutter camera reading out as `readout` captures: as
/// [`fisheye`], but each sample is seen with the vehicle's attitude when its row was read,
/// `attitude(dt_us)` at `dt_us` microseconds after the frame's middle row (the state's own
/// attitude is not used; its position, mount and time are).
pub fn rolling_fisheye(
    world: &dyn World,
    lens: &Lens,
    state: &State,
    readout: &Readout,
    attitude: impl Fn(f64) -> Euler + Sync,
) -> RgbImage {
    let mount = state.settings.mount.euler();
    let (eye, t) = (eye(state), state.time);
    let size = (lens.width, lens.height);
    supersample(lens.width, lens.height, SYNTH_SAMPLES, |p| {
        let q = p - DVec2::splat(0.5);
        let ray = lens.unproject(q)?;
        let world_from_lens =
            lens_from_world(attitude(readout.point_us(q, size)), mount).transpose();
        Some(world.colour(eye, world_from_lens * ray, t))
    })
}

/// The output frame DigiView should render for `plan`, computed from the world directly
/// (no fisheye in between), with the same black mask as the renderers.
pub fn truth(world: &dyn World, plan: &FramePlan, state: &State) -> RgbImage {
    let mut fine = plan.clone();
    for v in &mut fine.views {
        v.samples = v.samples.max(TRUTH_SAMPLES);
    }
    let (eye, t) = (eye(state), state.time);
    render_with(&fine, |view, p| {
        fine.world_ray(view, p).map(|ray| world.colour(eye, ray, t))
    })
}

/// An equirectangular panorama of `world` seen from the state's vehicle position.
pub fn equirect(world: &dyn World, state: &State, width: u32, height: u32) -> RgbImage {
    let pano = super::PanoramaWorld::new(RgbImage::new(width, height));
    let (eye, t) = (eye(state), state.time);
    supersample(width, height, 2, |p| {
        Some(world.colour(eye, pano.ray(p - DVec2::splat(0.5)), t))
    })
}
