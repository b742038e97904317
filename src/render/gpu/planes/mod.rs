//! How the GPU holds a source frame: one texture with its own mip chain per plane (RGBA; or
//! the luma and the half-size chroma pairs of 4:2:0 input), where each plane's levels lie in
//! the level buffer that the ingest and mip passes write and the textures are copied from,
//! and what those passes are told of it (`IngestTargets`, `MipStep`, the twins of their WGSL
//! structs). Pure arithmetic, kept apart from the wgpu calls (src/render/gpu/input.rs) so it
//! can be checked on its own; `upload` lays frames out in the upload buffers, and
//! `host_levels` makes the passes' levels on the host.

mod host_levels;
mod upload;

pub use upload::{copy_for_upload, upload_layout};

use crate::frame::PixelFormat;
use crate::render::mip::{ImagedBox, levels_for};
use bytemuck::{Pod, Zeroable};

/// Texture copies need rows and offsets in multiples of this many bytes.
pub const COPY_ALIGN: u32 = 256;

/// The frame pixels (across, down) one ingest invocation takes (shaders/ingest.wgsl).
pub const INGEST_BLOCK: (u32, u32) = (16, 4);

/// Twin of the WGSL `Region` (shaders/levels.wgsl): one level of one plane in the level
/// buffer, in bytes (width in texels).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct Region {
    pub offset: u32,
    pub stride: u32,
    pub width: u32,
    pub height: u32,
}
const _: () = assert!(size_of::<Region>() == 16);

/// Twin of the WGSL `Targets` (shaders/ingest.wgsl): the regions the ingest writes, and the
/// lens's imaged box it covers.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct IngestTargets {
    /// RGBA, or luma: levels 1 and 2.
    pub level1: Region,
    pub level2: Region,
    /// Chroma: level 1 (none for RGBA).
    pub chroma1: Region,
    /// First column and row, and past the last (`Lens::imaged_box`).
    pub imaged: [u32; 4],
}
const _: () = assert!(size_of::<IngestTargets>() == 64);

impl IngestTargets {
    pub fn new(specs: &SourcePlanes, (columns, rows): &ImagedBox) -> IngestTargets {
        IngestTargets {
            level1: specs.region(0, 0),
            level2: specs.region(0, 1),
            chroma1: specs.region(1, 0),
            imaged: [columns.start, rows.start, columns.end, rows.end],
        }
    }
}

/// Twin of the WGSL `Step` (shaders/mip.wgsl): one level of one plane from the level before.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct MipStep {
    pub finer: Region,
    pub coarser: Region,
    /// Bytes per texel, then unused.
    pub channels: [u32; 4],
}
const _: () = assert!(size_of::<MipStep>() == 48);

impl MipStep {
    /// Level `finer + 1` of plane `plane` from level `finer` (1 or more: the levels the
    /// level buffer holds).
    pub fn new(specs: &SourcePlanes, plane: usize, finer: usize) -> MipStep {
        // Regions are indexed from level 1.
        MipStep {
            finer: specs.region(plane, finer - 1),
            coarser: specs.region(plane, finer),
            channels: [specs.planes[plane].channels, 0, 0, 0],
        }
    }

    /// Its dispatch: words of the coarser level across, rows down.
    pub fn dispatch(&self) -> (u32, u32) {
        let c = self.coarser;
        ((c.width * self.channels[0]).div_ceil(4), c.height)
    }
}

/// One plane of the source.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneSpec {
    /// Bytes per texel: 4 (RGBA), 1 (luma) or 2 (chroma).
    pub channels: u32,
    /// Level 0's size in texels.
    pub width: u32,
    pub height: u32,
    /// Levels in the plane's chain, level 0 included.
    pub levels: u32,
    /// Levels 1, 2, … in the level buffer (index 0 is level 1); level 0 is copied from the
    /// frame.
    pub regions: Vec<Region>,
    /// The plane's code value for black.
    pub black: u8,
    /// Levels (from 1) the ingest writes; the mip passes make the rest.
    pub ingested: u32,
}

/// Every plane of a source and the level buffer's size.
#[derive(Clone, Debug, PartialEq)]
pub struct SourcePlanes {
    pub planes: Vec<PlaneSpec>,
    pub buffer_size: u32,
}

