//! How the GPU holds a source frame: the layout frames take in the upload buffers (I420's two
//! chroma planes woven there into NV12's Cb Cr pairs), one texture with its own mip chain per
//! plane (RGBA; or the luma and the half-size chroma pairs of 4:2:0 input), and where each
//! plane's levels lie in the level buffer that the ingest and mip passes write and the
//! textures are copied from. Pure arithmetic and byte copies, kept apart from the wgpu calls
//! (src/render/gpu/renderer.rs) so it can be checked on its own.

use crate::frame::{PixelFormat, PlaneLayout, PlaneRows};
use crate::render::mip::{ImagedBox, levels_for};
use bytemuck::{Pod, Zeroable};
use std::ops::Range;

/// Texture copies need rows and offsets in multiples of this many bytes.
pub const COPY_ALIGN: u32 = 256;

/// The frame pixels (across, down) one ingest invocation takes (shaders/ingest.wgsl).
pub const INGEST_BLOCK: (u32, u32) = (16, 4);

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

    /// The levels the ingest and mip passes make (shaders/ingest.wgsl, shaders/mip.wgsl),
    /// made on the host instead, byte for byte: every plane's levels from 1 on of `frame`
    /// (laid out as `layout`, any layout of the source's format and size) written into
    /// `levels`, laid out as the level buffer and black where nothing is written (as
    /// [`SourcePlanes::black_levels`] starts it). The levels the ingest writes are made over
    /// the frame pixels its blocks cover from the imaged box `imaged`, the rest of each chain
    /// whole. Level texels read only picture pixels, never row padding, so the frame's own
    /// layout gives what its upload layout would.
    pub fn make_levels(
        &self,
        frame: &[u8],
        layout: &PlaneLayout,
        imaged: &ImagedBox,
        levels: &mut [u8],
    ) {
        let (columns, rows) = imaged;
        let covered = |range: &Range<u32>, block: u32| {
            range.start..range.start + range.len().next_multiple_of(block as usize) as u32
        };
        let cover = [
            covered(columns, INGEST_BLOCK.0),
            covered(rows, INGEST_BLOCK.1),
        ];
        let frame_planes = layout.planes();
        // I420's Cb and Cr rows, woven into pairs as the upload buffer holds them.
        let (mut upper, mut lower) = (Vec::new(), Vec::new());
        for (p, plane) in self.planes.iter().enumerate() {
            // The plane's level 0 in the frame, and its scale in the frame's chain (chroma
            // starts at the frame's level 1).
            let source = match (p, layout.format) {
                (1, PixelFormat::I420) => &frame_planes[1..3],
                _ => &frame_planes[p..p + 1],
            };
            let shift = p as u32;
            let ch = plane.channels as usize;
            for k in 1..plane.levels as usize {
                let r = plane.regions[k - 1];
                let span = |range: &Range<u32>, size: u32| {
                    if k as u32 > plane.ingested {
                        return 0..size as usize;
                    }
                    let s = k as u32 + shift;
                    (range.start >> s).min(size) as usize..(range.end >> s).min(size) as usize
                };
                let xs = span(&cover[0], r.width);
                let (head, coarser) = levels.split_at_mut(r.offset as usize);
                let (a, b) = (2 * xs.start * ch, 2 * xs.end * ch);
                for y in span(&cover[1], r.height) {
                    let (top, bottom) = match k {
                        1 => (
                            frame_row(frame, source, 2 * y, &mut upper),
                            frame_row(frame, source, 2 * y + 1, &mut lower),
                        ),
                        _ => {
                            let f = plane.regions[k - 2];
                            let row = |y: usize| &head[f.offset as usize + y * f.stride as usize..];
                            (row(2 * y), row(2 * y + 1))
                        }
                    };
                    let out = &mut coarser[y * r.stride as usize..][xs.start * ch..xs.end * ch];
                    let (top, bottom) = (&top[a..b], &bottom[a..b]);
                    halve_row(ch, top, bottom, out);
                }
            }
        }
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

/// Row `y` of a plane of `frame`: of `planes[0]`, or of two (I420's Cb and Cr) woven into
/// pairs in `woven`.
fn frame_row<'a>(
    frame: &'a [u8],
    planes: &[PlaneRows],
    y: usize,
    woven: &'a mut Vec<u8>,
) -> &'a [u8] {
    let row = |p: &PlaneRows| {
        let at = p.offset as usize + y * p.stride as usize;
        &frame[at..at + p.bytes as usize]
    };
    let [cb, cr] = planes else {
        return row(&planes[0]);
    };
    woven.clear();
    woven.extend(row(cb).iter().zip(row(cr)).flat_map(|(b, r)| [*b, *r]));
    woven
}

