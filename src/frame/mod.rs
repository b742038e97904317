//! Frames as plain bytes, the data every stage of the path hands on: the pixel formats frames
//! come in and go out in (RGBA8 for images, the camera-native and encoder-native 4:2:0 layouts
//! I420 and NV12), where each plane sits in a buffer, BT.709 conversion to and from RGB
//! (`yuv`), and one camera frame with its capture time. Sources make them, the renderers read
//! and write them, the encoder takes them; nothing here knows about any of those.

pub mod yuv;

use std::fmt;

#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum PixelFormat {
    /// Four bytes per pixel, R G B A.
    Rgba,
    /// 4:2:0 planar: Y, then U, then V, each chroma plane half size both ways.
    I420,
    /// 4:2:0 semi-planar: Y, then interleaved U V at half size both ways.
    Nv12,
}

impl PixelFormat {
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Rgba => "rgba",
            PixelFormat::I420 => "i420",
            PixelFormat::Nv12 => "nv12",
        }
    }

    /// The code the shaders use (`FORMAT_*` in shaders/common.wgsl).
    pub fn shader_code(self) -> u32 {
        self as u32
    }

    pub fn is_yuv(self) -> bool {
        self != PixelFormat::Rgba
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    #[error("a {0} frame needs an even width and height (got {1}x{2})")]
    OddSize(PixelFormat, u32, u32),
    #[error("a frame must be at least 1x1 (got {0}x{1})")]
    Empty(u32, u32),
    #[error("a {format} {width}x{height} frame is {want} bytes; got {got}")]
    Length {
        format: PixelFormat,
        width: u32,
        height: u32,
        want: usize,
        got: usize,
    },
}

/// One camera frame: its bytes, how they are laid out, and when the sensor captured it.
#[derive(Clone, Debug)]
pub struct Frame {
    pub data: Vec<u8>,
    pub layout: PlaneLayout,
    /// Microseconds on the monotonic clock the sources stamp frames with
    /// (`crate::clock::clock_us`).
    pub captured_us: u64,
}

impl Frame {
    /// The frame's luma: the Y plane as it is, or RGBA's luma; None for a buffer smaller than
    /// its layout.
    pub fn luma(&self) -> Option<image::GrayImage> {
        let l = &self.layout;
        let rows = |bytes: u32| -> Vec<u8> {
            self.data
                .chunks(l.stride as usize)
                .take(l.height as usize)
                .flat_map(|row| row.get(..bytes as usize).unwrap_or(&[]))
                .copied()
                .collect()
        };
        if l.format == PixelFormat::Rgba {
            let rgba = image::RgbaImage::from_raw(l.width, l.height, rows(l.width * 4))?;
            return Some(image::DynamicImage::ImageRgba8(rgba).to_luma8());
        }
        image::GrayImage::from_raw(l.width, l.height, rows(l.width))
    }
}

/// One plane's rows in a frame's buffer, in bytes: where the first starts, how far apart they
/// are, how many bytes of picture each holds (the rest is padding), and how many there are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneRows {
    pub offset: u32,
    pub stride: u32,
    pub bytes: u32,
    pub rows: u32,
}

/// Where the planes of one frame sit in its buffer. Strides and offsets in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PlaneLayout {
    pub format: PixelFormat,
    pub width: u32,
    pub height: u32,
    /// Row stride of the RGBA plane or the Y plane.
    pub stride: u32,
    /// Row stride of the chroma plane(s); 0 for RGBA.
    pub chroma_stride: u32,
    /// Offsets of U (or UV for NV12) and V; 0 for RGBA.
    pub chroma: [u32; 2],
    /// Bytes in all.
    pub size: u32,
}

impl PlaneLayout {
    /// Rows packed with no padding (what `image` and GStreamer use for even widths).
    pub fn tight(format: PixelFormat, width: u32, height: u32) -> Result<Self, FrameError> {
        Self::aligned(format, width, height, 1)
    }

    /// Luma rows padded to a multiple of `align` pixels (`align` even), chroma rows to match.
    pub fn aligned(
        format: PixelFormat,
        width: u32,
        height: u32,
        align: u32,
    ) -> Result<Self, FrameError> {
        if width == 0 || height == 0 {
            return Err(FrameError::Empty(width, height));
        }
        let padded = width.div_ceil(align) * align;
        if format == PixelFormat::Rgba {
            return Ok(PlaneLayout {
                format,
                width,
                height,
                stride: padded * 4,
                chroma_stride: 0,
                chroma: [0, 0],
                size: padded * 4 * height,
            });
        }
        if width % 2 == 1 || height % 2 == 1 {
            return Err(FrameError::OddSize(format, width, height));
        }
        let luma = padded * height;
        let (chroma_stride, chroma, size) = match format {
            PixelFormat::I420 => {
                let plane = padded / 2 * height / 2;
                (padded / 2, [luma, luma + plane], luma + 2 * plane)
            }
            _ => (padded, [luma, luma], luma + padded * height / 2),
        };
        Ok(PlaneLayout {
            format,
            width,
            height,
            stride: padded,
            chroma_stride,
            chroma,
            size,
        })
    }

