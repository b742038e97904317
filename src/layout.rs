//! Where everything sits in the output frame: the user views of each layout mode, the
//! detection overlay strip and its 120x120 tiles (conventions.md, "Layouts").
//!
//! Pure integer geometry: the renderers draw exactly these rectangles and VIDEO_OUTPUT reports
//! exactly these rectangles.

use crate::modes::{LayoutMode, OverlayMode};
use serde::Serialize;

/// single_detection_size: the side of a detection tile.
pub const TILE_SIZE: u32 = 120;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

impl Rect {
    pub const fn new(x: u32, y: u32, w: u32, h: u32) -> Self {
        Rect { x, y, w, h }
    }
    pub fn right(&self) -> u32 {
        self.x + self.w
    }
    pub fn bottom(&self) -> u32 {
        self.y + self.h
    }
    pub fn area(&self) -> u64 {
        self.w as u64 * self.h as u64
    }
    pub fn overlaps(&self, o: &Rect) -> bool {
        self.x < o.right() && o.x < self.right() && self.y < o.bottom() && o.y < self.bottom()
    }
    pub fn contains(&self, px: u32, py: u32) -> bool {
        px >= self.x && px < self.right() && py >= self.y && py < self.bottom()
    }
}

/// What a view slot shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Slot {
    Square,
    Panorama,
    /// Layout 6: the whole fisheye frame, no camera input.
    Debug,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Layout {
    pub width: u32,
    pub height: u32,
    /// View i is user camera i.
    pub views: Vec<(Rect, Slot)>,
    /// The whole overlay strip (or the single tile of mode 1); all zero for mode 0.
    pub overlay_box: Rect,
    pub tiles: Vec<Rect>,
}

#[derive(Debug, PartialEq, Eq, thiserror::Error)]
#[error("output {0}x{1} is too small for layout {2} with overlay {3}")]
pub struct LayoutError(pub u32, pub u32, pub u8, pub u8);

/// The rectangles of a layout mode and overlay mode in a `width` × `height` frame.
pub fn layout(
    width: u32,
    height: u32,
    mode: LayoutMode,
    overlay: OverlayMode,
) -> Result<Layout, LayoutError> {
    let too_small = LayoutError(width, height, mode.code(), overlay.code());
    let s = TILE_SIZE;
    // The overlay reserves its strip first; the views fill what is left (`area`).
    let (overlay_box, area, tiles) = match overlay {
        OverlayMode::None => (Rect::default(), Rect::new(0, 0, width, height), vec![]),
        OverlayMode::OneTile => {
            if width < s || height < s {
                return Err(too_small);
            }
            let tile = Rect::new(width - s, 0, s, s);
            (tile, Rect::new(0, 0, width, height), vec![tile])
        }
        OverlayMode::Right | OverlayMode::Left => {
            if width <= s || height < s {
                return Err(too_small);
            }
            let right = overlay == OverlayMode::Right;
            let x = if right { width - s } else { 0 };
            let strip = Rect::new(x, 0, s, height);
            let area = Rect::new(if right { 0 } else { s }, 0, width - s, height);
            (
                strip,
                area,
                (0..height / s).map(|i| Rect::new(x, i * s, s, s)).collect(),
            )
        }
        OverlayMode::Top | OverlayMode::Bottom => {
            if height <= s || width < s {
                return Err(too_small);
            }
            let top = overlay == OverlayMode::Top;
            let y = if top { 0 } else { height - s };
            let strip = Rect::new(0, y, width, s);
            let area = Rect::new(0, if top { s } else { 0 }, width, height - s);
            (
                strip,
                area,
                (0..width / s).map(|i| Rect::new(i * s, y, s, s)).collect(),
            )
        }
    };
    let views = place_views(area, mode);
    if views.iter().any(|(r, _)| r.w == 0 || r.h == 0) {
        return Err(too_small);
    }
    Ok(Layout {
        width,
        height,
        views,
        overlay_box,
        tiles,
    })
}

/// A row of `n` squares of side `side` centred horizontally in `area`, at `y`.
fn square_row(area: Rect, n: u32, side: u32, y: u32) -> impl Iterator<Item = (Rect, Slot)> {
    let x0 = area.x + (area.w - n * side) / 2;
    (0..n).map(move |i| (Rect::new(x0 + i * side, y, side, side), Slot::Square))
}

