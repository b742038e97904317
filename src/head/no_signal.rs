//! The frame streamed while the source is down: dark grey with "NO SIGNAL" in the middle, so
//! a viewer sees the head is alive and the camera is not.

use crate::frame::{PixelFormat, PlaneLayout};

/// 5x7 glyphs, one byte per row, bit 4 the leftmost column.
fn glyph(c: char) -> [u8; 7] {
    match c {
        'N' => [0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x11],
        'O' => [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'S' => [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e],
        'I' => [0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e],
        'G' => [0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f],
        'A' => [0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f],
        _ => [0; 7],
    }
}

const TEXT: &str = "NO SIGNAL";
const BACKGROUND_Y: u8 = 40;
const TEXT_Y: u8 = 200;

/// An I420 frame of `width` × `height` (even sizes).
pub fn frame(width: u32, height: u32) -> (Vec<u8>, PlaneLayout) {
    let layout = PlaneLayout::tight(PixelFormat::I420, width, height)
        .expect("output sizes are even and non-zero");
    let mut data = vec![128u8; layout.size as usize];
    data[..(width * height) as usize].fill(BACKGROUND_Y);
    // Each glyph cell is 6x8 units; the text spans about half the width.
    let unit = (width / 2 / (6 * TEXT.len() as u32)).max(1);
    let x0 = (width - unit * 6 * TEXT.len() as u32) / 2;
    let y0 = (height.saturating_sub(unit * 7)) / 2;
    for (i, c) in TEXT.chars().enumerate() {
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..5u32 {
                if bits & (0x10 >> col) == 0 {
                    continue;
                }
                let gx = x0 + (i as u32 * 6 + col) * unit;
                let gy = y0 + row as u32 * unit;
                for y in gy..(gy + unit).min(height) {
                    let at = (y * layout.stride + gx) as usize;
                    let end = (gx + unit).min(width) - gx;
                    data[at..at + end as usize].fill(TEXT_Y);
                }
            }
        }
    }
    (data, layout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_is_bright_on_dark_and_centred() {
        let (data, layout) = frame(640, 480);
        let bright: Vec<(u32, u32)> = (0..480)
            .flat_map(|y| (0..640).map(move |x| (x, y)))
            .filter(|&(x, y)| data[(y * layout.stride + x) as usize] == TEXT_Y)
            .collect();
        assert!(bright.len() > 2000, "{} text pixels", bright.len());
        let (sx, sy) = bright
            .iter()
            .fold((0u64, 0u64), |(a, b), &(x, y)| (a + x as u64, b + y as u64));
        let (cx, cy) = (sx / bright.len() as u64, sy / bright.len() as u64);
        assert!(
            (300..340).contains(&cx) && (220..260).contains(&cy),
            "{cx},{cy}"
        );
    }
}
