//! The GPU renderer as the GPU tests use it: one device per test binary (lavapipe in CI; no
//! adapter is a failure, never a skip), a standard state and frames in every format.

use super::{DEG, four_view_state, three_tracked};
use digiview::frame::{PixelFormat, PlaneLayout, yuv};
use digiview::layout::Rect;
use digiview::modes::OverlayMode;
use digiview::plan::Filter;
use digiview::render::gpu::{Gpu, Renderer};
use digiview::state::State;
use image::RgbImage;
use std::sync::OnceLock;

/// One device for the whole test binary: opening lavapipe is not free.
pub fn gpu() -> Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| Gpu::new().expect("a GPU adapter (lavapipe in CI)"))
        .clone()
}

pub fn renderer(format: PixelFormat, filter: Filter) -> Renderer {
    Renderer::new(&gpu(), format, filter).unwrap()
}

pub fn whole(img: &RgbImage) -> Rect {
    Rect::new(0, 0, img.width(), img.height())
}

/// Four views and three detection tiles at 480x272, the vehicle rolled.
pub fn base_state() -> State {
    let mut s = four_view_state(7);
    (s.settings.output.width, s.settings.output.height) = (480, 272);
    s.settings.output.overlay = OverlayMode::Right;
    s.vehicle.attitude.roll = 10.0 * DEG;
    s.tracked = three_tracked();
    s
}

/// The fisheye frame as bytes of `format` (chroma from each 2x2 block's mean).
pub fn as_format(img: &RgbImage, format: PixelFormat) -> (Vec<u8>, PlaneLayout) {
    let layout = PlaneLayout::tight(format, img.width(), img.height()).unwrap();
    (yuv::encode(img, &layout), layout)
}
