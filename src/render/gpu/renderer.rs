//! The GPU renderer proper: resources made once per input and output layout, pipelines cached
//! by what forces a rebuild (input format, lens model, output format, filter), and per frame
//! only the small parameter and view buffers rewritten.
//!
//! A frame's path: its bytes are copied into a mapped upload buffer (one of a ring, so the
//! copy never waits for a fresh allocation), copied to the GPU, turned into mip levels 0, 1
//! and 2 by the ingest pass (over the lens's imaged box only) and into the rest of the chain
//! by the mip passes; the draw pass writes the output frame (RGBA, I420 or NV12) into a
//! storage buffer, which is copied into a readback buffer of the ring. The draw pass is two
//! dispatches: blocks inside one view, then the few that straddle an edge (the block map,
//! rebuilt when the rectangles change). [`Renderer::push`] hands back frame N-1 while frame N
//! renders.

use super::blocks::{BLOCK_H, BLOCK_W, BlockMap};
use super::params::{GpuParams, GpuView, MAX_VIEWS, frame_params, model_code};
use super::shaders;
use super::{Gpu, GpuError};
use crate::render::frame::{PixelFormat, PlaneLayout};
use crate::render::mip::{Filter, levels_for};
use crate::render::plan::FramePlan;
use crate::render::yuv;
use image::RgbImage;
use std::collections::{HashMap, VecDeque};
use std::ops::Range;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::{Duration, Instant};

/// Frames in flight: frame N renders while frame N-1 is read back.
pub const RING: usize = 2;
/// Output rows are padded to this many pixels so the draw pass writes whole words.
const OUTPUT_ALIGN: u32 = 8;
const WORKGROUP: u32 = 8;

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

/// Where one frame's time went, each stage waited for on its own (see
/// [`Renderer::render_staged`]).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// Copy into the upload buffer, transfer, format conversion and mip chain.
    pub upload: Duration,
    /// The draw pass.
    pub render: Duration,
    /// Copy to the readback buffer, map, and copy out.
    pub readback: Duration,
}

const PENDING: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

/// A buffer of the ring with its mapping state, set by wgpu's map callback.
#[derive(Clone)]
struct MapSlot {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
}

impl MapSlot {
    fn new(device: &wgpu::Device, label: &str, size: u64, usage: wgpu::BufferUsages) -> Self {
        let write = usage.contains(wgpu::BufferUsages::MAP_WRITE);
        MapSlot {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: write,
            }),
            state: Arc::new(AtomicU8::new(if write { MAPPED } else { PENDING })),
        }
    }

    /// Asks for the buffer to be mapped once the GPU is done with it.
    fn request(&self, mode: wgpu::MapMode) {
        self.state.store(PENDING, Ordering::Release);
        let state = self.state.clone();
        self.buffer.map_async(mode, .., move |r| {
            state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
        });
    }

    fn wait(&self, device: &wgpu::Device) -> Result<(), GpuError> {
        while self.state.load(Ordering::Acquire) == PENDING {
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| GpuError::Failed(e.to_string()))?;
        }
        match self.state.load(Ordering::Acquire) {
            MAPPED => Ok(()),
            _ => Err(GpuError::Failed("mapping a ring buffer failed".into())),
        }
    }
}

/// Columns and rows of the input the lens images.
type ImagedBox = (Range<u32>, Range<u32>);

/// What depends on the input layout: upload ring, raw buffer, the mip-chained texture.
struct Source {
    layout: PlaneLayout,
    /// The input pixels the ingest converts (`Lens::imaged_box`).
    imaged: ImagedBox,
    levels: u32,
    uploads: Vec<MapSlot>,
    raw: wgpu::Buffer,
    sampled: wgpu::TextureView,
    ingest: wgpu::BindGroup,
    /// Level k → k + 1 for k = 2..levels-1 (the ingest writes levels 0, 1 and 2).
    mips: Vec<(wgpu::BindGroup, (u32, u32))>,
}

/// What depends on the output layout: the storage buffer the draw pass writes, readback ring.
struct Target {
    layout: PlaneLayout,
    buffer: wgpu::Buffer,
    readbacks: Vec<MapSlot>,
}

