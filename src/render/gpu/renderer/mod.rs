//! The GPU renderer proper: resources made once per input and output layout (`input` and the
//! output target here), pipelines cached by what forces a rebuild (`pipelines`), and per frame
//! only the small parameter and view buffers rewritten.
//!
//! A frame's path: its bytes go into an upload buffer of the ring and from there into the
//! planes' textures and their mip chains (`input`). The draw pass writes the output frame
//! (RGBA, I420 or NV12) into a storage buffer, which is copied into a readback buffer of the
//! ring (`ring`). The draw pass is two dispatches: blocks inside one view, then the few that
//! straddle an edge (the block map, rebuilt when the rectangles change). [`Renderer::push`]
//! hands back frame N-1 while frame N renders. Further outputs (`output`) are drawn from the
//! same upload by [`Renderer::redraw`]: one upload for every output.

use super::input::{Input, InputSetup};
use super::layer::LayerPass;
use super::pipelines::{PipelineKey, Pipelines};
use super::planes::INGEST_BLOCK;
use super::ring::{MapSlot, RING};
use super::{Gpu, GpuError};

mod output;
mod staged;

use crate::frame::{PixelFormat, PlaneLayout, yuv};
use crate::lens::Lens;
use crate::plan::{Filter, FramePlan};
use crate::render::mip::ImagedBox;
use crate::render::stitch::Stitches;
use image::RgbImage;
use output::Output;
pub use output::OutputId;
pub use staged::StageTimes;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Output rows are padded to this many pixels so the draw pass writes whole words.
const OUTPUT_ALIGN: u32 = 8;

/// A rendered output frame, in `layout` (rows may be padded; see [`PlaneLayout`]).
#[derive(Clone, Debug)]
pub struct RenderedFrame {
    /// Counts the frames pushed, from 0.
    pub id: u64,
    pub layout: PlaneLayout,
    pub data: Vec<u8>,
    /// From the start of its upload to its bytes being readable here.
    pub latency: Duration,
}

impl RenderedFrame {
    pub fn to_rgb(&self) -> RgbImage {
        yuv::decode(&self.data, &self.layout).expect("the renderer sized the frame")
    }
}

struct InFlight {
    id: u64,
    readback: MapSlot,
    layout: PlaneLayout,
    started: Instant,
}

pub struct Renderer {
    gpu: Gpu,
    filter: Filter,
    pipelines: Pipelines,
    input: Option<Input>,
    /// What each upload is drawn into.
    main: Output,
    /// What [`Renderer::redraw`] draws into.
    more: Vec<Output>,
    /// See [`Renderer::make_levels_on_host`].
    levels_on_host: bool,
    next_id: u64,
    in_flight: VecDeque<InFlight>,
    /// The thermal layer's passes, made with the first frame that has one.
    layer: Option<LayerPass>,
    /// A lens pair's seam, blended into each frame before it is uploaded.
    stitches: Stitches,
}

