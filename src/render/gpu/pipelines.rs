//! The renderer's compute pipelines: the bind group layouts of the three passes, and the
//! pipelines built with the override constants that force a rebuild (input and output format,
//! filter, lens model, the view kinds a frame has), cached by a [`PipelineKey`] of them.
//!
//! The draw pipelines leave out the code of view kinds a frame lacks. A frame with new kinds
//! never waits for a build: generic pipelines (all kinds), made with the first frame, draw it
//! while the specialised ones are built on another thread ([`Pipelines::draw`]).

use super::{Gpu, GpuError, shaders};
use crate::frame::PixelFormat;
use crate::lens::Lens;
use crate::plan::Filter;
use std::collections::HashMap;
use std::sync::mpsc;

/// Invocations in a workgroup of the ingest, mip and draw passes, across and down.
pub(super) const WORKGROUP: u32 = 8;
/// Invocations in a `draw_mixed` workgroup, one block each.
pub(super) const MIXED_WORKGROUP: u32 = 64;
/// The VIEW_KINDS of the generic draw pipelines, which draw every kind (a bit per `KIND_*`)
/// and correct a rolling shutter (`SHUTTER_BIT`) when the frame has one.
const ALL_KINDS: u32 = 0x1f;

/// What the draw pipelines are built for: every override constant of shaders/render.wgsl.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct DrawKey {
    /// `Lens::shader_model`: the model's code, and whether the lens is a pair.
    pub lens_model: u32,
    pub output: PixelFormat,
    pub filter: Filter,
    /// As the frame lies in the upload buffers (RGBA or NV12).
    pub input: PixelFormat,
    /// A bit per view kind (`KIND_*`) the frame has.
    pub view_kinds: u32,
}

impl DrawKey {
    /// The pipelines that draw every view kind.
    pub fn generic(self) -> DrawKey {
        DrawKey {
            view_kinds: ALL_KINDS,
            ..self
        }
    }
}

/// A pipeline: its pass and the override constants it is built with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum PipelineKey {
    /// Levels 1 and 2 of a frame that lies in the upload buffers as `input`.
    Ingest { input: PixelFormat },
    /// One more level from the one before.
    Mip,
    /// The draw pass over blocks that lie in one view.
    Draw(DrawKey),
    /// The draw pass over blocks that straddle views, pixel by pixel.
    DrawMixed(DrawKey),
}

impl PipelineKey {
    fn entry_point(self) -> &'static str {
        match self {
            PipelineKey::Ingest { .. } => "ingest",
            PipelineKey::Mip => "downsample",
            PipelineKey::Draw(_) => "draw",
            PipelineKey::DrawMixed(_) => "draw_mixed",
        }
    }

    /// Its override constants, by name.
    fn constants(self) -> Vec<(&'static str, f64)> {
        let code = |v: u32| v as f64;
        match self {
            PipelineKey::Ingest { input } => vec![("INPUT_FORMAT", code(input.shader_code()))],
            PipelineKey::Mip => vec![],
            PipelineKey::Draw(k) | PipelineKey::DrawMixed(k) => vec![
                ("LENS_MODEL", code(k.lens_model)),
                ("OUTPUT_FORMAT", code(k.output.shader_code())),
                ("FILTER", code(k.filter.shader_code())),
                ("INPUT_FORMAT", code(k.input.shader_code())),
                ("VIEW_KINDS", code(k.view_kinds)),
            ],
        }
    }
}

/// The bind group layouts of the passes.
pub(super) struct Layouts {
    pub ingest: wgpu::BindGroupLayout,
    pub mip: wgpu::BindGroupLayout,
    pub draw: wgpu::BindGroupLayout,
}

impl Layouts {
    fn new(device: &wgpu::Device) -> Layouts {
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let sampler = wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering);
        Layouts {
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
                    entry(3, sampler),
                    entry(4, storage(false)),
                    entry(5, storage(true)),
                    entry(6, sampled_texture()),
                ],
            ),
        }
    }
}

