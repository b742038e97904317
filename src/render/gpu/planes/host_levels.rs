//! The mip filter's levels made on the host, byte for byte what the ingest and mip passes
//! make: on a software rasterizer the passes are CPU work too, and their storage-buffer loads
//! are checked and branched on lane by lane, so a vectorised loop here takes a fraction of
//! their time (docs/performance.md).

use super::{INGEST_BLOCK, SourcePlanes};
use crate::frame::{PixelFormat, PlaneLayout, PlaneRows};
use crate::render::mip::ImagedBox;
use std::ops::Range;

impl SourcePlanes {
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

#[cfg(test)]
mod tests {
    use super::super::Region;
    use super::*;

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
}