    /// Every plane's rows, in order: RGBA; or Y, then UV (NV12) or U and V (I420).
    pub fn planes(&self) -> Vec<PlaneRows> {
        let (w, h) = (self.width, self.height);
        let plane = |offset, stride, bytes, rows| PlaneRows {
            offset,
            stride,
            bytes,
            rows,
        };
        match self.format {
            PixelFormat::Rgba => vec![plane(0, self.stride, 4 * w, h)],
            PixelFormat::Nv12 => vec![
                plane(0, self.stride, w, h),
                plane(self.chroma[0], self.chroma_stride, w, h / 2),
            ],
            PixelFormat::I420 => vec![
                plane(0, self.stride, w, h),
                plane(self.chroma[0], self.chroma_stride, w / 2, h / 2),
                plane(self.chroma[1], self.chroma_stride, w / 2, h / 2),
            ],
        }
    }

    /// Byte offsets of the U and V samples of 2x2 block (bx, by) of a 4:2:0 layout.
    pub fn chroma_at(&self, bx: u32, by: u32) -> (usize, usize) {
        let row = by * self.chroma_stride;
        let (u, v) = match self.format {
            PixelFormat::I420 => (self.chroma[0] + row + bx, self.chroma[1] + row + bx),
            _ => (
                self.chroma[0] + row + 2 * bx,
                self.chroma[0] + row + 2 * bx + 1,
            ),
        };
        (u as usize, v as usize)
    }

    /// Checks that a buffer holds exactly one frame of this layout.
    pub fn check(&self, data: &[u8]) -> Result<(), FrameError> {
        if data.len() == self.size as usize {
            return Ok(());
        }
        Err(FrameError::Length {
            format: self.format,
            width: self.width,
            height: self.height,
            want: self.size as usize,
            got: data.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tight_layouts_have_the_standard_plane_sizes() {
        let i420 = PlaneLayout::tight(PixelFormat::I420, 1920, 1080).unwrap();
        assert_eq!((i420.stride, i420.chroma_stride), (1920, 960));
        assert_eq!(i420.chroma, [1920 * 1080, 1920 * 1080 + 960 * 540]);
        assert_eq!(i420.size, 1920 * 1080 * 3 / 2);
        let nv12 = PlaneLayout::tight(PixelFormat::Nv12, 1920, 1080).unwrap();
        assert_eq!((nv12.chroma_stride, nv12.size), (1920, 1920 * 1080 * 3 / 2));
        let rgba = PlaneLayout::tight(PixelFormat::Rgba, 3, 2).unwrap();
        assert_eq!((rgba.stride, rgba.size), (12, 24));
    }

    #[test]
    fn padded_rows_keep_whole_words_in_every_plane() {
        let l = PlaneLayout::aligned(PixelFormat::I420, 1366, 768, 8).unwrap();
        assert_eq!((l.stride, l.chroma_stride), (1368, 684));
        assert_eq!(l.chroma[0] % 4, 0);
        assert_eq!(l.chroma[1] % 4, 0);
    }

    #[test]
    fn planes_list_each_plane_rows_with_their_padding() {
        let l = PlaneLayout::aligned(PixelFormat::I420, 1366, 768, 8).unwrap();
        let p = l.planes();
        assert_eq!(p.len(), 3);
        assert_eq!((p[0].stride, p[0].bytes, p[0].rows), (1368, 1366, 768));
        assert_eq!(
            (p[2].offset, p[2].stride, p[2].bytes, p[2].rows),
            (l.chroma[1], 684, 683, 384)
        );
        let nv12 = PlaneLayout::tight(PixelFormat::Nv12, 6, 4)
            .unwrap()
            .planes();
        assert_eq!((nv12[1].offset, nv12[1].bytes, nv12[1].rows), (24, 6, 2));
        let rgba = PlaneLayout::tight(PixelFormat::Rgba, 3, 2)
            .unwrap()
            .planes();
        assert_eq!((rgba[0].bytes, rgba[0].rows), (12, 2));
    }

    #[test]
    fn odd_sizes_and_wrong_lengths_are_errors() {
        assert_eq!(
            PlaneLayout::tight(PixelFormat::Nv12, 641, 480),
            Err(FrameError::OddSize(PixelFormat::Nv12, 641, 480))
        );
        let l = PlaneLayout::tight(PixelFormat::I420, 4, 2).unwrap();
        assert!(l.check(&[0; 12]).is_ok());
        assert!(matches!(
            l.check(&[0; 11]),
            Err(FrameError::Length {
                want: 12,
                got: 11,
                ..
            })
        ));
    }
}