/// A row of a coarser level from two rows of the finer one, `channels` bytes a texel: each
/// byte the rounded mean (halves up) of its channel in the 2x2 finer texels under it, as
/// `halve` in shaders/levels.wgsl. Texels are read as words and their bytes summed in
/// 16-bit lanes, which the compiler turns into vector code (each width on its own, so that
/// it does).
fn halve_row(channels: usize, top: &[u8], bottom: &[u8], out: &mut [u8]) {
    match channels {
        1 => halve_luma(top, bottom, out),
        2 => halve_pairs(top, bottom, out),
        _ => halve_rgba(top, bottom, out),
    }
}

#[inline(never)]
fn halve_luma(top: &[u8], bottom: &[u8], out: &mut [u8]) {
    let rows = top.as_chunks::<2>().0.iter().zip(bottom.as_chunks::<2>().0);
    for (o, (t, b)) in out.iter_mut().zip(rows) {
        let (t, b) = (u16::from_le_bytes(*t), u16::from_le_bytes(*b));
        let sum = (t & 0xff) + (t >> 8) + (b & 0xff) + (b >> 8);
        *o = ((sum + 2) >> 2) as u8;
    }
}

/// Two Cb Cr pairs a word: Cb sums in the even bytes' lanes, Cr in the odd.
#[inline(never)]
fn halve_pairs(top: &[u8], bottom: &[u8], out: &mut [u8]) {
    let rows = top.as_chunks::<4>().0.iter().zip(bottom.as_chunks::<4>().0);
    for (o, (t, b)) in out.as_chunks_mut::<2>().0.iter_mut().zip(rows) {
        let (t, b) = (u32::from_le_bytes(*t), u32::from_le_bytes(*b));
        let cb = (t & 0x00ff00ff) + (b & 0x00ff00ff);
        let cr = ((t >> 8) & 0x00ff00ff) + ((b >> 8) & 0x00ff00ff);
        let mean = |s: u32| (((s & 0xffff) + (s >> 16) + 2) >> 2) as u8;
        *o = [mean(cb), mean(cr)];
    }
}

/// Four RGBA texels at a time (the rows summed in 16-bit lanes, then each texel's two
/// columns), which the compiler vectorises; then the last few one by one.
#[inline(never)]
fn halve_rgba(top: &[u8], bottom: &[u8], out: &mut [u8]) {
    let len = out.len();
    let (outs, rest) = out.as_chunks_mut::<16>();
    let rows = top
        .as_chunks::<32>()
        .0
        .iter()
        .zip(bottom.as_chunks::<32>().0);
    for (o, (t, b)) in outs.iter_mut().zip(rows) {
        let sums: [u16; 32] = std::array::from_fn(|i| t[i] as u16 + b[i] as u16);
        *o = std::array::from_fn(|j| {
            let at = 8 * (j / 4) + j % 4;
            ((sums[at] + sums[at + 4] + 2) >> 2) as u8
        });
    }
    let done = 2 * (len - rest.len());
    let (top, bottom) = (&top[done..], &bottom[done..]);
    for (j, o) in rest.iter_mut().enumerate() {
        let at = 8 * (j / 4) + j % 4;
        let sum = [top[at], top[at + 4], bottom[at], bottom[at + 4]].map(u16::from);
        *o = ((sum.iter().sum::<u16>() + 2) >> 2) as u8;
    }
}

/// The layout a frame laid out as `layout` takes in the upload buffers: RGBA, or NV12 for
/// 4:2:0 (I420's chroma planes woven into Cb Cr pairs by [`copy_for_upload`], which costs the
/// copy next to nothing and spares the GPU a pass), with every plane's rows a multiple of
/// [`COPY_ALIGN`] bytes as copies into textures need.
pub fn upload_layout(layout: &PlaneLayout) -> PlaneLayout {
    let (format, pixels) = match layout.format {
        PixelFormat::Rgba => (PixelFormat::Rgba, COPY_ALIGN / 4),
        _ => (PixelFormat::Nv12, COPY_ALIGN),
    };
    PlaneLayout::aligned(format, layout.width, layout.height, pixels)
        .expect("a layout that exists already")
}