pub(super) fn entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty,
        count: None,
    }
}

pub(super) fn uniform() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

pub(super) fn storage(read_only: bool) -> wgpu::BindingType {
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

/// A bind group entry.
pub(super) fn bind(binding: u32, resource: wgpu::BindingResource<'_>) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource }
}

/// Workgroups of [`WORKGROUP`] invocations that cover `n`.
pub(super) fn groups(n: u32) -> u32 {
    n.div_ceil(WORKGROUP)
}

/// What building one pipeline needs (all cheap clones of device objects), so another thread
/// can do it.
struct Builder {
    device: wgpu::Device,
    module: wgpu::ShaderModule,
    bindings: wgpu::BindGroupLayout,
    key: PipelineKey,
}

impl Builder {
    fn build(&self) -> Result<wgpu::ComputePipeline, GpuError> {
        let device = &self.device;
        let name = self.key.entry_point();
        let constants = self.key.constants();
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &[Some(&self.bindings)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&layout),
            module: &self.module,
            entry_point: Some(name),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(GpuError::Failed(format!(
                "building the {name} pipeline: {e}"
            ))),
            None => Ok(pipeline),
        }
    }
}

type DrawPair = Result<[wgpu::ComputePipeline; 2], GpuError>;

/// Every pipeline built so far, and the draw pipelines being built on another thread.
pub(super) struct Pipelines {
    device: wgpu::Device,
    pub layouts: Layouts,
    /// The ingest, mip and render modules.
    modules: [wgpu::ShaderModule; 3],
    built: HashMap<PipelineKey, wgpu::ComputePipeline>,
    /// Specialised draw pipelines being built on another thread: their key, and where the
    /// pair arrives.
    building: Option<(DrawKey, mpsc::Receiver<DrawPair>)>,
    /// See `Renderer::build_in_background`.
    pub build_in_background: bool,
    /// Whether a frame's view kinds may differ from the last one's (see
    /// `Renderer::fixed_view_kinds`).
    pub kinds_change: bool,
    /// Generic draw pipelines just built, to be dispatched once with the next frame so a
    /// device that compiles at dispatch has them compiled before they are needed.
    warm_up: Vec<DrawKey>,
    /// Lens models (`Model::code`) whose generic draw pipelines the first frame also makes.
    expected_models: Vec<u32>,
}

impl Pipelines {
    pub fn new(gpu: &Gpu) -> Pipelines {
        let device = &gpu.device;
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
        Pipelines {
            device: device.clone(),
            layouts: Layouts::new(device),
            modules,
            built: HashMap::new(),
            building: None,
            build_in_background: !gpu.is_software(),
            kinds_change: true,
            warm_up: Vec::new(),
            expected_models: Vec::new(),
        }
    }

    /// How many pipelines are built.
    pub fn len(&self) -> usize {
        self.built.len()
    }

    /// A pipeline made by [`Pipelines::ensure`].
    pub fn get(&self, key: PipelineKey) -> &wgpu::ComputePipeline {
        &self.built[&key]
    }

    /// Builds the pipeline of `key` unless it is built.
    pub fn ensure(&mut self, key: PipelineKey) -> Result<(), GpuError> {
        if !self.built.contains_key(&key) {
            let pipeline = self.builder(key).build()?;
            self.built.insert(key, pipeline);
        }
        Ok(())
    }

    /// The pair of draw pipelines (`draw`, `draw_mixed`) of `key`.
    fn draw_pair(&mut self, key: DrawKey) -> Result<(), GpuError> {
        self.ensure(PipelineKey::Draw(key))?;
        self.ensure(PipelineKey::DrawMixed(key))
    }

    fn builder(&self, key: PipelineKey) -> Builder {
        let (module, bindings) = match key {
            PipelineKey::Ingest { .. } => (0, &self.layouts.ingest),
            PipelineKey::Mip => (1, &self.layouts.mip),
            PipelineKey::Draw(_) | PipelineKey::DrawMixed(_) => (2, &self.layouts.draw),
        };
        Builder {
            device: self.device.clone(),
            module: self.modules[module].clone(),
            bindings: bindings.clone(),
            key,
        }
    }

