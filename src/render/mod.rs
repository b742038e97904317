//! From a fisheye frame and a state to the output frame. `plan` turns the state into one
//! mapping per view and tile (what the GPU renderer uploads as a small buffer each frame);
//! `mip` defines the minification filter both renderers use; `cpu` is the f64 reference
//! renderer the GPU is measured against; `gpu` is the wgpu renderer that does the work;
//! `frame` and `yuv` describe frames as bytes (RGBA, I420, NV12).

pub mod cpu;
pub mod frame;
pub mod gpu;
pub mod mip;
pub mod plan;
pub mod yuv;

pub use frame::{PixelFormat, PlaneLayout};
pub use mip::Filter;
pub use plan::{FramePlan, PlannedView, ViewMap};
