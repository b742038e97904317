//! From a fisheye frame and a frame plan (`crate::plan`: one mapping per view and tile, what
//! the GPU renderer uploads as a small buffer each frame) to the output frame. `mip` builds
//! and samples the minification chain both renderers use; `cpu` is the f64 reference renderer
//! the GPU is measured against; `gpu` is the wgpu renderer that does the work; `choose` picks
//! the adapter it runs on, one that draws a known frame as `cpu` does; `stitch` blends a lens
//! pair's seam into the frame before either renders it; `shutter_fit` measures
//! a rolling shutter's readout from frames the plan's mapping explains. Only the frame loop
//! (`crate::head`), `bench` and the CLI's offline renders use it; the frames themselves, as
//! bytes, are `crate::frame`'s.

pub mod choose;
pub mod cpu;
pub mod gpu;
pub mod mip;
pub mod shutter_fit;
pub mod stitch;