    /// The draw pipelines a frame of `wanted` is drawn with. The first frame builds the
    /// pipelines specialised for its view kinds and (unless the kinds are fixed) the generic
    /// ones, which draw any kinds, and dispatches both (and the generic ones of the lens
    /// models named by `expect_lens_models`). A later frame whose kinds are new, or whose lens
    /// model or format is, is drawn at once by the generic ones (built first for a model not
    /// named or a new format); the specialised ones are built on another thread and used from
    /// the frame after they are ready. Software rasterizers compile a pipeline when it is
    /// first dispatched, on the queue's one thread, so there the frame stream would wait
    /// anyway (1.2 s on lavapipe with a cold shader cache): they keep drawing with the
    /// generic ones. An output's first frame (`new_output`: a view's stream that starts)
    /// waits for its specialised pair, as the very first frame does.
    pub fn draw(&mut self, wanted: DrawKey, new_output: bool) -> Result<DrawKey, GpuError> {
        self.collect_built(false);
        if self.built.contains_key(&PipelineKey::Draw(wanted)) {
            return Ok(wanted);
        }
        let generic = wanted.generic();
        let first = !self.built.keys().any(|k| matches!(k, PipelineKey::Draw(_)));
        if new_output && !first {
            self.draw_pair(wanted)?;
            return Ok(wanted);
        }
        if !self.kinds_change || first {
            self.draw_pair(wanted)?;
            if self.kinds_change {
                // This frame's lens model, then the others the stream may switch to.
                let others = self.expected_models.iter().copied();
                let models = std::iter::once(wanted.lens_model)
                    .chain(others.filter(|&m| m != wanted.lens_model));
                for lens_model in models.collect::<Vec<_>>() {
                    let generic = DrawKey {
                        lens_model,
                        ..generic
                    };
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
            let builders = [
                self.builder(PipelineKey::Draw(wanted)),
                self.builder(PipelineKey::DrawMixed(wanted)),
            ];
            let (done, built) = mpsc::channel();
            std::thread::spawn(move || {
                let [draw, mixed] = builders;
                let pair = draw.build().and_then(|d| Ok([d, mixed.build()?]));
                // The renderer may be gone; then nobody needs the pipelines.
                let _ = done.send(pair);
            });
            self.building = Some((wanted, built));
        }
        Ok(generic)
    }

    /// Keeps the specialised draw pipelines built on another thread once they are ready
    /// (`wait`: waiting until they are).
    pub fn collect_built(&mut self, wait: bool) {
        let Some((key, built)) = self.building.take() else {
            return;
        };
        let result = if wait {
            built.recv().ok()
        } else {
            match built.try_recv() {
                Err(mpsc::TryRecvError::Empty) => {
                    self.building = Some((key, built));
                    return;
                }
                result => result.ok(),
            }
        };
        match result {
            Some(Ok([draw, mixed])) => {
                self.built.insert(PipelineKey::Draw(key), draw);
                self.built.insert(PipelineKey::DrawMixed(key), mixed);
            }
            // The generic pipelines go on drawing; building is not tried again.
            Some(Err(e)) => {
                tracing::warn!("drawing with generic pipelines: {e}");
                self.build_in_background = false;
            }
            None => self.build_in_background = false,
        }
    }

    /// See `Renderer::expect_lenses`.
    pub fn expect_lenses<'a>(&mut self, lenses: impl IntoIterator<Item = &'a Lens>) {
        self.expected_models.clear();
        for code in lenses.into_iter().map(Lens::shader_model) {
            if !self.expected_models.contains(&code) {
                self.expected_models.push(code);
            }
        }
    }

    /// The generic draw pipelines to dispatch once with the next frame (and forget).
    pub fn take_warm_up(&mut self) -> Vec<DrawKey> {
        std::mem::take(&mut self.warm_up)
    }
}