struct InFlight {
    id: u64,
    readback: MapSlot,
    layout: PlaneLayout,
    started: Instant,
}

struct Layouts {
    ingest: wgpu::BindGroupLayout,
    mip: wgpu::BindGroupLayout,
    draw: wgpu::BindGroupLayout,
}

pub struct Renderer {
    gpu: Gpu,
    output_format: PixelFormat,
    filter: Filter,
    params: wgpu::Buffer,
    views: wgpu::Buffer,
    sampler: wgpu::Sampler,
    layouts: Layouts,
    modules: [wgpu::ShaderModule; 3],
    pipelines: HashMap<(usize, [u32; 3]), wgpu::ComputePipeline>,
    source: Option<Source>,
    target: Option<Target>,
    draw_group: Option<wgpu::BindGroup>,
    /// The block map of the last frame's rectangles and the buffer holding it.
    blocks: Option<(BlockMap, wgpu::Buffer)>,
    next_id: u64,
    in_flight: VecDeque<InFlight>,
}

fn entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty,
        count: None,
    }
}

fn uniform() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn storage(read_only: bool) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn store_texture() -> wgpu::BindingType {
    wgpu::BindingType::StorageTexture {
        access: wgpu::StorageTextureAccess::WriteOnly,
        format: wgpu::TextureFormat::Rgba8Unorm,
        view_dimension: wgpu::TextureViewDimension::D2,
    }
}

fn sampled_texture() -> wgpu::BindingType {
    wgpu::BindingType::Texture {
        sample_type: wgpu::TextureSampleType::Float { filterable: true },
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled: false,
    }
}

fn groups(n: u32) -> u32 {
    n.div_ceil(WORKGROUP)
}

const INGEST: usize = 0;
const MIP: usize = 1;
const DRAW: usize = 2;
/// The draw pass's per-pixel dispatch, from the draw module.
const DRAW_MIXED: usize = 3;
const ENTRY_POINTS: [&str; 4] = ["ingest", "downsample", "draw", "draw_mixed"];
/// Mip levels the ingest writes (the rest come from the mip passes).
const INGEST_LEVELS: u32 = 3;
/// Invocations in a `draw_mixed` workgroup, one block each.
const MIXED_WORKGROUP: u32 = 64;

