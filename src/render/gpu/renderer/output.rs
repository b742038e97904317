//! One output of the renderer: what the draw pass writes for one frame plan (the frame's
//! parameters and views, the block map, the target it draws into and reads back from) and the
//! pipelines it draws with. A renderer has its main output, drawn with each upload, and may
//! have more, drawn again from the same upload ([`super::Renderer::redraw`]): the views
//! alone and the detection scans, each at its own size, format and filter.

use super::super::blocks::{BLOCK_H, BLOCK_W};
use super::super::draw::{BlockBuffer, Target};
use super::super::input::Input;
use super::super::params::{GpuParams, GpuView, MAX_VIEWS, SHUTTER_BIT, frame_params};
use super::super::pipelines::{DrawKey, MIXED_WORKGROUP, PipelineKey, Pipelines, bind, groups};
use super::super::{Gpu, GpuError};
use super::OUTPUT_ALIGN;
use crate::frame::{PixelFormat, PlaneLayout};
use crate::plan::Filter;
use crate::plan::FramePlan;

/// An output drawn again from the renderer's last upload, made by
/// [`super::Renderer::add_output`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputId(pub(super) usize);

pub(super) struct Output {
    pub format: PixelFormat,
    pub filter: Filter,
    /// The one level the bilinear filter samples.
    level: u32,
    pub params: wgpu::Buffer,
    views: wgpu::Buffer,
    /// Mip's sampler and bilinear's, in `Filter` order.
    samplers: [wgpu::Sampler; 2],
    pub target: Option<Target>,
    group: Option<wgpu::BindGroup>,
    blocks: Option<BlockBuffer>,
    /// The draw pipelines drawing the frame last prepared, and that frame's own view kinds
    /// (they differ while it is drawn generically).
    pub draw_key: Option<DrawKey>,
    pub frame_kinds: u32,
    /// Frames drawn, which picks the readback buffer of the next.
    pub drawn: u64,
}

impl Output {
    pub fn new(device: &wgpu::Device, format: PixelFormat, filter: Filter) -> Output {
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
        let samplers = [Filter::Mip, Filter::Bilinear].map(|filter| {
            device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("trilinear"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: match filter {
                    Filter::Mip => wgpu::MipmapFilterMode::Linear,
                    Filter::Bilinear => wgpu::MipmapFilterMode::Nearest,
                },
                ..Default::default()
            })
        });
        Output {
            format,
            filter,
            level: 0,
            params,
            views,
            samplers,
            target: None,
            group: None,
            blocks: None,
            draw_key: None,
            frame_kinds: 0,
            drawn: 0,
        }
    }

    /// Draws from now on with `filter`, the bilinear filter from the frame's level `level`.
    pub fn set_filter(&mut self, filter: Filter, level: u32) {
        if (filter, level) != (self.filter, self.level) {
            (self.filter, self.level) = (filter, level);
            self.group = None;
        }
    }

    /// Forgets the bindings that name the input (it was made again).
    pub fn forget_input(&mut self) {
        self.group = None;
    }

    /// Makes the target, block map and bindings match `plan`, chooses the draw pipelines
    /// (for this output's first frame, or its first with another filter, those specialised
    /// for its view kinds: see
    /// [`Pipelines::draw`]) and writes the frame's parameters.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        pipelines: &mut Pipelines,
        input: &Input,
        plan: &FramePlan,
    ) -> Result<(), GpuError> {
        let layout = PlaneLayout::aligned(
            self.format,
            plan.layout.width,
            plan.layout.height,
            OUTPUT_ALIGN,
        )?;
        if !self.target.as_ref().is_some_and(|t| t.layout == layout) {
            self.target = Some(Target::new(&gpu.device, layout));
            self.group = None;
        }
        let rects: Vec<_> = plan.views.iter().map(|v| v.rect).collect();
        let size = (plan.layout.width, plan.layout.height);
        if BlockBuffer::follow(&mut self.blocks, &gpu.device, &gpu.queue, size, &rects) {
            self.group = None;
        }
        if self.group.is_none() {
            self.group = Some(self.bind(gpu, pipelines, input));
        }
        let target = self.target.as_ref().unwrap();
        let mixed = self.mixed_blocks();
        let (params, views) =
            frame_params(plan, &input.padded, &target.layout, input.levels, mixed)?;
        // The draw pipeline leaves out the code of view kinds the frame lacks.
        let shutter = (plan.shutter.is_some() as u32) << SHUTTER_BIT;
        let kinds = views
            .iter()
            .fold(shutter, |kinds, v| kinds | 1 << v.kind[0]);
        let wanted = DrawKey {
            lens_model: plan.lens.shader_model(),
            output: self.format,
            filter: self.filter,
            input: input.padded.format,
            view_kinds: kinds,
        };
        let new = self.draw_key.is_none_or(|k| k.filter != self.filter);
        self.draw_key = Some(pipelines.draw(wanted, new)?);
        self.frame_kinds = kinds;
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if !views.is_empty() {
            gpu.queue
                .write_buffer(&self.views, 0, bytemuck::cast_slice(&views));
        }
        Ok(())
    }

    fn bind(&self, gpu: &Gpu, pipelines: &Pipelines, input: &Input) -> wgpu::BindGroup {
        let target = self.target.as_ref().unwrap();
        let blocks = &self.blocks.as_ref().unwrap().buffer;
        // RGBA has one plane: bound twice, the second never sampled.
        let plane =
            |i| wgpu::BindingResource::TextureView(input.plane_view(i, self.filter, self.level));
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("draw"),
            layout: &pipelines.layouts.draw,
            entries: &[
                bind(0, self.params.as_entire_binding()),
                bind(1, self.views.as_entire_binding()),
                bind(2, plane(0)),
                bind(
                    3,
                    wgpu::BindingResource::Sampler(&self.samplers[self.filter as usize]),
                ),
                bind(4, target.buffer.as_entire_binding()),
                bind(5, blocks.as_entire_binding()),
                bind(6, plane(1)),
            ],
        })
    }

    /// Blocks the draw pass's per-pixel dispatch draws.
    fn mixed_blocks(&self) -> u32 {
        self.blocks.as_ref().map_or(0, BlockBuffer::mixed)
    }

    /// The draw pass of the frame prepared, after one workgroup of each pipeline in
    /// `warm_up` (see [`Pipelines::take_warm_up`]).
    pub fn encode_draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipelines: &Pipelines,
        warm_up: &[DrawKey],
    ) {
        let target = self.target.as_ref().unwrap();
        let key = self.draw_key.expect("a prepared frame");
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("draw"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, self.group.as_ref().unwrap(), &[]);
        // One workgroup of each generic pipeline, drawing what the full dispatch then draws
        // again, so they are compiled now rather than when a frame first needs them (a pair
        // for another lens model reads this frame's lens as one of its own: what it draws is
        // nonsense, drawn over the same way).
        for &generic in warm_up {
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
}
