//! The GPU renderer (wgpu, WGSL in shaders/): fisheye bytes in, output frame bytes out, one
//! draw pass per frame for all views. `device` picks the adapter, `shaders` composes the WGSL,
//! `params` lays out the per-frame buffers shared with it, `planes` how the source's planes
//! and mip levels are held (plain arithmetic), `blocks` says which view draws each block of
//! the output, `pipelines` builds and caches the passes' pipelines, `input` owns the
//! input-side resources and the upload, `draw` the output target and the block map's buffer,
//! `ring` the mapped buffers of frames in flight, and `renderer` ties them into the upload →
//! render → readback path; `thermal` colours a thermal sensor's counts and `layer` draws
//! them over the output. Touches no sockets
//! and no GStreamer.

pub mod blocks;
pub mod device;
mod draw;
mod input;
pub mod layer;
pub mod params;
mod pipelines;
pub mod planes;
pub mod renderer;
mod ring;
pub mod shaders;
pub mod thermal;
#[cfg(test)]
mod twins;

pub use device::Gpu;
pub use renderer::{OutputId, RenderedFrame, Renderer, StageTimes};

use crate::frame::FrameError;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter of the backend asked for; what to install.
    #[error("no GPU adapter found{0}")]
    NoAdapter(String),
    /// The start-up check's known frame came out unlike the CPU reference's (`render::choose`).
    #[error("it drew a known frame wrong: {0:.1} dB against the CPU reference, {1} needed")]
    DrewWrong(f64, f64),
    /// Every adapter tried drew wrong or would not open: each with why.
    #[error("no GPU adapter draws right: {0}")]
    NoneDrawsRight(String),
    #[error("no GPU adapter's name contains {wanted:?} (found: {found})")]
    AdapterNotFound { wanted: String, found: String },
    #[error("opening the GPU device {adapter}: {source}")]
    Device {
        adapter: String,
        source: wgpu::RequestDeviceError,
    },
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("the frame has {0} views and tiles; the GPU renderer draws at most {1}")]
    TooManyViews(usize, usize),
    #[error("lens {lens}: {what}")]
    Lens { lens: String, what: String },
    #[error("the input frame is {0}x{1}; the GPU renderer takes at least 4x4")]
    InputTooSmall(u32, u32),
    #[error("the plan's lens is for a {0}x{1} frame but the input is {2}x{3}")]
    LensSize(u32, u32, u32, u32),
    #[error("no frame has been uploaded to draw again")]
    NothingUploaded,
    #[error("the plan's lens images the frame otherwise than the upload's")]
    OtherLens,
    #[error("the GPU failed: {0}")]
    Failed(String),
}
