//! The renderer's input side: what depends on the input frame's layout and the lens's imaged
//! box, made once and kept while neither changes. A frame's bytes are copied into a mapped
//! upload buffer of the ring (rows padded as texture copies need, I420's chroma woven into
//! NV12's pairs). Each plane's level 0 is copied from there into its texture over the imaged
//! box. For the mip filter, the ingest pass reads the frame (in the upload buffer itself where
//! the device shares host memory, else in a copy of it) and writes every plane's levels 1 and
//! 2 into a level buffer, the mip passes the rest, and those levels are copied into the
//! textures; on a software rasterizer the host makes the same levels instead, into the upload
//! buffer after the frame (`SourcePlanes::make_levels`).

use super::pipelines::{Layouts, PipelineKey, Pipelines, bind, groups};
use super::planes::{
    COPY_ALIGN, INGEST_BLOCK, IngestTargets, MipStep, PlaneSpec, SourcePlanes, copy_for_upload,
    upload_layout,
};
use super::ring::{MapSlot, RING};
use super::{Gpu, GpuError};
use crate::frame::PlaneLayout;
use crate::plan::Filter;
use crate::render::mip::{ImagedBox, levels_for};
use wgpu::util::DeviceExt;

/// One plane of the source on the GPU: its texture (all levels); `Input::specs` says where
/// its levels from 1 on lie in the level buffer.
struct Plane {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    /// Each level alone, for an output drawn with the bilinear filter from one level.
    levels: Vec<wgpu::TextureView>,
}

/// One mip pass: its bind group and dispatch size (words across, rows).
type MipPass = (wgpu::BindGroup, (u32, u32));

/// What the input side needs to know of the renderer.
pub(super) struct InputSetup<'a> {
    pub gpu: &'a Gpu,
    pub layouts: &'a Layouts,
    /// The frame parameters the ingest reads.
    pub params: &'a wgpu::Buffer,
    pub filter: Filter,
    /// Whether the host makes the mip filter's levels (`Renderer::make_levels_on_host`).
    pub levels_on_host: bool,
}

impl InputSetup<'_> {
    /// Whether the ingest and mip passes make the mip filter's levels (not the host, and not
    /// the bilinear filter, which needs none).
    pub fn level_passes(&self) -> bool {
        self.filter == Filter::Mip && !self.levels_on_host
    }
}

/// What depends on the input layout: upload ring, raw buffer, level buffer, the planes.
pub(super) struct Input {
    pub layout: PlaneLayout,
    /// The layout in the upload buffers: `layout` with rows padded for texture copies.
    pub padded: PlaneLayout,
    /// The input pixels the GPU takes in (`Lens::imaged_box`).
    pub imaged: ImagedBox,
    pub levels: u32,
    pub uploads: Vec<MapSlot>,
    /// The frame's bytes where the ingest reads them: a copy of the upload buffer, or none
    /// where the device reads the upload buffers themselves (`Gpu::shared_memory`) or no
    /// pass makes levels.
    raw: Option<wgpu::Buffer>,
    /// Every plane's levels from 1 on, packed (`planes::SourcePlanes`), where the passes
    /// make them.
    level_buffer: Option<wgpu::Buffer>,
    /// Where levels made on the host lie in each upload buffer, after the frame, and the
    /// host's copy they are made in.
    host_levels: Option<(u64, Vec<u8>)>,
    /// Every plane's size, levels and level regions, in the order of `planes`.
    specs: SourcePlanes,
    planes: Vec<Plane>,
    /// The ingest's bindings: one, or one per upload buffer where it reads them.
    ingest: Vec<wgpu::BindGroup>,
    mips: Vec<MipPass>,
}

impl Input {
    /// The input side for frames laid out as `layout`, of which the lens images `imaged`
    /// (everything starts black, and nothing outside the box is written).
    pub fn new(setup: &InputSetup, layout: &PlaneLayout, imaged: ImagedBox) -> Input {
        let device = &setup.gpu.device;
        let padded = upload_layout(layout);
        let specs = SourcePlanes::new(padded.format, layout.width, layout.height);
        // The ingest may read a word past the last row's end.
        let frame_size = (padded.size as u64 + 16).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let passes = setup.level_passes();
        let host_levels = (setup.filter == Filter::Mip && setup.levels_on_host)
            .then(|| frame_size.next_multiple_of(COPY_ALIGN as u64));
        let size = match host_levels {
            Some(at) => at + specs.buffer_size as u64,
            None => frame_size,
        };
        let shared = setup.gpu.shared_memory;
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
        let planes: Vec<Plane> = specs.planes.iter().map(|spec| plane(setup, spec)).collect();
        let (ingest, mips) = match &level_buffer {
            Some(levels) => {
                let inputs = match &raw {
                    Some(raw) => vec![raw],
                    None => uploads.iter().map(|u| &u.buffer).collect(),
                };
                level_pass_groups(setup, levels, inputs, &specs, &imaged)
            }
            None => (Vec::new(), Vec::new()),
        };
        Input {
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
        }
    }

    /// Plane `i`'s texture as an output drawn with `filter` samples it: every level, or for
    /// the bilinear filter one level alone, the frame's level `level` (RGBA's one plane for
    /// any `i`; 4:2:0's chroma plane starts at the frame's level 1, so it gives its level
    /// `level - 1`, or 0).
    pub fn plane_view(&self, i: usize, filter: Filter, level: u32) -> &wgpu::TextureView {
        let plane = &self.planes[i.min(self.planes.len() - 1)];
        let level = match i {
            1 if self.planes.len() == 2 => level.saturating_sub(1),
            _ => level,
        };
        match filter {
            Filter::Mip => &plane.view,
            Filter::Bilinear => &plane.levels[(level as usize).min(plane.levels.len() - 1)],
        }
    }