/// Copies frame `data`, laid out as `from`, into an upload buffer laid out as `to` (its
/// [`upload_layout`]), handing `put` each run of bytes and where in the buffer it goes.
pub fn copy_for_upload(
    data: &[u8],
    from: &PlaneLayout,
    to: &PlaneLayout,
    mut put: impl FnMut(usize, &[u8]),
) {
    if from == to {
        put(0, data);
        return;
    }
    let (ours, theirs) = (from.planes(), to.planes());
    // RGBA, luma and NV12's chroma: row by row as they come.
    let as_they_come = if from.format == to.format {
        ours.len()
    } else {
        1
    };
    for (a, b) in ours.iter().zip(&theirs).take(as_they_come) {
        let n = a.bytes as usize;
        for r in 0..a.rows {
            let s = (a.offset + r * a.stride) as usize;
            put((b.offset + r * b.stride) as usize, &data[s..s + n]);
        }
    }
    if let ([_, u, v], [_, uv]) = (&ours[..], &theirs[..]) {
        let mut pairs = vec![0u8; 2 * u.bytes as usize];
        for r in 0..u.rows {
            let row = |p: &PlaneRows| {
                let s = (p.offset + r * p.stride) as usize;
                &data[s..s + p.bytes as usize]
            };
            for ((pair, cb), cr) in pairs.chunks_exact_mut(2).zip(row(u)).zip(row(v)) {
                pair[0] = *cb;
                pair[1] = *cr;
            }
            put((uv.offset + r * uv.stride) as usize, &pairs);
        }
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

    #[test]
    fn upload_rows_suit_texture_copies_in_every_plane_and_4_2_0_arrives_as_nv12() {
        for format in [PixelFormat::Rgba, PixelFormat::I420, PixelFormat::Nv12] {
            let l = upload_layout(&PlaneLayout::tight(format, 1002, 566).unwrap());
            assert_eq!(l.stride % COPY_ALIGN, 0, "{format}");
            let want = match format {
                PixelFormat::Rgba => PixelFormat::Rgba,
                _ => PixelFormat::Nv12,
            };
            assert_eq!(l.format, want);
            if want == PixelFormat::Nv12 {
                assert_eq!(l.chroma_stride % COPY_ALIGN, 0);
            }
        }
        let tight = PlaneLayout::tight(PixelFormat::Nv12, 3840, 2160).unwrap();
        assert_eq!(upload_layout(&tight), tight, "4K NV12 needs no padding");
    }

    #[test]
    fn host_levels_are_rounded_box_means_over_the_ingest_cover_and_black_around_it() {
        // 64x40 NV12, every luma and chroma sample distinct enough; imaged box columns 32..64
        // and rows 0..34, which the ingest's 16x4 blocks cover as rows 0..36.
        let nv12 = PlaneLayout::tight(PixelFormat::Nv12, 64, 40).unwrap();
        let mut data = vec![0u8; nv12.size as usize];
        for (i, b) in data.iter_mut().enumerate() {
            *b = (i * 37 % 241) as u8;
        }
        let specs = SourcePlanes::new(PixelFormat::Nv12, 64, 40);
        let imaged = (32..64, 0..34);
        let mut levels = specs.black_levels();
        specs.make_levels(&data, &nv12, &imaged, &mut levels);
        let luma = |x: usize, y: usize| data[y * 64 + x] as u32;
        let (l1, l2) = (specs.planes[0].regions[0], specs.planes[0].regions[1]);
        let at = |r: Region, x: u32, y: u32, ch: u32| {
            levels[(r.offset + y * r.stride + x * ch) as usize]
        };
        let mean = |s: u32| ((s + 2) / 4) as u8;
        let box_mean = |x: usize, y: usize| {
            mean(
                luma(2 * x, 2 * y)
                    + luma(2 * x + 1, 2 * y)
                    + luma(2 * x, 2 * y + 1)
                    + luma(2 * x + 1, 2 * y + 1),
            )
        };
        for y in 0..18 {
            for x in 16..32 {
                assert_eq!(
                    at(l1, x, y, 1),
                    box_mean(x as usize, y as usize),
                    "({x}, {y})"
                );
            }
        }
        // Left of the box, and below the cover (level 1 row 18 of 20): black.
        assert_eq!((at(l1, 15, 3, 1), at(l1, 20, 18, 1)), (16, 16));
        // Level 2 from level 1, over the cover's quarter.
        let l2_mean = mean(
            [(16, 4), (17, 4), (16, 5), (17, 5)]
                .map(|(x, y)| at(l1, x, y, 1) as u32)
                .iter()
                .sum(),
        );
        assert_eq!(at(l2, 8, 2, 1), l2_mean);
        assert_eq!(at(l2, 7, 2, 1), 16);
        // Chroma level 1 (the frame's level 2): each channel's mean of 2x2 pairs.
        let c1 = specs.planes[1].regions[0];
        let chroma = |c: usize, x: usize, y: usize| {
            data[nv12.chroma[0] as usize + y * 64 + 2 * x + c] as u32
        };
        for c in 0..2 {
            let m = (chroma(c, 18, 8) + chroma(c, 19, 8)) + (chroma(c, 18, 9) + chroma(c, 19, 9));
            assert_eq!(
                levels[(c1.offset + 4 * c1.stride + 9 * 2) as usize + c],
                mean(m)
            );
        }
        assert_eq!(at(c1, 7, 4, 2), 128);
        // I420 of the same picture makes the same levels.
        let i420 = PlaneLayout::tight(PixelFormat::I420, 64, 40).unwrap();
        let mut planar = vec![0u8; i420.size as usize];
        planar[..64 * 40].copy_from_slice(&data[..64 * 40]);
        for by in 0..20 {
            for bx in 0..32 {
                let ((u, v), (cb, cr)) = (i420.chroma_at(bx, by), nv12.chroma_at(bx, by));
                (planar[u], planar[v]) = (data[cb], data[cr]);
            }
        }
        let mut again = specs.black_levels();
        specs.make_levels(&planar, &i420, &imaged, &mut again);
        assert!(again == levels, "I420 and NV12 levels differ");
    }

    #[test]
    fn rows_halve_to_rounded_means_at_every_width_and_texel_size() {
        // The vectorised bodies and the texels after them, for luma, pairs and RGBA.
        for ch in [1, 2, 4] {
            for w in 0..40 {
                let top: Vec<u8> = (0..2 * w * ch).map(|i| (i * 89 % 256) as u8).collect();
                let bottom: Vec<u8> = (0..2 * w * ch).map(|i| (i * 53 % 251) as u8).collect();
                let mut out = vec![0; w * ch];
                halve_row(ch, &top, &bottom, &mut out);
                for x in 0..w {
                    for c in 0..ch {
                        let at = 2 * x * ch + c;
                        let sum: u32 = [top[at], top[at + ch], bottom[at], bottom[at + ch]]
                            .iter()
                            .map(|&b| b as u32)
                            .sum();
                        let want = ((sum + 2) / 4) as u8;
                        assert_eq!(out[x * ch + c], want, "{ch} bytes, width {w}, ({x}, {c})");
                    }
                }
            }
        }
    }

    /// `data` copied for upload into a buffer laid out as its upload layout.
    fn uploaded(data: &[u8], from: &PlaneLayout) -> (Vec<u8>, PlaneLayout) {
        let to = upload_layout(from);
        let mut buffer = vec![0xee; to.size as usize];
        copy_for_upload(data, from, &to, |at, bytes| {
            buffer[at..at + bytes.len()].copy_from_slice(bytes)
        });
        (buffer, to)
    }

    #[test]
    fn i420_arrives_woven_into_nv12_pairs_with_every_sample_where_it_belongs() {
        // Every sample distinct in its plane: luma from its position, Cb and Cr apart.
        let from = PlaneLayout::tight(PixelFormat::I420, 36, 10).unwrap();
        let mut data = vec![0u8; from.size as usize];
        for y in 0..10 {
            for x in 0..36 {
                data[(y * 36 + x) as usize] = (y * 36 + x) as u8;
            }
        }
        for by in 0..5 {
            for bx in 0..18 {
                let (u, v) = from.chroma_at(bx, by);
                data[u] = (by * 18 + bx) as u8;
                data[v] = 100 + (by * 18 + bx) as u8;
            }
        }
        let (buffer, to) = uploaded(&data, &from);
        assert_eq!(to.format, PixelFormat::Nv12);
        for y in 0..10 {
            for x in 0..36 {
                let at = (y * to.stride + x) as usize;
                assert_eq!(buffer[at], (y * 36 + x) as u8, "luma ({x}, {y})");
            }
        }
        for by in 0..5 {
            for bx in 0..18 {
                let (cb, cr) = to.chroma_at(bx, by);
                let want = (by * 18 + bx) as u8;
                assert_eq!((buffer[cb], buffer[cr]), (want, 100 + want), "({bx}, {by})");
            }
        }
        // Row padding is left as it was: only picture bytes are written.
        assert_eq!(buffer[36], 0xee);
    }

    #[test]
    fn frames_already_in_their_upload_layout_are_copied_whole_and_others_row_by_row() {
        let nv12 = PlaneLayout::tight(PixelFormat::Nv12, 3840, 2160).unwrap();
        let data: Vec<u8> = (0..nv12.size).map(|i| (i % 251) as u8).collect();
        assert_eq!(uploaded(&data, &nv12).0, data);
        let rgba = PlaneLayout::tight(PixelFormat::Rgba, 3, 2).unwrap();
        let (buffer, to) = uploaded(&(1..=24).collect::<Vec<u8>>(), &rgba);
        assert_eq!(to.stride, 256);
        assert_eq!(&buffer[..12], &(1..=12).collect::<Vec<u8>>()[..]);
        assert_eq!(&buffer[256..268], &(13..=24).collect::<Vec<u8>>()[..]);
    }
}
