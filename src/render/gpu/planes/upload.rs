//! How frames lie in the upload buffers: RGBA, or NV12 for 4:2:0 (I420's two chroma planes
//! woven into NV12's Cb Cr pairs on the way), with every plane's rows padded as texture copies
//! need.

use super::COPY_ALIGN;
use crate::frame::{PixelFormat, PlaneLayout, PlaneRows};

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
