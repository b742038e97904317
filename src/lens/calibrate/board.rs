//! The calibration board: an AprilGrid as Kalibr prints it (tag36h11 tags with a two-bit
//! black border, ids row by row from the bottom-left, black squares where the gaps between
//! tags cross), described by a spec such as `cols=6,rows=6,tag=88mm,spacing=0.3`. Its
//! geometry (each tag's corners on the board), its picture for printing, and the shade at any
//! point of it for the synthetic scene.

use crate::units::parse_length;
use glam::DVec2;
use image::GrayImage;

/// Data bits across a tag36h11 tag, and black border bits on each side of them.
const DATA_BITS: u32 = 6;
const BORDER_BITS: u32 = 2;
const TAG_BITS: u32 = DATA_BITS + 2 * BORDER_BITS;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "board `{spec}`: {why} (a board is cols=N,rows=N,tag=LENGTH[,spacing=RATIO], e.g. cols=6,rows=6,tag=88mm,spacing=0.3)"
)]
pub struct BoardError {
    pub spec: String,
    pub why: String,
}

/// An AprilGrid: `cols` × `rows` tags of side `tag` metres (across the black border), with
/// gaps of `spacing` × `tag` between them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Board {
    pub cols: u32,
    pub rows: u32,
    pub tag: f64,
    pub spacing: f64,
}

impl Board {
    pub fn parse(spec: &str) -> Result<Board, BoardError> {
        let fail = |why: String| BoardError {
            spec: spec.to_string(),
            why,
        };
        let (mut cols, mut rows, mut tag, mut spacing) = (None, None, None, 0.3);
        for field in spec.split(',').map(str::trim).filter(|f| !f.is_empty()) {
            let (key, value) = field
                .split_once('=')
                .ok_or_else(|| fail(format!("`{field}` is not key=value")))?;
            let count = || {
                value
                    .parse::<u32>()
                    .map_err(|_| fail(format!("{key}: `{value}` is not a whole number")))
            };
            match key.trim() {
                "cols" => cols = Some(count()?),
                "rows" => rows = Some(count()?),
                "tag" => tag = Some(parse_length(value).map_err(|e| fail(e.to_string()))?),
                "spacing" => {
                    spacing = value
                        .parse()
                        .map_err(|_| fail(format!("spacing: `{value}` is not a number")))?
                }
                other => return Err(fail(format!("no field `{other}`"))),
            }
        }
        let (Some(cols), Some(rows), Some(tag)) = (cols, rows, tag) else {
            return Err(fail("cols, rows and tag are needed".into()));
        };
        let tags = aprilgrid::tag_families::T36H11.len() as u32;
        if cols < 2 || rows < 2 || cols * rows > tags {
            return Err(fail(format!(
                "{cols}x{rows} tags: at least 2x2, and at most {tags} tags (tag36h11 has {tags})"
            )));
        }
        if !(0.1..=1.0).contains(&spacing) {
            return Err(fail(format!("spacing {spacing} is outside 0.1..=1.0")));
        }
        Ok(Board {
            cols,
            rows,
            tag,
            spacing,
        })
    }

    /// The gap between tags, metres.
    pub fn gap(&self) -> f64 {
        self.tag * self.spacing
    }

    /// From one tag's corner to the next tag's same corner, metres.
    pub fn pitch(&self) -> f64 {
        self.tag + self.gap()
    }

    pub fn tags(&self) -> u32 {
        self.cols * self.rows
    }

    /// The printed board's lower-left and upper-right corners, metres: the corner squares
    /// and a white margin one gap wide around them.
    pub fn extent(&self) -> (DVec2, DVec2) {
        let margin = 2.0 * self.gap();
        let far = DVec2::new(self.cols as f64, self.rows as f64) * self.pitch() + self.gap();
        (DVec2::splat(-margin), far)
    }

    /// Tag `id`'s corners on the board (metres, x right, y up, from tag 0's lower-left corner)
    /// in Kalibr's order: lower-left, lower-right, upper-right, upper-left.
    pub fn corners(&self, id: u32) -> Option<[DVec2; 4]> {
        if id >= self.tags() {
            return None;
        }
        let o = DVec2::new((id % self.cols) as f64, (id / self.cols) as f64) * self.pitch();
        let s = self.tag;
        Some([
            o,
            o + DVec2::new(s, 0.0),
            o + DVec2::new(s, s),
            o + DVec2::new(0.0, s),
        ])
    }

    /// The board's shade at point `p` (metres): 0 black, 1 white; None off the printed board.
    pub fn shade(&self, p: DVec2) -> Option<f64> {
        let (low, high) = self.extent();
        if p.x < low.x || p.y < low.y || p.x >= high.x || p.y >= high.y {
            return None;
        }
        let pitch = self.pitch();
        let (tx, ty) = ((p.x / pitch).floor(), (p.y / pitch).floor());
        let (u, v) = (p.x - tx * pitch, p.y - ty * pitch);
        let (in_x, in_y) = (u < self.tag, v < self.tag);
        let (tx, ty) = (tx as i64, ty as i64);
        let on_grid = |t: i64, n: u32, inside: bool| {
            if inside {
                (0..n as i64).contains(&t)
            } else {
                (-1..n as i64).contains(&t)
            }
        };
        if !on_grid(tx, self.cols, in_x) || !on_grid(ty, self.rows, in_y) {
            return Some(1.0); // the margin
        }
        Some(match (in_x, in_y) {
            (false, false) => 0.0, // a corner square
            (true, true) => {
                let id = ty as u32 * self.cols + tx as u32;
                let bits = TAG_BITS as f64 / self.tag;
                let col = (u * bits) as u32;
                let row = TAG_BITS - 1 - (v * bits) as u32; // from the tag's top
                tag_bit(id, col, row)
            }
            _ => 1.0,
        })
    }

    /// The board to print at `dots_per_metre`, each pixel the mean of 4 × 4 samples.
    pub fn picture(&self, dots_per_metre: f64) -> GrayImage {
        let (low, high) = self.extent();
        let size = (high - low) * dots_per_metre;
        let (w, h) = (size.x.round() as u32, size.y.round() as u32);
        GrayImage::from_fn(w, h, |x, y| {
            let mut sum = 0.0;
            for i in 0..4 {
                for j in 0..4 {
                    let d = DVec2::new(
                        x as f64 + (i as f64 + 0.5) / 4.0,
                        y as f64 + (j as f64 + 0.5) / 4.0,
                    );
                    let p = DVec2::new(low.x + d.x / dots_per_metre, high.y - d.y / dots_per_metre);
                    sum += self.shade(p).unwrap_or(1.0);
                }
            }
            image::Luma([(sum / 16.0 * 255.0).round() as u8])
        })
    }
}

/// Bit (col, row) of tag `id`, counted from its top-left including the border: 0 black, 1 white.
fn tag_bit(id: u32, col: u32, row: u32) -> f64 {
    let data = BORDER_BITS..BORDER_BITS + DATA_BITS;
    if !data.contains(&col) || !data.contains(&row) {
        return 0.0;
    }
    let code = aprilgrid::tag_families::T36H11[id as usize];
    let index = (row - BORDER_BITS) * DATA_BITS + (col - BORDER_BITS);
    ((code >> (DATA_BITS * DATA_BITS - 1 - index)) & 1) as f64
}
