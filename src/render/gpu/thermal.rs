//! The thermal colouring on the GPU (shaders/thermal.wgsl): a frame of 16-bit counts, the gain
//! table and the palette in, a colour a pixel out, as `thermal::colourise` does on the CPU.
//! One compute pass; the tables are a few kilobytes sent with each frame.

use super::pipelines::{bind, entry, storage, uniform};
use super::ring::MapSlot;
use super::{Gpu, GpuError};
use crate::thermal::{GainTable, Palette, ThermalFrame};
use image::RgbaImage;
use wgpu::util::DeviceExt;

pub const SOURCE: &str = include_str!("../../../shaders/thermal.wgsl");

/// The pass's inputs, bindings 0 to 3: the parameters, the gain's levels, the palette's
/// colours and the frame's counts (two a word: an odd count of pixels is padded with one).
fn inputs(
    device: &wgpu::Device,
    frame: &ThermalFrame,
    gain: &GainTable,
    palette: Palette,
) -> [wgpu::Buffer; 4] {
    let init = |label, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let params = ThermalParams {
        lo: gain.lo as u32,
        span: gain.span,
        width: frame.width,
        height: frame.height,
    };
    let levels: Vec<u32> = gain.levels.iter().map(|&l| l as u32).collect();
    let colours: Vec<u32> = palette
        .table()
        .iter()
        .map(|c| u32::from_le_bytes(*c))
        .collect();
    let padded;
    let counts: &[u16] = match frame.counts.len() % 2 {
        0 => &frame.counts,
        _ => {
            padded = [&frame.counts[..], &[0]].concat();
            &padded
        }
    };
    let storage = wgpu::BufferUsages::STORAGE;
    [
        init(
            "thermal params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        ),
        init("thermal levels", bytemuck::cast_slice(&levels), storage),
        init("thermal palette", bytemuck::cast_slice(&colours), storage),
        init("thermal counts", bytemuck::cast_slice(counts), storage),
    ]
}

/// Twin of `ThermalParams` in shaders/thermal.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ThermalParams {
    lo: u32,
    span: u32,
    width: u32,
    height: u32,
}

/// The colouring pass, built once for a device.
pub struct ThermalPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl ThermalPass {
    pub fn new(gpu: &Gpu) -> Result<ThermalPass, GpuError> {
        let device = &gpu.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("thermal"),
            source: wgpu::ShaderSource::Wgsl(SOURCE.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("thermal bindings"),
            entries: &[
                entry(0, uniform()),
                entry(1, storage(true)),
                entry(2, storage(true)),
                entry(3, storage(true)),
                entry(4, storage(false)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("thermal"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("thermal"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("colourise"),
            compilation_options: Default::default(),
            cache: None,
        });
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(GpuError::Failed(format!("building the thermal pass: {e}"))),
            None => Ok(ThermalPass { pipeline, layout }),
        }
    }

    /// Queues the colouring of `frame` under `gain` in `palette` on `encoder`: the buffer the
    /// colours land in (a word a pixel, R in the low byte), for a later pass to read.
    pub fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        frame: &ThermalFrame,
        gain: &GainTable,
        palette: Palette,
    ) -> wgpu::Buffer {
        let buffers = inputs(device, frame, gain, palette);
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("thermal colours"),
            size: frame.counts.len() as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| bind(i as u32, b.as_entire_binding()))
            .collect();
        entries.push(bind(4, out.as_entire_binding()));
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("thermal"),
            layout: &self.layout,
            entries: &entries,
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(frame.width.div_ceil(8), frame.height.div_ceil(8), 1);
        drop(pass);
        out
    }

    /// `frame` coloured under `gain` in `palette`, read back.
    pub fn colourise(
        &self,
        gpu: &Gpu,
        frame: &ThermalFrame,
        gain: &GainTable,
        palette: Palette,
    ) -> Result<RgbaImage, GpuError> {
        let device = &gpu.device;
        let size = frame.counts.len() as u64 * 4;
        let readback = MapSlot::new(
            device,
            "thermal readback",
            size,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        let out = self.encode(device, &mut encoder, frame, gain, palette);
        encoder.copy_buffer_to_buffer(&out, 0, &readback.buffer, 0, None);
        gpu.queue.submit([encoder.finish()]);
        readback.request(wgpu::MapMode::Read);
        readback.wait(device)?;
        let bytes = readback.read_out(size as usize)?;
        RgbaImage::from_raw(frame.width, frame.height, bytes)
            .ok_or_else(|| GpuError::Failed("the thermal colours are short".into()))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_thermal_pass_parses_and_validates_with_naga() {
        let module = naga::front::wgsl::parse_str(super::SOURCE)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(super::SOURCE)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(super::SOURCE)));
    }
}
