//! The thermal layer on the GPU (shaders/layer.wgsl): after the draw pass, the thermal frame is
//! coloured (`thermal`) and drawn over the output buffer in place, as
//! `ThermalLayer::draw_rgb` does on the CPU. Queued on the frame's own command encoder, so
//! the readback that follows sees it; a frame without a layer costs nothing.

use super::params::{GpuLens, GpuView, gpu_lens, projection_params, rays_view};
use super::pipelines::{bind, entry, groups, storage, uniform};
use super::shaders::compose;
use super::thermal::ThermalPass;
use super::{Gpu, GpuError};
use crate::frame::{PixelFormat, PlaneLayout};
use crate::plan::thermal::ThermalLayer;
use bytemuck::{Pod, Zeroable};
use std::collections::HashMap;
use wgpu::util::DeviceExt;

pub const SOURCE: &str = include_str!("../../../shaders/layer.wgsl");

/// The most rectangles one frame's layer covers (four views, each with a picture-in-picture,
/// and room to spare).
pub const MAX_ENTRIES: usize = 16;

/// Twin of `LayerParams` in shaders/layer.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLayerParams {
    pub output: [u32; 4],
    pub output_planes: [u32; 4],
    pub picture: [u32; 4],
    pub lens: GpuLens,
}

/// Twin of `Entry` in shaders/layer.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLayerEntry {
    pub view: GpuView,
    pub share: [f32; 4],
}

/// The layer's parameters and entries for an output frame laid out as `output`.
fn layer_params(
    layer: &ThermalLayer,
    output: &PlaneLayout,
) -> Result<(GpuLayerParams, Vec<GpuLayerEntry>), GpuError> {
    if layer.entries.len() > MAX_ENTRIES {
        return Err(GpuError::Failed(format!(
            "the thermal picture is over {} rectangles, at most {MAX_ENTRIES}",
            layer.entries.len()
        )));
    }
    let mut entries: Vec<GpuLayerEntry> = layer
        .entries
        .iter()
        .map(|e| GpuLayerEntry {
            view: rays_view(
                e.rect,
                projection_params(e.projection, e.thermal_from_view),
                e.black_outside as u32,
            ),
            share: [e.alpha as f32, 0.0, 0.0, 0.0],
        })
        .collect();
    let count = entries.len() as u32;
    entries.resize(MAX_ENTRIES, GpuLayerEntry::zeroed());
    let params = GpuLayerParams {
        output: [output.width, output.height, count, output.stride],
        output_planes: [output.chroma[0], output.chroma[1], output.chroma_stride, 0],
        picture: [layer.frame.width, layer.frame.height, 0, 0],
        lens: gpu_lens(&layer.lens)?,
    };
    Ok((params, entries))
}

/// The colouring and layer passes, built once for a device; the layer's pipelines by output
/// format and thermal lens model, as frames need them.
pub struct LayerPass {
    thermal: ThermalPass,
    module: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    pipelines: HashMap<(u32, u32), wgpu::ComputePipeline>,
}

impl LayerPass {
    pub fn new(gpu: &Gpu) -> Result<LayerPass, GpuError> {
        let device = &gpu.device;
        let thermal = ThermalPass::new(gpu)?;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("layer"),
            source: wgpu::ShaderSource::Wgsl(compose(SOURCE).into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("layer bindings"),
            entries: &[
                entry(0, uniform()),
                entry(1, uniform()),
                entry(2, storage(true)),
                entry(3, storage(false)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("layer"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(GpuError::Failed(format!("building the layer pass: {e}"))),
            None => Ok(LayerPass {
                thermal,
                module,
                layout,
                pipeline_layout,
                pipelines: HashMap::new(),
            }),
        }
    }

    fn pipeline(&mut self, gpu: &Gpu, key: (u32, u32)) -> Result<(), GpuError> {
        if self.pipelines.contains_key(&key) {
            return Ok(());
        }
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let constants = [
            ("OUTPUT_FORMAT", key.0 as f64),
            ("LENS_MODEL", key.1 as f64),
        ];
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("layer"),
            layout: Some(&self.pipeline_layout),
            module: &self.module,
            entry_point: Some("layer"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Failed(format!(
                "building the layer pipeline: {e}"
            )));
        }
        self.pipelines.insert(key, pipeline);
        Ok(())
    }

    /// Queues `layer` drawn over `target` (an output frame laid out as `output`, in
    /// `format`) on `encoder`.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        layer: &ThermalLayer,
        (target, output, format): (&wgpu::Buffer, &PlaneLayout, PixelFormat),
    ) -> Result<(), GpuError> {
        if layer.entries.is_empty() {
            return Ok(());
        }
        let key = (format.shader_code(), layer.lens.radial.model.code());
        self.pipeline(gpu, key)?;
        let (params, entries) = layer_params(layer, output)?;
        let device = &gpu.device;
        let colours =
            self.thermal
                .encode(device, encoder, &layer.frame, &layer.gain, layer.palette);
        let init = |label, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let params = init("layer params", bytemuck::bytes_of(&params));
        let entries = init("layer entries", bytemuck::cast_slice(&entries));
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("layer"),
            layout: &self.layout,
            entries: &[
                bind(0, params.as_entire_binding()),
                bind(1, entries.as_entire_binding()),
                bind(2, colours.as_entire_binding()),
                bind(3, target.as_entire_binding()),
            ],
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&self.pipelines[&key]);
        pass.set_bind_group(0, &group, &[]);
        let blocks = (output.width.div_ceil(8), output.height.div_ceil(2));
        pass.dispatch_workgroups(groups(blocks.0), groups(blocks.1), 1);
        Ok(())
    }
}
