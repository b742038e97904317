//! From a fisheye frame and a state to the output frame. `plan` turns the state into one
//! mapping per view and tile (what the GPU renderer uploads as a small buffer each frame);
//! `mip` defines the minification filter both renderers use; `cpu` is the f64 reference
//! renderer the GPU is measured against; `gpu` is the wgpu renderer that does the work;
//! `shutter_fit` measures a rolling shutter's readout from frames the plan's mapping
//! explains; `thermal_layer` lays a thermal camera's picture over the views. The frames themselves, as bytes, are `crate::frame`'s.

pub mod cpu;
pub mod gpu;
pub mod mip;
pub mod plan;
pub mod shutter_fit;
pub mod thermal_layer;

pub use mip::Filter;
pub use plan::{FramePlan, PlannedView, ViewMap};
