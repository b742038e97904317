//! The GPU renderer proper: resources made once per input and output layout, pipelines cached
//! by what forces a rebuild (input format, lens model, output format, filter), and per frame
//! only the small parameter and view buffers rewritten.
//!
//! A frame's path: its bytes are copied into a mapped upload buffer (one of a ring, so the
//! copy never waits for a fresh allocation; rows padded as texture copies need, and I420's
//! chroma woven into NV12's pairs). Each plane's level 0 (RGBA, or the luma and the chroma
//! pairs, `planes`) is copied from there into its texture over the lens's imaged box. For the
//! mip filter, the ingest pass reads the frame (in the upload buffer itself where the device
//! shares host memory, else in a copy of it) and writes every plane's levels 1 and 2 into a
//! level buffer, the mip passes the rest, and those levels are copied into the textures; on a
//! software rasterizer the host makes the same levels instead, into the upload buffer after
//! the frame (`SourcePlanes::make_levels`). The draw pass writes the output frame (RGBA, I420
//! or NV12) into a storage buffer, which is copied into a readback buffer of the ring. The
//! draw pass is two dispatches: blocks inside one view, then the few that straddle an edge
//! (the block map, rebuilt when the rectangles change). [`Renderer::push`] hands back frame
//! N-1 while frame N renders.
//!
//! The draw pipelines leave out the code of view kinds a frame lacks. A frame with new kinds
//! never waits for a build: generic pipelines, made with the first frame, draw it
//! (`draw_pipelines`).

use super::blocks::{BLOCK_H, BLOCK_W, BlockMap};
use super::params::{GpuParams, GpuView, MAX_VIEWS, frame_params};
use super::planes::{
    COPY_ALIGN, INGEST_BLOCK, PlaneSpec, SourcePlanes, copy_for_upload, upload_layout,
};
use super::shaders;
use super::{Gpu, GpuError};
use crate::frame::yuv;
use crate::frame::{PixelFormat, PlaneLayout};
use crate::lens::Model;
use crate::render::mip::{Filter, ImagedBox, levels_for};
use crate::render::plan::FramePlan;
use image::RgbImage;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

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

/// One plane of the source on the GPU: its texture (all levels); `Source::specs` says where
/// its levels from 1 on lie in the level buffer.
struct Plane {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
}

/// One mip pass: its bind group and dispatch size (words across, rows).
type MipStep = (wgpu::BindGroup, (u32, u32));

/// What depends on the input layout: upload ring, raw buffer, level buffer, the planes.
struct Source {
    layout: PlaneLayout,
    /// The layout in the upload buffers: `layout` with rows padded for texture copies.
    padded: PlaneLayout,
    /// The input pixels the GPU takes in (`Lens::imaged_box`).
    imaged: ImagedBox,
    levels: u32,
    uploads: Vec<MapSlot>,
    /// The frame's bytes where the ingest reads them: a copy of the upload buffer, or none
    /// where the device reads the upload buffers themselves (`Gpu::shared_memory`) or no
    /// pass makes levels.
    raw: Option<wgpu::Buffer>,
    /// Every plane's levels from 1 on, packed (`planes::SourcePlanes`), where the passes
    /// make them.
    level_buffer: Option<wgpu::Buffer>,
    /// Where levels made on the host (`Renderer::make_levels_on_host`) lie in each upload
    /// buffer, after the frame, and the host's copy they are made in.
    host_levels: Option<(u64, Vec<u8>)>,
    /// Every plane's size, levels and level regions, in the order of `planes`.
    specs: SourcePlanes,
    planes: Vec<Plane>,
    /// The ingest's bindings: one, or one per upload buffer where it reads them.
    ingest: Vec<wgpu::BindGroup>,
    mips: Vec<MipStep>,
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

type DrawBuild = (
    [u32; 5],
    mpsc::Receiver<Result<[wgpu::ComputePipeline; 2], GpuError>>,
);

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
    pipelines: HashMap<(usize, [u32; 5]), wgpu::ComputePipeline>,
    source: Option<Source>,
    target: Option<Target>,
    draw_group: Option<wgpu::BindGroup>,
    /// The block map of the last frame's rectangles and the buffer holding it.
    blocks: Option<(BlockMap, wgpu::Buffer)>,
    /// The override constants of the draw pipelines drawing the frame last prepared, and that
    /// frame's own view kinds (`DRAW_KINDS`; they differ while it is drawn generically).
    draw_constants: [u32; 5],
    frame_kinds: u32,
    /// Specialised draw pipelines being built on another thread: their constants, and where
    /// the pair arrives.
    building: Option<DrawBuild>,
    /// See [`Renderer::build_in_background`].
    build_in_background: bool,
    /// See [`Renderer::make_levels_on_host`].
    levels_on_host: bool,
    /// Whether a frame's view kinds may differ from the last one's (see
    /// [`Renderer::fixed_view_kinds`]).
    kinds_change: bool,
    /// Generic draw pipelines just built, to be dispatched once with the next frame so a
    /// device that compiles at dispatch has them compiled before they are needed.
    warm_up: Vec<[u32; 5]>,
    /// Lens models (`Model::code`) whose generic draw pipelines the first frame also makes
    /// (see [`Renderer::expect_lens_models`]).
    expected_models: Vec<u32>,
    next_id: u64,
    in_flight: VecDeque<InFlight>,
}