impl SourcePlanes {
    /// The planes of a `width` × `height` frame of `format` (even sizes for 4:2:0; I420 and
    /// NV12 alike, since the upload weaves I420), whose full-size chain has
    /// `levels_for(width, height)` levels.
    pub fn new(format: PixelFormat, width: u32, height: u32) -> SourcePlanes {
        let levels = levels_for(width, height);
        let (w2, h2) = ((width / 2).max(1), (height / 2).max(1));
        // Bytes per texel, size, levels, black, levels the ingest writes.
        let specs = match format {
            PixelFormat::Rgba => vec![(4, width, height, levels, 0, 2)],
            _ => vec![
                (1, width, height, levels, 16, 2),
                (2, w2, h2, levels - 1, 128, 1),
            ],
        };
        let mut offset = 0;
        let mut region = |(w, h): (u32, u32), channels: u32| {
            let stride = (w * channels).next_multiple_of(COPY_ALIGN);
            let r = Region {
                offset,
                stride,
                width: w,
                height: h,
            };
            offset += stride * h;
            r
        };
        let planes = specs
            .into_iter()
            .map(|(channels, width, height, levels, black, ingested)| {
                let regions = (1..levels)
                    .map(|k| region(((width >> k).max(1), (height >> k).max(1)), channels))
                    .collect();
                PlaneSpec {
                    channels,
                    width,
                    height,
                    levels,
                    regions,
                    black,
                    ingested,
                }
            })
            .collect();
        SourcePlanes {
            planes,
            // The mip pass reads two words past a row's last texel, on the last row too.
            buffer_size: offset + 16,
        }
    }

    /// The level buffer's first contents: every plane's black (RGBA black is all zero).
    pub fn black_levels(&self) -> Vec<u8> {
        let mut out = vec![0u8; self.buffer_size as usize];
        for plane in &self.planes {
            for r in &plane.regions {
                let (a, b) = (r.offset as usize, (r.offset + r.stride * r.height) as usize);
                out[a..b].fill(plane.black);
            }
        }
        out
    }

    /// Level `k + 1` of plane `p` in the level buffer; an empty region where there is none.
    pub fn region(&self, p: usize, k: usize) -> Region {
        self.planes
            .get(p)
            .and_then(|s| s.regions.get(k))
            .copied()
            .unwrap_or_default()
    }

    /// Mip steps the mip pass runs after the ingest: (plane, finer level) for every level
    /// of every plane the ingest does not write, finer levels first.
    pub fn mip_steps(&self) -> Vec<(usize, usize)> {
        let mut steps = Vec::new();
        for (p, plane) in self.planes.iter().enumerate() {
            for k in plane.ingested..plane.levels - 1 {
                steps.push((p, k as usize));
            }
        }
        steps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_4k_4_2_0_frame_has_luma_and_chroma_pairs_whose_levels_tile_the_buffer() {
        let s = SourcePlanes::new(PixelFormat::Nv12, 3840, 2160);
        assert_eq!(s.planes.len(), 2);
        let luma = &s.planes[0];
        assert_eq!((luma.levels, luma.regions.len()), (8, 7));
        assert_eq!(
            luma.regions[0],
            Region {
                offset: 0,
                stride: 2048,
                width: 1920,
                height: 1080
            }
        );
        let chroma = &s.planes[1];
        assert_eq!((chroma.width, chroma.channels, chroma.levels), (1920, 2, 7));
        assert_eq!(chroma.black, 128);
        // Chroma level 1 is the frame's level 2: 960x540 pairs, rows padded to 2048 bytes.
        assert_eq!(
            (chroma.regions[0].width, chroma.regions[0].stride),
            (960, 2048)
        );
        // Regions follow each other, each on a copy boundary.
        let all: Vec<&Region> = s.planes.iter().flat_map(|p| &p.regions).collect();
        for pair in all.windows(2) {
            assert_eq!(
                pair[1].offset,
                pair[0].offset + pair[0].stride * pair[0].height
            );
        }
        assert!(
            all.iter()
                .all(|r| r.offset % COPY_ALIGN == 0 && r.stride % COPY_ALIGN == 0)
        );
        assert_eq!(s.mip_steps().len(), 5 + 5);
        assert_eq!(SourcePlanes::new(PixelFormat::I420, 3840, 2160), s);
    }

    #[test]
    fn nv12_chroma_is_one_plane_of_pairs_and_rgba_is_one_plane() {
        let nv12 = SourcePlanes::new(PixelFormat::Nv12, 1280, 720);
        assert_eq!(nv12.planes.len(), 2);
        assert_eq!(nv12.planes[1].channels, 2);
        // Chroma level 1: 320x180 texel pairs, 640 bytes a row padded to 768.
        assert_eq!(nv12.planes[1].regions[0].stride, 768);
        let rgba = SourcePlanes::new(PixelFormat::Rgba, 1001, 7);
        assert_eq!(rgba.planes.len(), 1);
        // 1001x7: levels 1 (500x3) and 2 (250x1), rows of 2000 and 1000 bytes padded.
        assert_eq!(rgba.planes[0].regions.len(), 2);
        assert_eq!(rgba.planes[0].regions[1].stride, 1024);
        assert!(rgba.mip_steps().is_empty());
    }

    #[test]
    fn the_buffer_starts_black_in_every_plane() {
        let s = SourcePlanes::new(PixelFormat::Nv12, 64, 32);
        let black = s.black_levels();
        assert_eq!(black[s.planes[0].regions[0].offset as usize], 16);
        assert_eq!(black[s.planes[1].regions[0].offset as usize + 1], 128);
    }
}
