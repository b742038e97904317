//! Synthetic worlds with known content: the input stand-in for a camera and the source of
//! ground truth. A world answers "what colour is seen along this ray from here at time t";
//! `synth` turns that into the fisheye frame a lens would capture and into the exact output
//! frame DigiView should produce; `thermal`, the world's temperatures and what a thermal camera
//! beside the fisheye sees of them.

pub mod board;
pub mod grid;
pub mod panorama;
pub mod synth;
pub mod thermal;

pub use grid::{GridWorld, Landmark};
pub use panorama::PanoramaWorld;

use glam::DVec3;

/// Colours are 8-bit-scale RGB in f64 (0..=255), no gamma: the renderers average them as is.
pub trait World: Sync {
    /// The colour seen from `eye` (NED metres in the world's frame) along unit `ray` at time
    /// `t` seconds.
    fn colour(&self, eye: DVec3, ray: DVec3, t: f64) -> DVec3;
}

pub(crate) fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