/// What building one pass's pipeline needs (all cheap clones of device objects).
struct Builder {
    device: wgpu::Device,
    module: wgpu::ShaderModule,
    bindings: wgpu::BindGroupLayout,
}

/// Pass `pass`'s pipeline with override constants `constants` (named per pass below).
fn build_pipeline(
    builder: &Builder,
    pass: usize,
    constants: [u32; 5],
) -> Result<wgpu::ComputePipeline, GpuError> {
    let device = &builder.device;
    let names: &[&str] = match pass {
        INGEST => &["INPUT_FORMAT"],
        MIP => &[],
        _ => &[
            "LENS_MODEL",
            "OUTPUT_FORMAT",
            "FILTER",
            "INPUT_FORMAT",
            "VIEW_KINDS",
        ],
    };
    let values: Vec<(&str, f64)> = names
        .iter()
        .zip(constants)
        .map(|(n, v)| (*n, v as f64))
        .collect();
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(ENTRY_POINTS[pass]),
        bind_group_layouts: &[Some(&builder.bindings)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(ENTRY_POINTS[pass]),
        layout: Some(&layout),
        module: &builder.module,
        entry_point: Some(ENTRY_POINTS[pass]),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: &values,
            zero_initialize_workgroup_memory: false,
        },
        cache: None,
    });
    match pollster::block_on(scope.pop()) {
        Some(e) => Err(GpuError::Failed(format!(
            "building the {} pipeline: {e}",
            ENTRY_POINTS[pass]
        ))),
        None => Ok(pipeline),
    }
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
/// The draw pipelines' VIEW_KINDS constant (a bit per view kind the frame has), and its
/// value for the generic pipelines, which draw every kind.
const DRAW_KINDS: usize = 4;
const ALL_KINDS: u32 = 0xf;
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
                    entry(2, storage(false)),
                    entry(3, uniform()),
                ],
            ),
            mip: layout(
                "mip bindings",
                &[entry(0, storage(false)), entry(1, uniform())],
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
                    entry(6, sampled_texture()),
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
        // Bilinear filtering samples level 0 alone: a sampler and views (`ensure_source`) that
        // say so let a software rasterizer leave out the per-pixel choice of levels.
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
            layouts,
            modules,
            pipelines: HashMap::new(),
            source: None,
            target: None,
            draw_group: None,
            blocks: None,
            draw_constants: [0; 5],
            frame_kinds: 0,
            building: None,
            build_in_background: !gpu.is_software(),
            levels_on_host: gpu.is_software(),
            kinds_change: true,
            warm_up: Vec::new(),
            expected_models: Vec::new(),
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

    fn pipeline(&mut self, pass: usize, constants: [u32; 5]) -> Result<(), GpuError> {
        if !self.pipelines.contains_key(&(pass, constants)) {
            let pipeline = build_pipeline(&self.builder(pass), pass, constants)?;
            self.pipelines.insert((pass, constants), pipeline);
        }
        Ok(())
    }

    /// The pair of draw pipelines (`draw`, `draw_mixed`) with override constants `constants`.
    fn draw_pair(&mut self, constants: [u32; 5]) -> Result<(), GpuError> {
        self.pipeline(DRAW, constants)?;
        self.pipeline(DRAW_MIXED, constants)
    }

    /// What building a pass's pipeline takes, cloned so another thread can do it.
    fn builder(&self, pass: usize) -> Builder {
        Builder {
            device: self.gpu.device.clone(),
            module: self.modules[pass.min(DRAW)].clone(),
            bindings: match pass {
                INGEST => self.layouts.ingest.clone(),
                MIP => self.layouts.mip.clone(),
                _ => self.layouts.draw.clone(),
            },
        }
    }

    /// The draw pipelines a frame of view kinds `wanted` (draw override constants) is drawn
    /// with. The renderer's first frame builds the pipelines specialised for its kinds and
    /// (unless the kinds are fixed, `fixed_view_kinds`) the generic ones, which draw any
    /// kinds, and dispatches both (and the generic ones of the lens models named by
    /// `expect_lens_models`). A later frame whose kinds are new, or whose lens model or
    /// format is, is drawn at once by the generic ones (built first for a model not named or
    /// a new format); the specialised ones are built on another thread and used from the frame
    /// after they are ready. Software rasterizers compile a pipeline when it is first
    /// dispatched, on the queue's one thread, so there the frame stream would wait anyway
    /// (1.2 s on lavapipe with a cold shader cache): they keep drawing with the generic ones.
    fn draw_pipelines(&mut self, wanted: [u32; 5]) -> Result<[u32; 5], GpuError> {
        self.collect_built(false);
        if self.pipelines.contains_key(&(DRAW, wanted)) {
            return Ok(wanted);
        }
        let mut generic = wanted;
        generic[DRAW_KINDS] = ALL_KINDS;
        let first = !self.pipelines.keys().any(|&(pass, _)| pass == DRAW);
        if !self.kinds_change || first {
            self.draw_pair(wanted)?;
            if self.kinds_change {
                // This frame's lens model, then the others the stream may switch to.
                let models = std::iter::once(wanted[0]).chain(
                    self.expected_models
                        .iter()
                        .copied()
                        .filter(|&m| m != wanted[0]),
                );
                for model in models.collect::<Vec<_>>() {
                    let mut generic = generic;
                    generic[0] = model;
                    self.draw_pair(generic)?;
                    self.warm_up.push(generic);
                }
            }
            return Ok(wanted);
        }
        // A new lens model or format while frames flow: the generic pair alone is built
        // (and compiled as it draws this frame), halving the wait.
        self.draw_pair(generic)?;
        if self.build_in_background && self.building.is_none() && wanted != generic {
            let builders = [self.builder(DRAW), self.builder(DRAW_MIXED)];
            let (done, built) = mpsc::channel();
            std::thread::spawn(move || {
                let [draw, mixed] = builders;
                let pair = build_pipeline(&draw, DRAW, wanted)
                    .and_then(|d| Ok([d, build_pipeline(&mixed, DRAW_MIXED, wanted)?]));
                // The renderer may be gone; then nobody needs the pipelines.
                let _ = done.send(pair);
            });
            self.building = Some((wanted, built));
        }
        Ok(generic)
    }

    /// Keeps the specialised draw pipelines built on another thread once they are ready
    /// (`wait`: waiting until they are).
    fn collect_built(&mut self, wait: bool) {
        let Some((constants, built)) = self.building.take() else {
            return;
        };
        let result = if wait {
            built.recv().ok()
        } else {
            match built.try_recv() {
                Err(mpsc::TryRecvError::Empty) => {
                    self.building = Some((constants, built));
                    return;
                }
                result => result.ok(),
            }
        };
        match result {
            Some(Ok([draw, mixed])) => {
                self.pipelines.insert((DRAW, constants), draw);
                self.pipelines.insert((DRAW_MIXED, constants), mixed);
            }
            // The generic pipelines go on drawing; building is not tried again.
            Some(Err(e)) => {
                tracing::warn!("drawing with generic pipelines: {e}");
                self.build_in_background = false;
            }
            None => self.build_in_background = false,
        }
    }

    /// Names the lens models the frames may switch to later (those of lens.cal, for a live
    /// stream where LENS SET can choose any of them): the first frame then makes and compiles
    /// their generic draw pipelines too, so a switch to one of them is drawn at once instead
    /// of waiting for a compilation (lavapipe: a second or two with a cold shader cache).
    /// Ignored with [`Renderer::fixed_view_kinds`].
    pub fn expect_lens_models<'a>(&mut self, models: impl IntoIterator<Item = &'a Model>) {
        self.expected_models.clear();
        for code in models.into_iter().map(Model::code) {
            if !self.expected_models.contains(&code) {
                self.expected_models.push(code);
            }
        }
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
        self.kinds_change = false;
    }

    /// Whether draw pipelines specialised for a frame's view kinds are built on another thread
    /// when the kinds change (see `draw_pipelines`). On by default where the device compiles
    /// pipelines when they are built (GPUs), off where it compiles them when they are first
    /// dispatched (software rasterizers).
    pub fn build_in_background(&mut self, on: bool) {
        self.build_in_background = on;
    }

    /// Whether the mip filter's levels are made on the host, as the frame is copied into its
    /// upload buffer ([`SourcePlanes::make_levels`]), rather than by the ingest and mip passes.
    /// The same bytes either way. On by default for software rasterizers, where a pass is CPU
    /// work too and the passes' storage-buffer loads are checked and branched on lane by
    /// lane: on lavapipe the passes take several times what the host's vectorised loop does.
    pub fn make_levels_on_host(&mut self, on: bool) {
        if on != self.levels_on_host {
            self.levels_on_host = on;
            self.source = None;
            self.draw_group = None;
        }
    }

    /// Whether the ingest and mip passes make the mip filter's levels (not the host, and not
    /// the bilinear filter, which needs none).
    fn level_passes(&self) -> bool {
        self.filter == Filter::Mip && !self.levels_on_host
    }

    /// Waits until the draw pipelines being built on another thread, if any, are ready.
    pub fn wait_for_builds(&mut self) {
        self.collect_built(true);
    }

    /// Whether the last frame prepared was drawn by pipelines specialised for its view kinds
    /// (else by the generic ones, while the specialised ones are built or on a software
    /// rasterizer).
    pub fn drew_specialised(&self) -> bool {
        self.draw_constants[DRAW_KINDS] == self.frame_kinds
    }

    /// Makes the input-side resources match `layout` and the lens's imaged box (kept while
    /// neither changes; everything starts black, and nothing outside the box is written).
    fn ensure_source(&mut self, layout: &PlaneLayout, imaged: ImagedBox) -> Result<(), GpuError> {
        if self
            .source
            .as_ref()
            .is_some_and(|s| s.layout == *layout && s.imaged == imaged)
        {
            return Ok(());
        }
        let device = &self.gpu.device;
        let padded = upload_layout(layout);
        let specs = SourcePlanes::new(padded.format, layout.width, layout.height);
        // The ingest may read a word past the last row's end.
        let frame_size = (padded.size as u64 + 16).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let passes = self.level_passes();
        let host_levels = (self.filter == Filter::Mip && self.levels_on_host)
            .then(|| frame_size.next_multiple_of(COPY_ALIGN as u64));
        let size = match host_levels {
            Some(at) => at + specs.buffer_size as u64,
            None => frame_size,
        };
        let shared = self.gpu.shared_memory;
        let read = if shared && passes {
            wgpu::BufferUsages::STORAGE
        } else {
            wgpu::BufferUsages::empty()
        };
        let uploads: Vec<MapSlot> = (0..RING)
            .map(|i| {
                MapSlot::new(
                    device,
                    &format!("upload {i}"),
                    size,
                    wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC | read,
                )
            })
            .collect();
        // Levels made on the host start black around the imaged box, as the level buffer
        // does; only the box is written after.
        let host_levels = host_levels.map(|at| (at, specs.black_levels()));
        let raw = (!shared && passes).then(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raw input"),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
        let level_buffer = passes.then(|| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("source levels"),
                contents: &specs.black_levels(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
        });
        let planes: Vec<Plane> = specs
            .planes
            .iter()
            .map(|spec| {
                let texture = device.create_texture(&wgpu::TextureDescriptor {
                    label: Some("source plane"),
                    size: wgpu::Extent3d {
                        width: spec.width,
                        height: spec.height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: spec.levels,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: match spec.channels {
                        1 => wgpu::TextureFormat::R8Unorm,
                        2 => wgpu::TextureFormat::Rg8Unorm,
                        _ => wgpu::TextureFormat::Rgba8Unorm,
                    },
                    usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                    view_formats: &[],
                });
                // Level 0 is copied over the imaged box only: black around it.
                fill_level0(&self.gpu.queue, &texture, spec);
                Plane {
                    view: texture.create_view(&wgpu::TextureViewDescriptor {
                        mip_level_count: (self.filter == Filter::Bilinear).then_some(1),
                        ..Default::default()
                    }),
                    texture,
                }
            })
            .collect();
        let (ingest, mips) = match &level_buffer {
            Some(levels) => {
                let inputs = match &raw {
                    Some(raw) => vec![raw],
                    None => uploads.iter().map(|u| &u.buffer).collect(),
                };
                self.level_pass_groups(levels, inputs, &specs, &imaged)
            }
            None => (Vec::new(), Vec::new()),
        };
        self.source = Some(Source {
            layout: *layout,
            padded,
            imaged,
            levels: levels_for(layout.width, layout.height),
            uploads,
            raw,
            level_buffer,
            host_levels,
            specs,
            planes,
            ingest,
            mips,
        });
        self.draw_group = None;
        Ok(())
    }

    /// The ingest and mip passes' bind groups, writing levels into `levels`: an ingest group
    /// per buffer in `inputs` (the frame's bytes: the upload buffers read in place, or their
    /// copy), and the mip steps with their dispatch sizes (words across, rows).
    fn level_pass_groups(
        &self,
        levels: &wgpu::Buffer,
        inputs: Vec<&wgpu::Buffer>,
        specs: &SourcePlanes,
        imaged: &ImagedBox,
    ) -> (Vec<wgpu::BindGroup>, Vec<MipStep>) {
        let device = &self.gpu.device;
        let uniform_init = |label, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let region = |p: usize, k: usize| {
            specs
                .planes
                .get(p)
                .and_then(|s| s.regions.get(k))
                .copied()
                .unwrap_or_default()
        };
        let regions = [region(0, 0), region(0, 1), region(1, 0)];
        let mut targets = bytemuck::cast_slice(&regions).to_vec();
        let (columns, rows) = imaged;
        let bounds = [columns.start, rows.start, columns.end, rows.end];
        targets.extend_from_slice(bytemuck::cast_slice(&bounds));
        let targets = uniform_init("ingest targets", &targets);
        let ingest = inputs
            .into_iter()
            .map(|input| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("ingest"),
                    layout: &self.layouts.ingest,
                    entries: &[
                        bind(0, self.params.as_entire_binding()),
                        bind(1, input.as_entire_binding()),
                        bind(2, levels.as_entire_binding()),
                        bind(3, targets.as_entire_binding()),
                    ],
                })
            })
            .collect();
        let mips = specs
            .mip_steps()
            .into_iter()
            .map(|(p, k)| {
                // Regions are indexed from level 1.
                let (finer, coarser) = (region(p, k - 1), region(p, k));
                let channels = specs.planes[p].channels;
                let mut step = bytemuck::bytes_of(&[finer, coarser]).to_vec();
                step.extend_from_slice(bytemuck::bytes_of(&[channels, 0, 0, 0]));
                let step = uniform_init("mip step", &step);
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("mip"),
                    layout: &self.layouts.mip,
                    entries: &[
                        bind(0, levels.as_entire_binding()),
                        bind(1, step.as_entire_binding()),
                    ],
                });
                (
                    group,
                    ((coarser.width * channels).div_ceil(4), coarser.height),
                )
            })
            .collect();
        (ingest, mips)
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
        // RGBA has one plane: bound twice, the second never sampled.
        let plane = |i: usize| {
            let p = &source.planes[i.min(source.planes.len() - 1)];
            wgpu::BindingResource::TextureView(&p.view)
        };
        self.draw_group = Some(
            self.gpu
                .device
                .create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("draw"),
                    layout: &self.layouts.draw,
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
        self.ensure_source(input, plan.lens.imaged_box())?;
        // Frames arrive in the upload buffers as RGBA or NV12 (I420 woven on the way).
        let upload = self.source.as_ref().unwrap().padded.format;
        if self.level_passes() {
            self.pipeline(INGEST, ingest_constants(upload))?;
            self.pipeline(MIP, [0; 5])?;
        }
        self.ensure_target(plan.layout.width, plan.layout.height)?;
        self.ensure_blocks(plan);
        self.ensure_draw_group();
        let source = self.source.as_ref().unwrap();
        let target = self.target.as_ref().unwrap();
        let mixed = self.mixed_blocks();
        let (params, views) =
            frame_params(plan, &source.padded, &target.layout, source.levels, mixed)?;
        // The draw pipeline leaves out the code of view kinds the frame lacks.
        let kinds = views.iter().fold(0, |kinds, v| kinds | 1 << v.kind[0]);
        let draw = [
            plan.lens.radial.model.code(),
            self.output_format.shader_code(),
            self.filter.shader_code(),
            upload.shader_code(),
            kinds,
        ];
        self.draw_constants = self.draw_pipelines(draw)?;
        self.frame_kinds = kinds;
        let queue = &self.gpu.queue;
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if !views.is_empty() {
            queue.write_buffer(&self.views, 0, bytemuck::cast_slice(&views));
        }
        Ok(())
    }

    /// Copies the frame's bytes into upload buffer `slot` (waiting until it is free), rows
    /// padded as the source's upload layout says, and, where the host makes the mip levels
    /// (`Source::host_levels`), the frame's levels after it.
    fn fill_upload(&mut self, slot: usize, data: &[u8]) -> Result<(), GpuError> {
        let source = self.source.as_mut().unwrap();
        let upload = &source.uploads[slot];
        upload.wait(&self.gpu.device)?;
        {
            let mut view = upload
                .buffer
                .get_mapped_range_mut(..)
                .map_err(|e| GpuError::Failed(e.to_string()))?;
            copy_for_upload(data, &source.layout, &source.padded, |at, bytes| {
                view.slice(at..at + bytes.len()).copy_from_slice(bytes)
            });
            if let Some((at, levels)) = &mut source.host_levels {
                let specs = &source.specs;
                specs.make_levels(data, &source.layout, &source.imaged, levels);
                let at = *at as usize;
                view.slice(at..at + levels.len()).copy_from_slice(levels);
            }
        }
        upload.buffer.unmap();
        Ok(())
    }

    fn encode_upload(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        let source = self.source.as_ref().unwrap();
        let upload = &source.uploads[slot].buffer;
        // The ingest reads the frame's bytes, where it reads a copy.
        if let Some(raw) = &source.raw {
            encoder.copy_buffer_to_buffer(upload, 0, raw, 0, None);
        }
        // Level 0 of every plane over the imaged box, straight from the upload buffer.
        let (columns, rows) = &source.imaged;
        let padded = &source.padded;
        for (i, (plane, spec)) in source.planes.iter().zip(&source.specs.planes).enumerate() {
            // Chroma planes are half size, starting at their plane's offset.
            let (scale, start, stride) = match i {
                0 => (1, 0, padded.stride),
                _ => (2, padded.chroma[i - 1], padded.chroma_stride),
            };
            let (x, y) = (columns.start / scale, rows.start / scale);
            let texel = spec.channels;
            encoder.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: upload,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: (start + y * stride + x * texel) as u64,
                        bytes_per_row: Some(stride),
                        rows_per_image: None,
                    },
                },
                texture_level(&plane.texture, 0, (x, y)),
                extent(columns.len() as u32 / scale, rows.len() as u32 / scale),
            );
        }
        // Bilinear filtering samples level 0 alone: no chain to make.
        if self.filter != Filter::Mip {
            return;
        }
        // Levels from 1 on: from the upload buffer, where made on the host, else from the
        // level buffer once the passes have made them.
        let (levels, base) = match (&source.host_levels, &source.level_buffer) {
            (Some((at, _)), _) => (upload, *at),
            (None, Some(level_buffer)) => {
                self.encode_level_passes(encoder, slot);
                (level_buffer, 0)
            }
            (None, None) => unreachable!("the mip filter has its levels made somewhere"),
        };
        for (plane, spec) in source.planes.iter().zip(&source.specs.planes) {
            for (k, r) in spec.regions.iter().enumerate() {
                encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: levels,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: base + r.offset as u64,
                            bytes_per_row: Some(r.stride),
                            rows_per_image: None,
                        },
                    },
                    texture_level(&plane.texture, k as u32 + 1, (0, 0)),
                    extent(r.width, r.height),
                );
            }
        }
    }

    /// The ingest and mip passes, writing every plane's levels from 1 on into the level
    /// buffer.
    fn encode_level_passes(&self, encoder: &mut wgpu::CommandEncoder, slot: usize) {
        let source = self.source.as_ref().unwrap();
        let (columns, rows) = &source.imaged;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("ingest and mip chain"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines[&(INGEST, ingest_constants(source.padded.format))]);
        pass.set_bind_group(0, &source.ingest[slot.min(source.ingest.len() - 1)], &[]);
        pass.dispatch_workgroups(
            groups(columns.len().div_ceil(INGEST_BLOCK.0 as usize) as u32),
            groups(rows.len().div_ceil(INGEST_BLOCK.1 as usize) as u32),
            1,
        );
        pass.set_pipeline(&self.pipelines[&(MIP, [0; 5])]);
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

    fn encode_draw(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let warm_up = std::mem::take(&mut self.warm_up);
        let target = self.target.as_ref().unwrap();
        let constants = self.draw_constants;
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
            for pipeline in [DRAW, DRAW_MIXED] {
                pass.set_pipeline(&self.pipelines[&(pipeline, generic)]);
                pass.dispatch_workgroups(1, 1, 1);
            }
        }
        pass.set_pipeline(&self.pipelines[&(DRAW, constants)]);
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
        self.encode_draw(&mut encoder);
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
        self.encode_draw(&mut encoder);
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

/// The ingest pipeline's override constants for frames that are `upload` in the upload
/// buffers (RGBA or NV12).
fn ingest_constants(upload: PixelFormat) -> [u32; 5] {
    [upload.shader_code(), 0, 0, 0, 0]
}

/// Fills level 0 of a fresh plane texture with the plane's black (fresh textures are zero,
/// which is black only for RGBA).
fn fill_level0(queue: &wgpu::Queue, texture: &wgpu::Texture, spec: &PlaneSpec) {
    if spec.black == 0 {
        return;
    }
    let row = spec.width * spec.channels;
    queue.write_texture(
        texture_level(texture, 0, (0, 0)),
        &vec![spec.black; (row * spec.height) as usize],
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(row),
            rows_per_image: None,
        },
        extent(spec.width, spec.height),
    );
}

fn texture_level(
    texture: &wgpu::Texture,
    level: u32,
    (x, y): (u32, u32),
) -> wgpu::TexelCopyTextureInfo<'_> {
    wgpu::TexelCopyTextureInfo {
        texture,
        mip_level: level,
        origin: wgpu::Origin3d { x, y, z: 0 },
        aspect: wgpu::TextureAspect::All,
    }
}

fn extent(width: u32, height: u32) -> wgpu::Extent3d {
    wgpu::Extent3d {
        width,
        height,
        depth_or_array_layers: 1,
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
