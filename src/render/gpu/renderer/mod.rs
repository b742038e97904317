//! The GPU renderer proper: resources made once per input and output layout (`input` and the
//! output target here), pipelines cached by what forces a rebuild (`pipelines`), and per frame
//! only the small parameter and view buffers rewritten.
//!
//! A frame's path: its bytes go into an upload buffer of the ring and from there into the
//! planes' textures and their mip chains (`input`). The draw pass writes the output frame
//! (RGBA, I420 or NV12) into a storage buffer, which is copied into a readback buffer of the
//! ring (`ring`). The draw pass is two dispatches: blocks inside one view, then the few that
//! straddle an edge (the block map, rebuilt when the rectangles change). [`Renderer::push`]
//! hands back frame N-1 while frame N renders.

use super::blocks::{BLOCK_H, BLOCK_W};
use super::draw::{BlockBuffer, Target};
use super::input::{Input, InputSetup};
use super::params::{GpuParams, GpuView, MAX_VIEWS, frame_params};
use super::pipelines::{DrawKey, MIXED_WORKGROUP, PipelineKey, Pipelines, bind, groups};
use super::planes::INGEST_BLOCK;
use super::ring::{MapSlot, RING};
use super::{Gpu, GpuError};

mod staged;

use crate::frame::{PixelFormat, PlaneLayout, yuv};
use crate::lens::Model;
use crate::render::mip::{Filter, ImagedBox};
use crate::render::plan::FramePlan;
use image::RgbImage;
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
    output_format: PixelFormat,
    filter: Filter,
    params: wgpu::Buffer,
    views: wgpu::Buffer,
    sampler: wgpu::Sampler,
    pipelines: Pipelines,
    input: Option<Input>,
    target: Option<Target>,
    draw_group: Option<wgpu::BindGroup>,
    blocks: Option<BlockBuffer>,
    /// The draw pipelines drawing the frame last prepared, and that frame's own view kinds
    /// (they differ while it is drawn generically).
    draw_key: Option<DrawKey>,
    frame_kinds: u32,
    /// See [`Renderer::make_levels_on_host`].
    levels_on_host: bool,
    next_id: u64,
    in_flight: VecDeque<InFlight>,
}

