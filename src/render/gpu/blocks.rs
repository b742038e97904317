//! Which view draws each 8x2 block of the output frame (the block one draw invocation
//! writes), worked out on the CPU when the frame's rectangles change. Most blocks lie inside
//! one view (or in no view), so the draw pass fetches that view once per block instead of
//! searching the rectangles for each of its 16 pixels; the few blocks that straddle a view's
//! edge or the frame's edge are listed for a second, per-pixel dispatch.

use crate::layout::Rect;

/// Output pixels in one block, across and down (`draw` in shaders/render.wgsl).
pub const BLOCK_W: u32 = 8;
pub const BLOCK_H: u32 = 2;
/// A block drawn by the per-pixel dispatch (`MIXED` in shaders/render.wgsl).
pub const MIXED: u32 = u32::MAX - 1;
/// A block no view covers: black (`NO_VIEW`, -1 as i32, in shaders/render.wgsl).
pub const NO_VIEW: u32 = u32::MAX;

/// The block table, row by row, followed by the mixed blocks' coordinates (`bx | by << 16`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockMap {
    pub width: u32,
    pub height: u32,
    pub rects: Vec<Rect>,
    /// One entry per block: the view index, [`NO_VIEW`] or [`MIXED`].
    pub table: Vec<u32>,
    pub mixed: Vec<u32>,
}

impl BlockMap {
    /// The blocks of a `width` x `height` frame whose views are `rects`, a later rectangle
    /// covering an earlier one (tiles over views), as the per-pixel lookup has it.
    pub fn new(width: u32, height: u32, rects: &[Rect]) -> Self {
        let (across, down) = (width.div_ceil(BLOCK_W), height.div_ceil(BLOCK_H));
        let padded = (across * BLOCK_W) as usize;
        // A pixel past the frame's edge is padding: its block goes per pixel, which draws it
        // black as the frame's edge needs.
        const PADDING: u32 = u32::MAX - 2;
        let paint_row = |y: u32, row: &mut Vec<u32>| {
            row.clear();
            row.resize(padded, PADDING);
            if y >= height {
                return;
            }
            row[..width as usize].fill(NO_VIEW);
            for (i, r) in rects.iter().enumerate() {
                if y >= r.y && y < r.bottom() {
                    let end = r.right().min(width) as usize;
                    row[(r.x as usize).min(end)..end].fill(i as u32);
                }
            }
        };
        let mut table = Vec::with_capacity((across * down) as usize);
        let mut mixed = Vec::new();
        let (mut top, mut bottom) = (Vec::new(), Vec::new());
        for by in 0..down {
            paint_row(by * BLOCK_H, &mut top);
            paint_row(by * BLOCK_H + 1, &mut bottom);
            for bx in 0..across {
                let span = (bx * BLOCK_W) as usize..((bx + 1) * BLOCK_W) as usize;
                let first = top[span.start];
                let uniform = top[span.clone()]
                    .iter()
                    .chain(&bottom[span])
                    .all(|&v| v == first);
                if uniform && first != PADDING {
                    table.push(first);
                } else {
                    table.push(MIXED);
                    mixed.push(bx | by << 16);
                }
            }
        }
        BlockMap {
            width,
            height,
            rects: rects.to_vec(),
            table,
            mixed,
        }
    }

    /// Whether this map was made for these rectangles in a frame of this size.
    pub fn is_for(&self, width: u32, height: u32, rects: &[Rect]) -> bool {
        (self.width, self.height) == (width, height) && self.rects == rects
    }

    /// What the shader reads: the table, then the mixed list.
    pub fn words(&self) -> Vec<u32> {
        [self.table.as_slice(), &self.mixed].concat()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::layout;
    use crate::modes::{LayoutMode, OverlayMode};

    /// The view at a pixel as the shader's per-pixel lookup finds it: the last rectangle
    /// containing it.
    fn view_at(rects: &[Rect], x: u32, y: u32) -> u32 {
        rects
            .iter()
            .rposition(|r| r.contains(x, y))
            .map_or(NO_VIEW, |i| i as u32)
    }

    fn check(width: u32, height: u32, rects: &[Rect]) -> BlockMap {
        let map = BlockMap::new(width, height, rects);
        let across = width.div_ceil(BLOCK_W);
        assert_eq!(map.table.len() as u32, across * height.div_ceil(BLOCK_H));
        for (i, &entry) in map.table.iter().enumerate() {
            let (bx, by) = (i as u32 % across, i as u32 / across);
            if entry == MIXED {
                assert!(map.mixed.contains(&(bx | by << 16)));
                continue;
            }
            for y in by * BLOCK_H..(by + 1) * BLOCK_H {
                for x in bx * BLOCK_W..(bx + 1) * BLOCK_W {
                    assert!(x < width && y < height, "block {bx},{by} has padding");
                    assert_eq!(view_at(rects, x, y), entry, "pixel {x},{y}");
                }
            }
        }
        map
    }

    #[test]
    fn blocks_inside_one_view_name_it_and_the_rest_are_listed() {
        // The benchmark's layout: four 540-px squares (one edge at x = 900, not a multiple
        // of 8) and the detection column at x = 1800.
        let l = layout(1920, 1080, LayoutMode::Four, OverlayMode::Right).unwrap();
        let rects: Vec<Rect> = l.views.iter().map(|(r, _)| *r).chain(l.tiles).collect();
        let map = check(1920, 1080, &rects);
        // Only the column of blocks across x = 900 is mixed.
        assert_eq!(map.mixed.len(), 540);
        assert!(map.mixed.iter().all(|b| b & 0xffff == 900 / 8));
    }

    #[test]
    fn padding_odd_edges_and_overlaps_go_per_pixel() {
        let rects = [
            Rect::new(0, 0, 101, 51),
            Rect::new(3, 5, 20, 1),
            Rect::new(64, 0, 37, 120),
        ];
        let map = check(101, 121, &rects);
        // The last column (padding past x = 100) and the last row (y = 121 is past the frame).
        let across = 101u32.div_ceil(8);
        assert_eq!(map.table[(across - 1) as usize], MIXED);
        assert_eq!(map.table[(60 * across) as usize], MIXED);
        // A block fully covered by the later, overlapping rectangle names it.
        assert_eq!(map.table[(10 * across + 8) as usize], 2);
        // Below the first rectangle and left of the third: no view.
        assert_eq!(map.table[(40 * across) as usize], NO_VIEW);
    }

    #[test]
    fn every_layout_maps_exactly() {
        for (w, h) in [(640, 480), (1280, 720), (1366, 768), (1001, 603)] {
            for &mode in LayoutMode::ALL {
                for &overlay in OverlayMode::ALL {
                    if let Ok(l) = layout(w, h, mode, overlay) {
                        let rects: Vec<Rect> =
                            l.views.iter().map(|(r, _)| *r).chain(l.tiles).collect();
                        check(w, h, &rects);
                    }
                }
            }
        }
    }
}
