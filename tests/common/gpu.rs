//! The GPU renderer as the GPU tests use it: one device per backend per test binary (Mesa's
//! lavapipe through Vulkan and llvmpipe through GL in CI; no adapter is a failure, never a
//! skip), a standard state and frames in every format.

use super::{DEG, four_view_state, three_tracked};
use digiview::frame::{PixelFormat, PlaneLayout, yuv};
use digiview::layout::Rect;
use digiview::modes::GpuBackend;
use digiview::modes::OverlayMode;
use digiview::plan::Filter;
use digiview::render::choose;
pub use digiview::render::gpu::Gpu;
use digiview::render::gpu::Renderer;
use digiview::state::State;
use image::RgbImage;
use std::sync::OnceLock;

/// One Vulkan device for the whole test binary: opening lavapipe is not free.
pub fn gpu() -> Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| open(GpuBackend::Vulkan)).clone()
}

/// One GL device for the whole test binary (llvmpipe through EGL in CI).
pub fn gl() -> Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| open(GpuBackend::Gl)).clone()
}

fn open(backend: GpuBackend) -> Gpu {
    match choose::open(backend) {
        Ok(chosen) => chosen.gpu,
        Err(e) => panic!("a {} adapter (Mesa's in CI): {e}", backend.name()),
    }
}

/// A renderer on the Vulkan device.
pub fn renderer(format: PixelFormat, filter: Filter) -> Renderer {
    renderer_on(&gpu(), format, filter)
}

/// A renderer on `gpu`.
pub fn renderer_on(gpu: &Gpu, format: PixelFormat, filter: Filter) -> Renderer {
    Renderer::new(gpu, format, filter).unwrap()
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

/// Each picture test `NAME(&Gpu)` as two tests, `NAME::vulkan` and `NAME::gl`: the same
/// bounds on lavapipe through Vulkan and on llvmpipe through GL (issue 58).
#[allow(unused_macros)] // tests/alone has no picture tests
macro_rules! on_each_backend {
    ($($name:ident),+ $(,)?) => {$(
        mod $name {
            #[test]
            fn vulkan() {
                super::$name(&crate::common::gpu::gpu())
            }
            #[test]
            fn gl() {
                super::$name(&crate::common::gpu::gl())
            }
        }
    )+};
}
#[allow(unused_imports)]
pub(crate) use on_each_backend;
