//! From a fisheye frame and a state to the output frame. `plan` turns the state into one
//! mapping per view and tile (the part the GPU renderer will upload as a small buffer);
//! `cpu` is the f64 reference renderer that the GPU is measured against.

pub mod cpu;
pub mod plan;

pub use plan::{FramePlan, PlannedView, ViewMap};