impl Renderer {
    /// A renderer producing `output_format` frames filtered with `filter`. Input and output
    /// sizes are taken from each frame; resources follow them.
    pub fn new(gpu: &Gpu, output_format: PixelFormat, filter: Filter) -> Result<Self, GpuError> {
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pipelines::new(gpu);
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame params"),
            size: size_of::<GpuParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let views = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame views"),
            size: (size_of::<GpuView>() * MAX_VIEWS) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Bilinear filtering samples level 0 alone: a sampler and views (`Input`) that say so
        // let a software rasterizer leave out the per-pixel choice of levels.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("trilinear"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: match filter {
                Filter::Mip => wgpu::MipmapFilterMode::Linear,
                Filter::Bilinear => wgpu::MipmapFilterMode::Nearest,
            },
            ..Default::default()
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Failed(format!("setting up the renderer: {e}")));
        }
        Ok(Renderer {
            gpu: gpu.clone(),
            output_format,
            filter,
            params,
            views,
            sampler,
            pipelines,
            input: None,
            target: None,
            draw_group: None,
            blocks: None,
            draw_key: None,
            frame_kinds: 0,
            levels_on_host: gpu.is_software(),
            next_id: 0,
            in_flight: VecDeque::new(),
        })
    }

    pub fn output_format(&self) -> PixelFormat {
        self.output_format
    }

    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Names the lens models the frames may switch to later (those of lens.cal, for a live
    /// stream where LENS SET can choose any of them): the first frame then makes and compiles
    /// their generic draw pipelines too, so a switch to one of them is drawn at once instead
    /// of waiting for a compilation (lavapipe: a second or two with a cold shader cache).
    /// Ignored with [`Renderer::fixed_view_kinds`].
    pub fn expect_lens_models<'a>(&mut self, models: impl IntoIterator<Item = &'a Model>) {
        self.pipelines.expect_lens_models(models);
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
            self.draw_group = None;
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
        self.draw_key
            .is_none_or(|key| key.view_kinds == self.frame_kinds)
    }

    fn input_setup(&self) -> InputSetup<'_> {
        InputSetup {
            gpu: &self.gpu,
            layouts: &self.pipelines.layouts,
            params: &self.params,
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
        self.draw_group = None;
    }

    /// Makes the output-side resources match a `width` × `height` frame.
    fn ensure_target(&mut self, width: u32, height: u32) -> Result<(), GpuError> {
        let layout = PlaneLayout::aligned(self.output_format, width, height, OUTPUT_ALIGN)?;
        if self.target.as_ref().is_some_and(|t| t.layout == layout) {
            return Ok(());
        }
        self.target = Some(Target::new(&self.gpu.device, layout));
        self.draw_group = None;
        Ok(())
    }

    fn ensure_draw_group(&mut self) {
        if self.draw_group.is_some() {
            return;
        }
        let (input, target) = (self.input.as_ref().unwrap(), self.target.as_ref().unwrap());
        let blocks = &self.blocks.as_ref().unwrap().buffer;
        // RGBA has one plane: bound twice, the second never sampled.
        let plane = |i| wgpu::BindingResource::TextureView(input.plane_view(i));
        self.draw_group = Some(
            self.gpu
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("draw"),
                    layout: &self.pipelines.layouts.draw,
                    entries: &[
                        bind(0, self.params.as_entire_binding()),
                        bind(1, self.views.as_entire_binding()),
                        bind(2, plane(0)),
                        bind(3, wgpu::BindingResource::Sampler(&self.sampler)),
                        bind(4, target.buffer.as_entire_binding()),
                        bind(5, blocks.as_entire_binding()),
                        bind(6, plane(1)),
                    ],
                }),
        );
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
        self.ensure_target(plan.layout.width, plan.layout.height)?;
        let rects: Vec<_> = plan.views.iter().map(|v| v.rect).collect();
        let size = (plan.layout.width, plan.layout.height);
        let gpu = &self.gpu;
        if BlockBuffer::follow(&mut self.blocks, &gpu.device, &gpu.queue, size, &rects) {
            self.draw_group = None;
        }
        self.ensure_draw_group();
        let input = self.input.as_ref().unwrap();
        let target = self.target.as_ref().unwrap();
        let mixed = self.mixed_blocks();
        let (params, views) =
            frame_params(plan, &input.padded, &target.layout, input.levels, mixed)?;
        // The draw pipeline leaves out the code of view kinds the frame lacks.
        let kinds = views.iter().fold(0, |kinds, v| kinds | 1 << v.kind[0]);
        let wanted = DrawKey {
            lens_model: plan.lens.radial.model.code(),
            output: self.output_format,
            filter: self.filter,
            input: upload,
            view_kinds: kinds,
        };
        self.draw_key = Some(self.pipelines.draw(wanted)?);
        self.frame_kinds = kinds;
        let queue = &self.gpu.queue;
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if !views.is_empty() {
            queue.write_buffer(&self.views, 0, bytemuck::cast_slice(&views));
        }
        Ok(())
    }

    /// Blocks the draw pass's per-pixel dispatch draws.
    fn mixed_blocks(&self) -> u32 {
        self.blocks.as_ref().map_or(0, BlockBuffer::mixed)
    }

    fn encode_draw(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let warm_up = self.pipelines.take_warm_up();
        let target = self.target.as_ref().unwrap();
        let key = self.draw_key.expect("a prepared frame");
        let pipelines = &self.pipelines;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("draw"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, self.draw_group.as_ref().unwrap(), &[]);
        // One workgroup of each generic pipeline, drawing what the full dispatch then draws
        // again, so they are compiled now rather than when a frame first needs them (a pair
        // for another lens model reads this frame's lens as one of its own: what it draws is
        // nonsense, drawn over the same way).
        for generic in warm_up {
            for pipeline in [PipelineKey::Draw(generic), PipelineKey::DrawMixed(generic)] {
                pass.set_pipeline(pipelines.get(pipeline));
                pass.dispatch_workgroups(1, 1, 1);
            }
        }
        pass.set_pipeline(pipelines.get(PipelineKey::Draw(key)));
        let (w, h) = (target.layout.width, target.layout.height);
        pass.dispatch_workgroups(groups(w.div_ceil(BLOCK_W)), groups(h.div_ceil(BLOCK_H)), 1);
        let mixed = self.mixed_blocks();
        if mixed > 0 {
            pass.set_pipeline(pipelines.get(PipelineKey::DrawMixed(key)));
            pass.dispatch_workgroups(mixed.div_ceil(MIXED_WORKGROUP), 1, 1);
        }
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
        self.prepare(data, input, plan)?;
        let id = self.next_id;
        let slot = (id % RING as u64) as usize;
        self.fill_upload(slot, data)?;
        let mut encoder = self.encoder();
        self.encode_upload(&mut encoder, slot);
        self.encode_draw(&mut encoder);
        self.target
            .as_ref()
            .unwrap()
            .encode_readback(&mut encoder, slot);
        self.submit(encoder);
        self.next_id += 1;
        let (input, target) = (self.input.as_ref().unwrap(), self.target.as_ref().unwrap());
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
        frame.readback.wait(&self.gpu.device)?;
        let data = frame.readback.read_out(frame.layout.size as usize)?;
        Ok(Some(RenderedFrame {
            id: frame.id,
            layout: frame.layout,
            data,
            latency: frame.started.elapsed(),
        }))
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