impl Renderer {
    /// A renderer producing `output_format` frames filtered with `filter`. Input and output
    /// sizes are taken from each frame; resources follow them.
    pub fn new(gpu: &Gpu, output_format: PixelFormat, filter: Filter) -> Result<Self, GpuError> {
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let layouts = Layouts {
            ingest: layout(
                "ingest bindings",
                &[
                    entry(0, uniform()),
                    entry(1, storage(true)),
                    entry(2, store_texture()),
                    entry(3, store_texture()),
                    entry(4, store_texture()),
                ],
            ),
            mip: layout(
                "mip bindings",
                &[entry(0, sampled_texture()), entry(1, store_texture())],
            ),
            draw: layout(
                "draw bindings",
                &[
                    entry(0, uniform()),
                    entry(1, uniform()),
                    entry(2, sampled_texture()),
                    entry(
                        3,
                        wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    ),
                    entry(4, storage(false)),
                    entry(5, storage(true)),
                ],
            ),
        };
        let modules = shaders::passes().map(|(name, source)| {
            let desc = wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            };
            // SAFETY: every index in the shaders is in range by construction (views by the
            // count written with them, words by the plane layouts the buffers are sized by,
            // both checked by the parity tests); the runtime bounds checks wgpu would add cost
            // a third of the draw pass on lavapipe.
            unsafe {
                device.create_shader_module_trusted(desc, wgpu::ShaderRuntimeChecks::unchecked())
            }
        });
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
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("trilinear"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
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
            layouts,
            modules,
            pipelines: HashMap::new(),
            source: None,
            target: None,
            draw_group: None,
            blocks: None,
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

    fn pipeline(&mut self, pass: usize, constants: [u32; 3]) -> Result<(), GpuError> {
        if self.pipelines.contains_key(&(pass, constants)) {
            return Ok(());
        }
        let device = &self.gpu.device;
        let names: &[&str] = match pass {
            INGEST => &["INPUT_FORMAT"],
            MIP => &[],
            _ => &["LENS_MODEL", "OUTPUT_FORMAT", "FILTER"],
        };
        let values: Vec<(&str, f64)> = names
            .iter()
            .zip(constants)
            .map(|(n, v)| (*n, v as f64))
            .collect();
        let bind_layout = match pass {
            INGEST => &self.layouts.ingest,
            MIP => &self.layouts.mip,
            _ => &self.layouts.draw,
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(ENTRY_POINTS[pass]),
            bind_group_layouts: &[Some(bind_layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(ENTRY_POINTS[pass]),
            layout: Some(&layout),
            module: &self.modules[pass.min(DRAW)],
            entry_point: Some(ENTRY_POINTS[pass]),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &values,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Failed(format!(
                "building the {} pipeline: {e}",
                ENTRY_POINTS[pass]
            )));
        }
        self.pipelines.insert((pass, constants), pipeline);
        Ok(())
    }

    /// Makes the input-side resources match `layout` and the lens's imaged box (kept while
    /// neither changes; a fresh texture is black outside the box, which the ingest never
    /// writes).
    fn ensure_source(&mut self, layout: &PlaneLayout, imaged: ImagedBox) {
        if self
            .source
            .as_ref()
            .is_some_and(|s| s.layout == *layout && s.imaged == imaged)
        {
            return;
        }
        let device = &self.gpu.device;
        let size = (layout.size as u64).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let uploads = (0..RING)
            .map(|i| {
                MapSlot::new(
                    device,
                    &format!("upload {i}"),
                    size,
                    wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
                )
            })
            .collect();
        let raw = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("raw input"),
            // The ingest reads up to 16 bytes past a row's last block.
            size: size + 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let levels = levels_for(layout.width, layout.height);
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("source"),
            size: wgpu::Extent3d {
                width: layout.width,
                height: layout.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::STORAGE_BINDING,
            view_formats: &[],
        });
        let level = |k: u32| {
            texture.create_view(&wgpu::TextureViewDescriptor {
                label: Some("source level"),
                base_mip_level: k,
                mip_level_count: Some(1),
                ..Default::default()
            })
        };
        let ingest = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ingest"),
            layout: &self.layouts.ingest,
            entries: &[
                bind(0, self.params.as_entire_binding()),
                bind(1, raw.as_entire_binding()),
                bind(2, wgpu::BindingResource::TextureView(&level(0))),
                bind(3, wgpu::BindingResource::TextureView(&level(1))),
                bind(4, wgpu::BindingResource::TextureView(&level(2))),
            ],
        });
        let mips = (INGEST_LEVELS - 1..levels - 1)
            .map(|k| {
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("mip"),
                    layout: &self.layouts.mip,
                    entries: &[
                        bind(0, wgpu::BindingResource::TextureView(&level(k))),
                        bind(1, wgpu::BindingResource::TextureView(&level(k + 1))),
                    ],
                });
                let size = (
                    (layout.width >> (k + 1)).max(1),
                    (layout.height >> (k + 1)).max(1),
                );
                (group, size)
            })
            .collect();
        let sampled = texture.create_view(&wgpu::TextureViewDescriptor::default());
        self.source = Some(Source {
            layout: *layout,
            imaged,
            levels,
            uploads,
            raw,
            sampled,
            ingest,
            mips,
        });
        self.draw_group = None;
    }

    /// Makes the output-side resources match a `width` × `height` frame.
    fn ensure_target(&mut self, width: u32, height: u32) -> Result<(), GpuError> {
        let layout = PlaneLayout::aligned(self.output_format, width, height, OUTPUT_ALIGN)?;
        if self.target.as_ref().is_some_and(|t| t.layout == layout) {
            return Ok(());
        }
        let device = &self.gpu.device;
        let size = layout.size as u64;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("output frame"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readbacks = (0..RING)
            .map(|i| {
                MapSlot::new(
                    device,
                    &format!("readback {i}"),
                    size,
                    wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                )
            })
            .collect();
        self.target = Some(Target {
            layout,
            buffer,
            readbacks,
        });
        self.draw_group = None;
        Ok(())
    }

    fn ensure_draw_group(&mut self) {
        if self.draw_group.is_some() {
            return;
        }
        let (source, target) = (self.source.as_ref().unwrap(), self.target.as_ref().unwrap());
        let blocks = &self.blocks.as_ref().unwrap().1;
        self.draw_group = Some(
            self.gpu
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("draw"),
                    layout: &self.layouts.draw,
                    entries: &[
                        bind(0, self.params.as_entire_binding()),
                        bind(1, self.views.as_entire_binding()),
                        bind(2, wgpu::BindingResource::TextureView(&source.sampled)),
                        bind(3, wgpu::BindingResource::Sampler(&self.sampler)),
                        bind(4, target.buffer.as_entire_binding()),
                        bind(5, blocks.as_entire_binding()),
                    ],
                }),
        );
    }

    /// Makes the block map follow the plan's rectangles, rewriting its buffer when they
    /// change (and replacing the buffer when it is too small).
    fn ensure_blocks(&mut self, plan: &FramePlan) {
        let (w, h) = (plan.layout.width, plan.layout.height);
        let rects: Vec<_> = plan.views.iter().map(|v| v.rect).collect();
        if self
            .blocks
            .as_ref()
            .is_some_and(|(m, _)| m.is_for(w, h, &rects))
        {
            return;
        }
        let map = BlockMap::new(w, h, &rects);
        let words = map.words();
        let size = (words.len() * 4) as u64;
        let buffer = match self.blocks.take() {
            Some((_, buffer)) if buffer.size() >= size => buffer,
            _ => {
                self.draw_group = None;
                self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("block map"),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            }
        };
        self.gpu
            .queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(&words));
        self.blocks = Some((map, buffer));
    }

    /// Checks a frame against the plan, sets up what it needs, and writes its parameters.
    fn prepare(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<(), GpuError> {
        input.check(data)?;
        if input.width.min(input.height) < 1 << (INGEST_LEVELS - 1) {
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
        let model = model_code(&plan.lens.radial.model);
        self.pipeline(INGEST, [input.format.shader_code(), 0, 0])?;
        self.pipeline(MIP, [0; 3])?;
        let draw = [
            model,
            self.output_format.shader_code(),
            self.filter.shader_code(),
        ];
        self.pipeline(DRAW, draw)?;
        self.pipeline(DRAW_MIXED, draw)?;
        self.ensure_source(input, plan.lens.imaged_box());
        self.ensure_target(plan.layout.width, plan.layout.height)?;
        self.ensure_blocks(plan);
        self.ensure_draw_group();
        let source = self.source.as_ref().unwrap();
        let target = self.target.as_ref().unwrap();
        let mixed = self.mixed_blocks();
        let (columns, rows) = &source.imaged;
        let origin = (columns.start, rows.start);
        let (params, views) =
            frame_params(plan, input, &target.layout, source.levels, origin, mixed)?;
        let queue = &self.gpu.queue;
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if !views.is_empty() {
            queue.write_buffer(&self.views, 0, bytemuck::cast_slice(&views));
        }
        Ok(())
    }

    /// Copies the frame's bytes into upload buffer `slot` (waiting until it is free).
    fn fill_upload(&self, slot: usize, data: &[u8]) -> Result<(), GpuError> {
        let upload = &self.source.as_ref().unwrap().uploads[slot];
        upload.wait(&self.gpu.device)?;
        {
            let mut view = upload
                .buffer
                .get_mapped_range_mut(..)
                .map_err(|e| GpuError::Failed(e.to_string()))?;
            view.slice(..data.len()).copy_from_slice(data);
        }
        upload.buffer.unmap();
        Ok(())
    }

    fn encode_upload(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        let source = self.source.as_ref().unwrap();
        encoder.copy_buffer_to_buffer(&source.uploads[slot].buffer, 0, &source.raw, 0, None);
        let format = source.layout.format.shader_code();
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("ingest and mip chain"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines[&(INGEST, [format, 0, 0])]);
        pass.set_bind_group(0, &source.ingest, &[]);
        let (columns, rows) = &source.imaged;
        pass.dispatch_workgroups(
            groups(columns.len().div_ceil(4) as u32),
            groups(rows.len().div_ceil(4) as u32),
            1,
        );
        pass.set_pipeline(&self.pipelines[&(MIP, [0; 3])]);
        for (group, (w, h)) in &source.mips {
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(groups(*w), groups(*h), 1);
        }
    }

    /// Blocks the draw pass's per-pixel dispatch draws.
    fn mixed_blocks(&self) -> u32 {
        self.blocks
            .as_ref()
            .map_or(0, |(m, _)| m.mixed.len() as u32)
    }

    fn encode_draw(&self, encoder: &mut wgpu::CommandEncoder, model: u32) {
        let target = self.target.as_ref().unwrap();
        let constants = [
            model,
            self.output_format.shader_code(),
            self.filter.shader_code(),
        ];
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("draw"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines[&(DRAW, constants)]);
        pass.set_bind_group(0, self.draw_group.as_ref().unwrap(), &[]);
        let (w, h) = (target.layout.width, target.layout.height);
        pass.dispatch_workgroups(groups(w.div_ceil(BLOCK_W)), groups(h.div_ceil(BLOCK_H)), 1);
        let mixed = self.mixed_blocks();
        if mixed > 0 {
            pass.set_pipeline(&self.pipelines[&(DRAW_MIXED, constants)]);
            pass.dispatch_workgroups(mixed.div_ceil(MIXED_WORKGROUP), 1, 1);
        }
    }

    fn encode_readback(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        let target = self.target.as_ref().unwrap();
        encoder.copy_buffer_to_buffer(&target.buffer, 0, &target.readbacks[slot].buffer, 0, None);
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
        self.encode_draw(&mut encoder, model_code(&plan.lens.radial.model));
        self.encode_readback(&mut encoder, slot);
        self.submit(encoder);
        self.next_id += 1;
        let (source, target) = (self.source.as_ref().unwrap(), self.target.as_ref().unwrap());
        source.uploads[slot].request(wgpu::MapMode::Write);
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
        let data = read_out(&frame.readback.buffer, frame.layout.size as usize)?;
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

    /// Renders one frame with each stage submitted and waited for on its own, to time the
    /// stages (slower than [`Renderer::push`], which overlaps them).
    pub fn render_staged(
        &mut self,
        data: &[u8],
        input: &PlaneLayout,
        plan: &FramePlan,
    ) -> Result<(RenderedFrame, StageTimes), GpuError> {
        while self.flush()?.is_some() {}
        let t0 = Instant::now();
        self.prepare(data, input, plan)?;
        let id = self.next_id;
        self.next_id += 1;
        let slot = (id % RING as u64) as usize;
        let device = self.gpu.device.clone();
        let wait = |index| {
            device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(index),
                    timeout: None,
                })
                .map_err(|e| GpuError::Failed(e.to_string()))
        };
        self.fill_upload(slot, data)?;
        let mut encoder = self.encoder();
        self.encode_upload(&mut encoder, slot);
        wait(self.submit(encoder))?;
        self.source.as_ref().unwrap().uploads[slot].request(wgpu::MapMode::Write);
        let t1 = Instant::now();
        let mut encoder = self.encoder();
        self.encode_draw(&mut encoder, model_code(&plan.lens.radial.model));
        wait(self.submit(encoder))?;
        let t2 = Instant::now();
        let mut encoder = self.encoder();
        self.encode_readback(&mut encoder, slot);
        self.submit(encoder);
        let target = self.target.as_ref().unwrap();
        let readback = &target.readbacks[slot];
        readback.request(wgpu::MapMode::Read);
        readback.wait(&device)?;
        let data = read_out(&readback.buffer, target.layout.size as usize)?;
        let t3 = Instant::now();
        let frame = RenderedFrame {
            id,
            layout: target.layout,
            data,
            latency: t3 - t0,
        };
        let times = StageTimes {
            upload: t1 - t0,
            render: t2 - t1,
            readback: t3 - t2,
        };
        Ok((frame, times))
    }
}

fn bind(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

/// Copies a mapped readback buffer's first `len` bytes out and unmaps it.
fn read_out(buffer: &wgpu::Buffer, len: usize) -> Result<Vec<u8>, GpuError> {
    let data = {
        let view = buffer
            .get_mapped_range(..)
            .map_err(|e| GpuError::Failed(e.to_string()))?;
        view[..len].to_vec()
    };
    buffer.unmap();
    Ok(data)
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