    /// Copies the frame's bytes into upload buffer `slot` (waiting until it is free), rows
    /// padded as the upload layout says, and, where the host makes the mip levels, the
    /// frame's levels after it.
    pub fn fill_upload(
        &mut self,
        device: &wgpu::Device,
        slot: usize,
        data: &[u8],
    ) -> Result<(), GpuError> {
        let upload = &self.uploads[slot];
        upload.wait(device)?;
        {
            let mut view = upload
                .buffer
                .get_mapped_range_mut(..)
                .map_err(|e| GpuError::Failed(e.to_string()))?;
            copy_for_upload(data, &self.layout, &self.padded, |at, bytes| {
                view.slice(at..at + bytes.len()).copy_from_slice(bytes)
            });
            if let Some((at, levels)) = &mut self.host_levels {
                self.specs
                    .make_levels(data, &self.layout, &self.imaged, levels);
                let at = *at as usize;
                view.slice(at..at + levels.len()).copy_from_slice(levels);
            }
        }
        upload.buffer.unmap();
        Ok(())
    }

    /// The frame in upload buffer `slot` into the planes' textures: level 0 over the imaged
    /// box, and for the mip filter every level from 1 on.
    pub fn encode_upload(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        slot: usize,
        filter: Filter,
        pipelines: &Pipelines,
    ) {
        let upload = &self.uploads[slot].buffer;
        // The ingest reads the frame's bytes, where it reads a copy.
        if let Some(raw) = &self.raw {
            encoder.copy_buffer_to_buffer(upload, 0, raw, 0, None);
        }
        // Level 0 of every plane over the imaged box, straight from the upload buffer.
        let (columns, rows) = &self.imaged;
        let padded = &self.padded;
        for (i, (plane, spec)) in self.planes.iter().zip(&self.specs.planes).enumerate() {
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
        if filter != Filter::Mip {
            return;
        }
        // Levels from 1 on: from the upload buffer, where made on the host, else from the
        // level buffer once the passes have made them.
        let (levels, base) = match (&self.host_levels, &self.level_buffer) {
            (Some((at, _)), _) => (upload, *at),
            (None, Some(level_buffer)) => {
                self.encode_level_passes(encoder, slot, pipelines);
                (level_buffer, 0)
            }
            (None, None) => unreachable!("the mip filter has its levels made somewhere"),
        };
        for (plane, spec) in self.planes.iter().zip(&self.specs.planes) {
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
    fn encode_level_passes(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        slot: usize,
        pipelines: &Pipelines,
    ) {
        let (columns, rows) = &self.imaged;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("ingest and mip chain"),
            timestamp_writes: None,
        });
        let input = self.padded.format;
        pass.set_pipeline(pipelines.get(PipelineKey::Ingest { input }));
        pass.set_bind_group(0, &self.ingest[slot.min(self.ingest.len() - 1)], &[]);
        pass.dispatch_workgroups(
            groups(columns.len().div_ceil(INGEST_BLOCK.0 as usize) as u32),
            groups(rows.len().div_ceil(INGEST_BLOCK.1 as usize) as u32),
            1,
        );
        pass.set_pipeline(pipelines.get(PipelineKey::Mip));
        for (group, (w, h)) in &self.mips {
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(groups(*w), groups(*h), 1);
        }
    }
}

/// A plane's texture with its whole chain, level 0 black (it is copied over the imaged box
/// only), and the views the draw pass samples: one level alone for the bilinear filter, so a
/// software rasterizer can leave out the per-pixel choice of levels.
fn plane(setup: &InputSetup, spec: &PlaneSpec) -> Plane {
    let texture = setup.gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("source plane"),
        size: extent(spec.width, spec.height),
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
    fill_level0(&setup.gpu.queue, &texture, spec);
    Plane {
        view: texture.create_view(&wgpu::TextureViewDescriptor::default()),
        levels: (0..spec.levels)
            .map(|level| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    base_mip_level: level,
                    mip_level_count: Some(1),
                    ..Default::default()
                })
            })
            .collect(),
        texture,
    }
}

/// The ingest and mip passes' bind groups, writing levels into `levels`: an ingest group per
/// buffer in `inputs` (the frame's bytes: the upload buffers read in place, or their copy),
/// and the mip steps with their dispatch sizes (words across, rows).
fn level_pass_groups(
    setup: &InputSetup,
    levels: &wgpu::Buffer,
    inputs: Vec<&wgpu::Buffer>,
    specs: &SourcePlanes,
    imaged: &ImagedBox,
) -> (Vec<wgpu::BindGroup>, Vec<MipPass>) {
    let device = &setup.gpu.device;
    let uniform_init = |label, contents: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::UNIFORM,
        })
    };
    let targets = IngestTargets::new(specs, imaged);
    let targets = uniform_init("ingest targets", bytemuck::bytes_of(&targets));
    let ingest = inputs
        .into_iter()
        .map(|input| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ingest"),
                layout: &setup.layouts.ingest,
                entries: &[
                    bind(0, setup.params.as_entire_binding()),
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
            let step = MipStep::new(specs, p, k);
            let size = step.dispatch();
            let step = uniform_init("mip step", bytemuck::bytes_of(&step));
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("mip"),
                layout: &setup.layouts.mip,
                entries: &[
                    bind(0, levels.as_entire_binding()),
                    bind(1, step.as_entire_binding()),
                ],
            });
            (group, size)
        })
        .collect();
    (ingest, mips)
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