impl Renderer {
    /// A renderer producing `output_format` frames filtered with `filter`. Input and output
    /// sizes are taken from each frame; resources follow them.
    pub fn new(gpu: &Gpu, output_format: PixelFormat, filter: Filter) -> Result<Self, GpuError> {
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pipelines::new(gpu);
        let main = Output::new(device, output_format, filter);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Failed(format!("setting up the renderer: {e}")));
        }
        Ok(Renderer {
            gpu: gpu.clone(),
            filter,
            pipelines,
            input: None,
            main,
            more: Vec::new(),
            levels_on_host: gpu.is_software(),
            next_id: 0,
            in_flight: VecDeque::new(),
            layer: None,
            stitches: Stitches::default(),
        })
    }

    pub fn output_format(&self) -> PixelFormat {
        self.main.format
    }

    /// Adds an output that [`Renderer::redraw`] draws from each upload, in `format` with
    /// `filter` (the mip filter only where the renderer's own filter is mip: the bilinear
    /// filter makes no levels).
    pub fn add_output(
        &mut self,
        format: PixelFormat,
        filter: Filter,
    ) -> Result<OutputId, GpuError> {
        self.check_filter(filter, 0)?;
        self.more
            .push(Output::new(&self.gpu.device, format, filter));
        Ok(OutputId(self.more.len() - 1))
    }

    /// Draws output `id` from the next [`Renderer::redraw`] on with `filter`, the bilinear
    /// filter from the frame's mip level `level` (0: the frame itself; the level is clamped
    /// to the chain). The mip filter, and a level past 0, only where the renderer's own filter
    /// is mip: the bilinear filter makes no levels.
    pub fn set_filter(
        &mut self,
        id: OutputId,
        (filter, level): (Filter, u32),
    ) -> Result<(), GpuError> {
        self.check_filter(filter, level)?;
        self.more
            .get_mut(id.0)
            .ok_or_else(|| GpuError::Failed(format!("no output {}", id.0)))?
            .set_filter(filter, level);
        Ok(())
    }

    fn check_filter(&self, filter: Filter, level: u32) -> Result<(), GpuError> {
        if self.filter == Filter::Bilinear && (filter == Filter::Mip || level > 0) {
            return Err(GpuError::Failed(
                "an output with the mip filter or a mip level needs a renderer that makes levels"
                    .into(),
            ));
        }
        Ok(())
    }

    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Names the lens models the frames may switch to later (those of lens.cal, for a live
    /// stream where LENS SET can choose any of them): the first frame then makes and compiles
    /// their generic draw pipelines too, so a switch to one of them is drawn at once instead
    /// of waiting for a compilation (lavapipe: a second or two with a cold shader cache).
    /// Ignored with [`Renderer::fixed_view_kinds`].
    pub fn expect_lenses<'a>(&mut self, lenses: impl IntoIterator<Item = &'a Lens>) {
        self.pipelines.expect_lenses(lenses);
    }

    /// How many pipelines the renderer holds (every pass, every set of override constants
    /// built so far).
    pub fn pipelines(&self) -> usize {
        self.pipelines.len()
    }

    /// Says the frames' view kinds will not change (an offline render of one state), so no
    /// generic draw pipelines are made with the first frame (lavapipe: 0.1 s with a warm
    /// shader cache, 1.2 s cold). Should the kinds change anyway, that frame waits for its
    /// pipelines.
    pub fn fixed_view_kinds(&mut self) {
        self.pipelines.kinds_change = false;
    }

    /// Whether draw pipelines specialised for a frame's view kinds are built on another thread
    /// when the kinds change (`Pipelines::draw`). On by default where the device compiles
    /// pipelines when they are built (GPUs), off where it compiles them when they are first
    /// dispatched (software rasterizers).
    pub fn build_in_background(&mut self, on: bool) {
        self.pipelines.build_in_background = on;
    }

    /// Whether the mip filter's levels are made on the host, as the frame is copied into its
    /// upload buffer (`SourcePlanes::make_levels`), rather than by the ingest and mip passes.
    /// The same bytes either way. On by default for software rasterizers, where a pass is CPU
    /// work too and the passes' storage-buffer loads are checked and branched on lane by
    /// lane: on lavapipe the passes take several times what the host's vectorised loop does.
    pub fn make_levels_on_host(&mut self, on: bool) {
        if on != self.levels_on_host {
            self.levels_on_host = on;
            self.input = None;
            self.forget_input();
        }
    }

    /// Waits until the draw pipelines being built on another thread, if any, are ready.
    pub fn wait_for_builds(&mut self) {
        self.pipelines.collect_built(true);
    }

    /// Whether the last frame prepared was drawn by pipelines specialised for its view kinds
    /// (else by the generic ones, while the specialised ones are built or on a software
    /// rasterizer).
    pub fn drew_specialised(&self) -> bool {
        let main = &self.main;
        main.draw_key
            .is_none_or(|key| key.view_kinds == main.frame_kinds)
    }

    /// Forgets every output's bindings that name the input.
    fn forget_input(&mut self) {
        for output in std::iter::once(&mut self.main).chain(&mut self.more) {
            output.forget_input();
        }
    }

    fn input_setup(&self) -> InputSetup<'_> {
        InputSetup {
            gpu: &self.gpu,
            layouts: &self.pipelines.layouts,
            // The ingest reads the input's part of them, which every output shares.
            params: &self.main.params,
            filter: self.filter,
            levels_on_host: self.levels_on_host,
        }
    }

    /// Makes the input side match `layout` and the lens's imaged box (kept while neither
    /// changes).
    fn ensure_input(&mut self, layout: &PlaneLayout, imaged: ImagedBox) {
        if self
            .input
            .as_ref()
            .is_some_and(|s| s.layout == *layout && s.imaged == imaged)
        {
            return;
        }
        self.input = Some(Input::new(&self.input_setup(), layout, imaged));
        self.forget_input();
    }

    /// Checks a frame against the plan, sets up what it needs, and writes its parameters.
    fn prepare(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<(), GpuError> {
        input.check(data)?;
        if input.width.min(input.height) < INGEST_BLOCK.1 {
            return Err(GpuError::InputTooSmall(input.width, input.height));
        }
        if (plan.lens.width, plan.lens.height) != (input.width, input.height) {
            return Err(GpuError::LensSize(
                plan.lens.width,
                plan.lens.height,
                input.width,
                input.height,
            ));
        }
        self.ensure_input(input, plan.lens.imaged_box());
        // Frames arrive in the upload buffers as RGBA or NV12 (I420 woven on the way).
        let upload = self.input.as_ref().unwrap().padded.format;
        if self.input_setup().level_passes() {
            self.pipelines
                .ensure(PipelineKey::Ingest { input: upload })?;
            self.pipelines.ensure(PipelineKey::Mip)?;
        }
        let input = self.input.as_ref().unwrap();
        self.main
            .prepare(&self.gpu, &mut self.pipelines, input, plan)
    }

    fn encode_draw(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let warm_up = self.pipelines.take_warm_up();
        self.main.encode_draw(encoder, &self.pipelines, &warm_up);
    }

    /// Queues `plan`'s thermal layer, if it has one, over `output` (the main one: None).
    fn encode_layer(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        plan: &FramePlan,
        output: Option<OutputId>,
    ) -> Result<(), GpuError> {
        let Some(layer) = &plan.thermal else {
            return Ok(());
        };
        if self.layer.is_none() {
            self.layer = Some(LayerPass::new(&self.gpu)?);
        }
        let out = match output {
            Some(id) => &self.more[id.0],
            None => &self.main,
        };
        let target = out.target.as_ref().unwrap();
        let pass = self.layer.as_mut().unwrap();
        pass.encode(
            &self.gpu,
            encoder,
            layer,
            (&target.buffer, &target.layout, out.format),
        )
    }

    fn encode_upload(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        let input = self.input.as_ref().unwrap();
        input.encode_upload(encoder, slot, self.filter, &self.pipelines);
    }

    fn fill_upload(&mut self, slot: usize, data: &[u8]) -> Result<(), GpuError> {
        let input = self.input.as_mut().unwrap();
        input.fill_upload(&self.gpu.device, slot, data)
    }

    fn submit(&self, encoder: wgpu::CommandEncoder) -> wgpu::SubmissionIndex {
        self.gpu.queue.submit([encoder.finish()])
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        self.gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            })
    }

    /// Queues one frame (`data` laid out as `input`, rendered as `plan` says) and returns the
    /// frame queued before it once that one is readable, so uploads and draws overlap
    /// readbacks. Call [`Renderer::flush`] for the last one.
    pub fn push(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<Option<RenderedFrame>, GpuError> {
        let started = Instant::now();
        self.with_stitched(data, input, plan, |r, data| {
            r.queue(data, input, plan, started)
        })
    }

    /// Calls `then` with `data` as drawn: a lens pair's seam blended (into the stitches' frame).
    fn with_stitched<T>(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
        then: impl FnOnce(&mut Self, &[u8]) -> T,
    ) -> T {
        let mut stitches = std::mem::take(&mut self.stitches);
        let done = then(self, stitches.stitched(&plan.lens, input, data));
        self.stitches = stitches;
        done
    }

    /// [`Renderer::push`] once the frame is as the renderer draws it.
    fn queue(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
        started: Instant,
    ) -> Result<Option<RenderedFrame>, GpuError> {
        self.prepare(data, input, plan)?;
        let id = self.next_id;
        let slot = (id % RING as u64) as usize;
        self.fill_upload(slot, data)?;
        let mut encoder = self.encoder();
        self.encode_upload(&mut encoder, slot);
        self.encode_draw(&mut encoder);
        self.encode_layer(&mut encoder, plan, None)?;
        let target = self.main.target.as_ref().unwrap();
        target.encode_readback(&mut encoder, slot);
        self.submit(encoder);
        self.next_id += 1;
        let input = self.input.as_ref().unwrap();
        input.uploads[slot].request(wgpu::MapMode::Write);
        let readback = target.readbacks[slot].clone();
        readback.request(wgpu::MapMode::Read);
        self.in_flight.push_back(InFlight {
            id,
            readback,
            layout: target.layout,
            started,
        });
        if self.in_flight.len() >= RING {
            return self.flush();
        }
        Ok(None)
    }

    /// Waits for the oldest frame in flight and returns it; None when none is.
    pub fn flush(&mut self) -> Result<Option<RenderedFrame>, GpuError> {
        let Some(frame) = self.in_flight.pop_front() else {
            return Ok(None);
        };
        self.read_back(frame).map(Some)
    }

    /// Waits for a frame's readback buffer and copies the frame out.
    fn read_back(&self, frame: InFlight) -> Result<RenderedFrame, GpuError> {
        frame.readback.wait(&self.gpu.device)?;
        let mut data = frame.readback.read_out(frame.layout.size as usize)?;
        if self.gpu.draws_black {
            data.fill(0);
        }
        Ok(RenderedFrame {
            id: frame.id,
            layout: frame.layout,
            data,
            latency: frame.started.elapsed(),
        })
    }

    /// Draws each `(output, plan)` from the frame last pushed, without uploading it again:
    /// one submission of each output's draw pass and readback, waited for. Each plan's lens
    /// must image the frame as the pushed frame's plan did (its size and imaged box), and an
    /// output is drawn at most once per call. With frames in flight ([`Renderer::push`]),
    /// the frame drawn is the newest pushed.
    pub fn redraw(
        &mut self,
        jobs: &[(OutputId, &FramePlan)],
    ) -> Result<Vec<RenderedFrame>, GpuError> {
        let started = Instant::now();
        let input = self.input.as_ref().ok_or(GpuError::NothingUploaded)?;
        for (n, &(id, plan)) in jobs.iter().enumerate() {
            if (plan.lens.width, plan.lens.height) != (input.layout.width, input.layout.height)
                || plan.lens.imaged_box() != input.imaged
            {
                return Err(GpuError::OtherLens);
            }
            if jobs[..n].iter().any(|&(other, _)| other == id) {
                return Err(GpuError::Failed(format!("output {} drawn twice", id.0)));
            }
            let output = self
                .more
                .get_mut(id.0)
                .ok_or_else(|| GpuError::Failed(format!("no output {}", id.0)))?;
            output.prepare(&self.gpu, &mut self.pipelines, input, plan)?;
        }
        let mut encoder = self.encoder();
        let mut drawn = Vec::with_capacity(jobs.len());
        // The frame drawn from: the newest pushed.
        let id = self.next_id.saturating_sub(1);
        for &(out, plan) in jobs {
            self.more[out.0].encode_draw(&mut encoder, &self.pipelines, &[]);
            self.encode_layer(&mut encoder, plan, Some(out))?;
            let output = &mut self.more[out.0];
            let slot = (output.drawn % RING as u64) as usize;
            output.drawn += 1;
            let target = output.target.as_ref().unwrap();
            target.encode_readback(&mut encoder, slot);
            drawn.push(InFlight {
                id,
                readback: target.readbacks[slot].clone(),
                layout: target.layout,
                started,
            });
        }
        self.submit(encoder);
        for frame in &drawn {
            frame.readback.request(wgpu::MapMode::Read);
        }
        drawn.into_iter().map(|f| self.read_back(f)).collect()
    }

    /// What the operator is told of a pair's exposure match (empty for a single lens).
    pub fn lenses_matched(&self) -> String {
        self.stitches.said()
    }

    /// Renders one frame and waits for it.
    pub fn render(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<RenderedFrame, GpuError> {
        while self.flush()?.is_some() {}
        self.push(data, input, plan)?;
        Ok(self.flush()?.expect("one frame in flight"))
    }
}

/// Uploads an RGB image as a one-off RGBA frame and renders it (for tests and single images).
pub fn render_image(
    renderer: &mut Renderer,
    image: &RgbImage,
    plan: &FramePlan,
) -> Result<RenderedFrame, GpuError> {
    let layout = PlaneLayout::tight(PixelFormat::Rgba, image.width(), image.height())?;
    let data = yuv::encode(image, &layout);
    renderer.render(&data, &layout, plan)
}