fn place_views(a: Rect, mode: LayoutMode) -> Vec<(Rect, Slot)> {
    use LayoutMode::*;
    match mode {
        // One square, centred.
        One => {
            let side = a.w.min(a.h);
            square_row(a, 1, side, a.y + (a.h - side) / 2).collect()
        }
        // Two squares stacked, centred.
        TwoStacked => {
            let side = a.w.min(a.h / 2);
            let y0 = a.y + (a.h - 2 * side) / 2;
            square_row(a, 1, side, y0)
                .chain(square_row(a, 1, side, y0 + side))
                .collect()
        }
        // Two full-width panoramas stacked.
        TwoPanoramas => {
            let h = a.h / 2;
            (0..2)
                .map(|i| (Rect::new(a.x, a.y + i * h, a.w, h), Slot::Panorama))
                .collect()
        }
        // n squares on top of one full-width panorama that takes the rest of the height; the
        // squares take at most two thirds of it so the panorama stays useful.
        TwoAndPanorama | ThreeAndPanorama => {
            let n = if mode == TwoAndPanorama { 2 } else { 3 };
            let side = (a.w / n).min(2 * a.h / 3);
            let mut v: Vec<_> = square_row(a, n, side, a.y).collect();
            v.push((Rect::new(a.x, a.y + side, a.w, a.h - side), Slot::Panorama));
            v
        }
        // Four squares, 2 × 2, centred.
        Four => {
            let side = (a.w / 2).min(a.h / 2);
            let y0 = a.y + (a.h - 2 * side) / 2;
            square_row(a, 2, side, y0)
                .chain(square_row(a, 2, side, y0 + side))
                .collect()
        }
        Whole => vec![(a, Slot::Debug)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn layout(w: u32, h: u32, mode: u8, overlay: u8) -> Result<Layout, LayoutError> {
        let (mode, overlay) = (LayoutMode::try_from(mode), OverlayMode::try_from(overlay));
        super::layout(w, h, mode.unwrap(), overlay.unwrap())
    }

    #[test]
    fn the_reference_layout_four_views_with_a_right_column() {
        let l = layout(1920, 1080, 4, 2).unwrap();
        let rects: Vec<Rect> = l.views.iter().map(|v| v.0).collect();
        assert_eq!(
            rects,
            vec![
                Rect::new(360, 0, 540, 540),
                Rect::new(900, 0, 540, 540),
                Rect::new(360, 540, 540, 540),
                Rect::new(900, 540, 540, 540)
            ]
        );
        assert_eq!(l.overlay_box, Rect::new(1800, 0, 120, 1080));
        assert_eq!(l.tiles.len(), 9);
    }

    #[test]
    fn tile_counts_follow_the_seeds_floor_formula() {
        assert_eq!(layout(1920, 1080, 0, 4).unwrap().tiles.len(), 16);
        assert_eq!(layout(640, 480, 0, 3).unwrap().tiles.len(), 4);
        assert_eq!(layout(1000, 700, 0, 5).unwrap().tiles.len(), 8);
        assert_eq!(layout(1000, 700, 0, 1).unwrap().tiles.len(), 1);
        assert_eq!(layout(1000, 700, 0, 0).unwrap().tiles.len(), 0);
    }

    proptest! {
        #[test]
        fn every_layout_is_well_formed(w in 640u32..=1920, h in 480u32..=1080, mode in 0u8..7, overlay in 0u8..6) {
            let l = layout(w, h, mode, overlay).unwrap();
            let expect_views = [1, 2, 2, 3, 4, 4, 1][mode as usize];
            prop_assert_eq!(l.views.len(), expect_views);
            for (i, (r, slot)) in l.views.iter().enumerate() {
                prop_assert!(r.w > 0 && r.h > 0);
                prop_assert!(r.right() <= w && r.bottom() <= h, "view {} {:?} outside {}x{}", i, r, w, h);
                match slot {
                    Slot::Square => prop_assert_eq!(r.w, r.h, "squares are square"),
                    Slot::Panorama => {
                        let strip_w = if overlay == 2 || overlay == 3 { TILE_SIZE } else { 0 };
                        prop_assert_eq!(r.w, w - strip_w, "panoramas span the area's full width");
                    }
                    Slot::Debug => {}
                }
                for (other, _) in &l.views[i + 1..] {
                    prop_assert!(!r.overlaps(other), "{:?} overlaps {:?}", r, other);
                }
                if overlay >= 2 {
                    prop_assert!(!r.overlaps(&l.overlay_box), "overlay {} covers view {}", overlay, i);
                }
            }
            // Views are numbered left to right, then top to bottom, squares before panoramas.
            for pair in l.views.windows(2) {
                let (a, b) = (pair[0].0, pair[1].0);
                prop_assert!(a.y < b.y || (a.y == b.y && a.x < b.x));
            }
            let limit = match overlay { 2 | 3 => h / TILE_SIZE, 4 | 5 => w / TILE_SIZE, 1 => 1, _ => 0 };
            prop_assert_eq!(l.tiles.len() as u32, limit);
            for (i, t) in l.tiles.iter().enumerate() {
                prop_assert!(t.w == TILE_SIZE && t.h == TILE_SIZE);
                prop_assert!(t.right() <= w && t.bottom() <= h);
                if overlay >= 2 {
                    prop_assert!(t.x >= l.overlay_box.x && t.right() <= l.overlay_box.right());
                    prop_assert!(t.y >= l.overlay_box.y && t.bottom() <= l.overlay_box.bottom());
                }
                for u in &l.tiles[i + 1..] {
                    prop_assert!(!t.overlaps(u));
                }
            }
        }
    }
}
