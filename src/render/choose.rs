//! Which adapter renders, and why: the backend's adapters are tried best first
//! (`gpu::device::adapters`), and each must draw a small known frame as the CPU reference
//! does before it is used; one that draws wrong (the Raspberry Pi 5's Vulkan driver has drawn
//! all black where its GL worked) or will not open is passed over for the next, and the reason
//! travels with the choice to the log, `/api/status` and `doctor`. For the test of this very
//! path, `DIGIVIEW_FAULT=black-adapter` makes the first adapter tried draw black.

use super::cpu;
use super::gpu::renderer::render_image;
use super::gpu::{Gpu, GpuError, Renderer, device};
use crate::frame::PixelFormat;
use crate::image_ops::psnr;
use crate::layout::Rect;
use crate::lens::samples::sample_lenses;
use crate::modes::{GpuBackend, LayoutMode, OverlayMode};
use crate::plan::{Filter, FramePlan};
use crate::scene::GridWorld;
use crate::scene::synth::fisheye;
use crate::state::State;
use image::RgbImage;
use serde::Serialize;
use tracing::{info, warn};

/// The PSNR against the CPU reference an adapter's picture of the known frame must reach:
/// lavapipe and llvmpipe reach over 40 dB; a black picture is under 10.
pub const RIGHT_PSNR: f64 = 30.0;

/// The renderer's adapter as the operator reads it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GpuChoice {
    /// Name, backend, type and driver.
    pub adapter: String,
    /// `vulkan`, `gl`, `metal` or `dx12`.
    pub backend: &'static str,
    /// Why this one: asked for, the best there is, or what the ones before it did wrong.
    pub why: String,
}

/// An open adapter that drew the known frame right, and why it was chosen.
#[derive(Clone, Debug)]
pub struct Chosen {
    pub gpu: Gpu,
    pub choice: GpuChoice,
}

/// Opens the first adapter of `backend` that draws right (see the module's doc).
pub fn open(backend: GpuBackend) -> Result<Chosen, GpuError> {
    let adapters = device::adapters(backend)?;
    let fault = std::env::var("DIGIVIEW_FAULT").is_ok_and(|s| s == "black-adapter");
    let only_gl = adapters
        .iter()
        .all(|a| a.get_info().backend == wgpu::Backend::Gl);
    let mut passed_over = Vec::new();
    for (i, adapter) in adapters.iter().enumerate() {
        let name = device::describe(&adapter.get_info());
        let checked = Gpu::open(adapter).and_then(|mut gpu| {
            gpu.draws_black = fault && i == 0;
            let db = self_check(&gpu)?;
            Ok((gpu, db))
        });
        match checked {
            Ok((gpu, db)) => {
                let choice = GpuChoice {
                    adapter: gpu.describe(),
                    backend: gpu.backend(),
                    why: why(backend, only_gl, &passed_over, db),
                };
                info!("GPU: {}: {}", choice.adapter, choice.why);
                return Ok(Chosen { gpu, choice });
            }
            Err(e) => {
                warn!("GPU: {name} passed over: {e}");
                passed_over.push(format!("{name}: {e}"));
            }
        }
    }
    Err(GpuError::NoneDrawsRight(passed_over.join("; ")))
}

/// Why the adapter chosen renders, in the operator's words (`only_gl`: the backend's adapters
/// were all GL ones).
fn why(backend: GpuBackend, only_gl: bool, passed_over: &[String], db: f64) -> String {
    let drew = format!("it drew the known frame right ({db:.1} dB against the CPU reference)");
    if !passed_over.is_empty() {
        return format!("{drew}, in place of {}", passed_over.join("; "));
    }
    match backend {
        GpuBackend::Auto if only_gl => format!("no Vulkan adapter was found; {drew}"),
        GpuBackend::Auto => format!("the best adapter there is; {drew}"),
        asked => format!("asked for (backend {}); {drew}", asked.name()),
    }
}

/// The known frame: the demo world seen by a sample lens in a 320x240 fisheye, and the
/// default state's four views at 192x192.
fn known_frame() -> (RgbImage, FramePlan) {
    let lens = sample_lenses().remove(0).for_frame(320, 240, None);
    let mut state = State::default();
    let output = &mut state.settings.output;
    (output.width, output.height) = (192, 192);
    (output.layout, output.overlay) = (LayoutMode::Four, OverlayMode::None);
    let plan = FramePlan::new(&state, &lens).expect("four views fit 192x192");
    (fisheye(&GridWorld::default(), &lens, &state), plan)
}

/// Draws the known frame on `gpu` and measures it against the CPU reference: its PSNR, or
/// why the adapter is wrong.
pub fn self_check(gpu: &Gpu) -> Result<f64, GpuError> {
    let (fish, plan) = known_frame();
    let reference = cpu::render(&plan, &fish, Filter::Mip);
    let mut renderer = Renderer::new(gpu, PixelFormat::Rgba, Filter::Mip)?;
    // The pipelines of this frame's view kinds alone: a first start compiles no more.
    renderer.fixed_view_kinds();
    let drawn = render_image(&mut renderer, &fish, &plan)?.to_rgb();
    let whole = Rect::new(0, 0, reference.width(), reference.height());
    let db = psnr(&drawn, &reference, whole);
    if db >= RIGHT_PSNR {
        return Ok(db);
    }
    Err(GpuError::DrewWrong(db, RIGHT_PSNR))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_known_frame_has_a_picture_a_black_one_is_far_from() {
        let (fish, plan) = known_frame();
        let reference = cpu::render(&plan, &fish, Filter::Mip);
        let black = RgbImage::new(reference.width(), reference.height());
        let whole = Rect::new(0, 0, reference.width(), reference.height());
        let db = psnr(&black, &reference, whole);
        assert!(
            db < RIGHT_PSNR - 15.0,
            "black is {db:.1} dB from the reference"
        );
    }
}
