//! How the GPU holds a source frame: one texture with its own mip chain per plane (RGBA; or
//! the luma and the half-size chroma of 4:2:0 input, Cb and Cr interleaved as NV12 has them,
//! into which the ingest weaves I420's two planes), and where each plane's levels lie in the
//! level buffer that the ingest and mip passes write and the textures are copied from. Pure arithmetic, kept apart from the
//! wgpu calls (src/render/gpu/renderer.rs) so it can be checked on its own.

use crate::render::frame::{PixelFormat, PlaneLayout};
use crate::render::mip::levels_for;
use bytemuck::{Pod, Zeroable};

/// Texture copies need rows and offsets in multiples of this many bytes.
pub const COPY_ALIGN: u32 = 256;

/// Twin of the WGSL `Region` (shaders/common.wgsl): one level of one plane in the level
/// buffer, in bytes (width in texels).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct Region {
    pub offset: u32,
    pub stride: u32,
    pub width: u32,
    pub height: u32,
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
    /// Levels 1, 2, … in the level buffer (index 0 is level 1).
    pub regions: Vec<Region>,
    /// Level 0 in the level buffer, where the ingest makes it (I420's woven chroma); else it
    /// is copied from the frame.
    pub woven: Option<Region>,
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
    /// The planes of a `width` × `height` frame of `format` (even sizes for 4:2:0), whose
    /// full-size chain has `levels_for(width, height)` levels.
    pub fn new(format: PixelFormat, width: u32, height: u32) -> SourcePlanes {
        let levels = levels_for(width, height);
        let (w2, h2) = ((width / 2).max(1), (height / 2).max(1));
        // Bytes per texel, size, levels, black, levels the ingest writes, woven level 0.
        let specs = match format {
            PixelFormat::Rgba => vec![(4, width, height, levels, 0, 2, false)],
            _ => vec![
                (1, width, height, levels, 16, 2, false),
                (2, w2, h2, levels - 1, 128, 1, format == PixelFormat::I420),
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
            .map(
                |(channels, width, height, levels, black, ingested, woven)| {
                    let woven = woven.then(|| region((width, height), channels));
                    let regions = (1..levels)
                        .map(|k| region(((width >> k).max(1), (height >> k).max(1)), channels))
                        .collect();
                    PlaneSpec {
                        channels,
                        width,
                        height,
                        levels,
                        regions,
                        woven,
                        black,
                        ingested,
                    }
                },
            )
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
            for r in plane.woven.iter().chain(&plane.regions) {
                let (a, b) = (r.offset as usize, (r.offset + r.stride * r.height) as usize);
                out[a..b].fill(plane.black);
            }
        }
        out
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

/// `layout` with rows padded as copies into textures need: the planes copied (RGBA, luma,
/// NV12 chroma) with rows a multiple of [`COPY_ALIGN`] bytes.
pub fn padded_for_copy(layout: &PlaneLayout) -> PlaneLayout {
    let pixels = match layout.format {
        PixelFormat::Rgba => COPY_ALIGN / 4,
        _ => COPY_ALIGN,
    };
    PlaneLayout::aligned(layout.format, layout.width, layout.height, pixels)
        .expect("a layout that exists already")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_4k_i420_frame_has_luma_and_woven_chroma_whose_levels_tile_the_buffer() {
        let s = SourcePlanes::new(PixelFormat::I420, 3840, 2160);
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
        // Level 0 woven from U and V: 1920 pairs a row, 3840 bytes.
        assert_eq!(chroma.woven.unwrap().stride, 3840);
        // Chroma level 1 is the frame's level 2: 960x540 pairs, rows padded to 2048 bytes.
        assert_eq!(
            (chroma.regions[0].width, chroma.regions[0].stride),
            (960, 2048)
        );
        // Regions follow each other, each on a copy boundary.
        let all: Vec<&Region> = s
            .planes
            .iter()
            .flat_map(|p| p.woven.iter().chain(&p.regions))
            .collect();
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
    }

    #[test]
    fn nv12_chroma_is_one_plane_as_it_comes_and_rgba_is_one_plane() {
        let nv12 = SourcePlanes::new(PixelFormat::Nv12, 1280, 720);
        assert_eq!(nv12.planes.len(), 2);
        assert_eq!(nv12.planes[1].channels, 2);
        assert_eq!(
            nv12.planes[1].woven, None,
            "NV12's chroma is copied as it comes"
        );
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

    #[test]
    fn padded_rows_suit_texture_copies_in_every_plane_copied() {
        for format in [PixelFormat::Rgba, PixelFormat::I420, PixelFormat::Nv12] {
            let l = padded_for_copy(&PlaneLayout::tight(format, 1002, 566).unwrap());
            assert_eq!(l.stride % COPY_ALIGN, 0, "{format}");
        }
        let nv12 = padded_for_copy(&PlaneLayout::tight(PixelFormat::Nv12, 1002, 566).unwrap());
        assert_eq!(nv12.chroma_stride % COPY_ALIGN, 0);
        for format in [PixelFormat::I420, PixelFormat::Nv12] {
            let tight = PlaneLayout::tight(format, 3840, 2160).unwrap();
            assert_eq!(
                padded_for_copy(&tight),
                tight,
                "4K {format} needs no padding"
            );
        }
    }
}
