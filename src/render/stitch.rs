//! The seam of a lens pair, blended in the frame before either renderer reads it. Both
//! renderers draw each ray from the one lens that sees it best (`lens::pair`); here each
//! pixel of either image near the seam takes the blend the ray it sees should have: its own
//! lens's colour and the other lens's for the same ray, weighted by a smooth step across the
//! feather. Both images then hold the same colour for a ray in the overlap, so the switch from
//! one lens to the other shows nothing.
//!
//! The taps (which pixel, where the other lens sees its ray, with what weight) are worked out
//! once per pair and frame layout; a frame then costs one bilinear sample per tap. Only the
//! band the views can reach is done: the feather, and [`REACH`] beyond it on the side a lens
//! is not chosen (mip filtering reads a little past where a view's rays land). Pixels the
//! pair's masks cover (what the airframe hides) take the other lens's colour the same way.

use crate::frame::{PixelFormat, PlaneLayout, PlaneRows};
use crate::lens::Lens;
use crate::lens::pair::{Pair, Side, other, weight_of};
use gains::{Component, MOST_GAIN, MOST_OFFSET, Matching};
use glam::DVec2;
use rayon::prelude::*;

pub mod gains;

/// How far past the feather's edge (radians of margin) a lens's pixels still take the blend:
/// what a coarse mip level at the seam reads from the side that is not drawn.
pub const REACH: f64 = 0.035;

/// The exposure match reads one tap in this many.
const MEAN_STRIDE: usize = 7;

/// One pixel of one plane that takes the blend.
#[derive(Clone, Copy, Debug)]
struct Tap {
    /// Byte offset of the pixel's first channel.
    dst: u32,
    /// Byte offset of the top-left of the four pixels the other lens's sample reads.
    src: u32,
    /// The sample's position between them, in 256ths.
    fx: u8,
    fy: u8,
    /// The other lens's share, in 255ths.
    weight: u8,
    /// Whether the pixel is the second lens's.
    second: bool,
    /// Whether the exposure match reads it: in the seam's band, and neither lens's colour
    /// the airframe (a mask's).
    matched: bool,
}

/// One plane's taps: where its rows lie, how many channels a pixel has, how many frame
/// pixels across one of its pixels is.
#[derive(Clone, Debug)]
struct PlaneTaps {
    rows: PlaneRows,
    channels: u32,
    scale: f64,
    /// In the order of their pixels, row by row.
    taps: Vec<Tap>,
    /// Where each row's taps begin in `taps`, and past the last.
    row_starts: Vec<u32>,
}

/// Where a frame of one layout from one lens pair takes the seam's blend, and which parts of
/// the frame are which lens's (for the exposure match, `gains`).
#[derive(Clone, Debug)]
pub struct Stitch {
    planes: Vec<PlaneTaps>,
    pair: Pair,
    components: Vec<Component>,
}

impl Stitch {
    /// The taps for frames of `layout` through `lens`; None for a lens that is not a pair.
    pub fn new(lens: &Lens, layout: &PlaneLayout) -> Option<Stitch> {
        let pair = lens.pair.as_ref()?;
        let rows = layout.planes();
        let planes = match layout.format {
            PixelFormat::Rgba => vec![plane_taps(pair, &rows[0], 4, 1.0)],
            PixelFormat::Nv12 => vec![
                plane_taps(pair, &rows[0], 1, 1.0),
                plane_taps(pair, &rows[1], 2, 2.0),
            ],
            PixelFormat::I420 => vec![
                plane_taps(pair, &rows[0], 1, 1.0),
                plane_taps(pair, &rows[1], 1, 2.0),
                plane_taps(pair, &rows[2], 1, 2.0),
            ],
        };
        Some(Stitch {
            planes,
            pair: (**pair).clone(),
            components: gains::components(layout.format),
        })
    }

    /// Pixels that take the blend, over every plane.
    pub fn taps(&self) -> usize {
        self.planes.iter().map(|p| p.taps.len()).sum()
    }

    /// `data` into `out` (the same length): each lens's part of the frame put through its
    /// tables (per component, the first lens's and the second's), and the seam blended from
    /// the values so corrected. Rows go in parallel; every value is read from `data`.
    fn stitch_into(&self, data: &[u8], out: &mut [u8], tables: &[[[u8; 256]; 2]]) {
        self.copy_outside_planes(data, out);
        for (p, plane) in self.planes.iter().enumerate() {
            let chans = self.channel_tables(p, tables);
            self.copy_corrected(plane, data, out, &chans);
            blend_into(plane, data, out, &chans);
        }
    }

    /// Plane `p`'s tables, channel by channel: None for a channel not matched (alpha).
    fn channel_tables(&self, p: usize, tables: &[[[u8; 256]; 2]]) -> Vec<Option<[[u8; 256]; 2]>> {
        (0..self.planes[p].channels as usize)
            .map(|ch| {
                let c = self
                    .components
                    .iter()
                    .position(|c| c.plane == p && c.channel == ch);
                c.map(|i| tables[i])
            })
            .collect()
    }

    /// The bytes no plane's rows hold (none in a tight layout), as they are.
    fn copy_outside_planes(&self, data: &[u8], out: &mut [u8]) {
        let mut spans: Vec<(usize, usize)> = self
            .planes
            .iter()
            .map(|p| span(&p.rows, data.len()))
            .collect();
        spans.sort_unstable();
        let mut from = 0;
        for (start, end) in spans.into_iter().chain([(data.len(), data.len())]) {
            if start > from {
                out[from..start].copy_from_slice(&data[from..start]);
            }
            from = from.max(end);
        }
    }

    /// A plane's rows into `out`, each pixel's matched channels through its lens's tables.
    fn copy_corrected(
        &self,
        plane: &PlaneTaps,
        data: &[u8],
        out: &mut [u8],
        chans: &[Option<[[u8; 256]; 2]>],
    ) {
        let n = plane.channels as usize;
        let width = (plane.rows.bytes as usize) / n;
        let (start, end) = span(&plane.rows, data.len());
        let stride = plane.rows.stride as usize;
        let unchanged = chans.iter().flatten().all(|t| t.iter().all(is_identity));
        out[start..end]
            .par_chunks_mut(stride)
            .zip(data[start..end].par_chunks(stride))
            .enumerate()
            .for_each(|(y, (row, from))| {
                row.copy_from_slice(from);
                if unchanged {
                    return;
                }
                let (split, right_is_second) = self.split(plane, y as u32, width);
                let sides = if right_is_second { [0, 1] } else { [1, 0] };
                let len = (width * n).min(row.len());
                let pixels = row[..len].chunks_exact_mut(n);
                for (x, px) in pixels.enumerate() {
                    let side = sides[usize::from(x >= split)];
                    for (v, table) in px.iter_mut().zip(chans) {
                        if let Some(t) = table {
                            *v = t[side][*v as usize];
                        }
                    }
                }
            });
    }
}

/// Where a plane's rows lie in a buffer of `len` bytes.
fn span(rows: &PlaneRows, len: usize) -> (usize, usize) {
    let start = (rows.offset as usize).min(len);
    (
        start,
        ((rows.offset + rows.stride * rows.rows) as usize).min(len),
    )
}

fn is_identity(table: &[u8; 256]) -> bool {
    table.iter().enumerate().all(|(i, &v)| v as usize == i)
}

/// Blends a plane's taps into `out`, rows in parallel: each tap's own value and the other
/// lens's bilinear sample, both read from `data` through their lens's tables.
fn blend_into(plane: &PlaneTaps, data: &[u8], out: &mut [u8], chans: &[Option<[[u8; 256]; 2]>]) {
    let (c, stride) = (plane.channels as usize, plane.rows.stride as usize);
    let (start, end) = span(&plane.rows, data.len());
    out[start..end]
        .par_chunks_mut(stride)
        .enumerate()
        .for_each(|(y, row)| {
            let base = start + y * stride;
            let (from, to) = (
                plane.row_starts[y] as usize,
                plane.row_starts[y + 1] as usize,
            );
            for t in &plane.taps[from..to] {
                let own_side = usize::from(t.second);
                for (ch, table) in chans.iter().enumerate() {
                    // Alpha keeps the pixel's own.
                    let Some(table) = table else { continue };
                    let own = table[own_side][data[t.dst as usize + ch] as usize] as u64;
                    let other = &table[1 - own_side];
                    let sample = sample(data, t, (ch, c, stride), |v| other[v as usize]);
                    let w = t.weight as u64;
                    let mixed = ((own * (255 - w)) << 16) + sample * w;
                    row[t.dst as usize - base + ch] = ((mixed + (255 << 15)) / (255 << 16)) as u8;
                }
            }
        });
}

/// The taps of the last lens and layout asked for, kept while they stay the same: what a
/// renderer holds.
#[derive(Debug, Default)]
pub struct Stitches {
    last: Option<(Lens, PlaneLayout, Option<Stitch>)>,
    matching: Matching,
    /// The last stitched frame (its allocation kept from frame to frame).
    stitched: Vec<u8>,
}

impl Stitches {
    /// A frame's bytes with the seam blended, for frames of `layout` through `lens` (the
    /// bytes as they are for a lens that is not a pair).
    pub fn stitched<'a>(
        &'a mut self,
        lens: &Lens,
        layout: &PlaneLayout,
        data: &'a [u8],
    ) -> &'a [u8] {
        if lens.pair.is_none() {
            return data;
        }
        let fresh = self
            .last
            .as_ref()
            .is_none_or(|(l, at, _)| l != lens || at != layout);
        if fresh {
            self.last = Some((lens.clone(), *layout, Stitch::new(lens, layout)));
            self.matching = Matching::default();
        }
        match self.last.as_ref().and_then(|(_, _, s)| s.as_ref()) {
            Some(stitch) if data.len() == layout.size as usize => {
                self.matching
                    .update(&stitch.components, &stitch.means(data));
                let tables = self.matching.tables(&stitch.components);
                self.stitched.resize(data.len(), 0);
                stitch.stitch_into(data, &mut self.stitched, &tables);
                &self.stitched
            }
            _ => data,
        }
    }

    /// What the operator is told of the match: how far the second lens is from the first,
    /// component by component, e.g. `second lens: luma x1.48, Cb +0.0, Cr -1.0 (each
    /// corrected halfway)`. Empty before a pair's first frame.
    pub fn said(&self) -> String {
        let Some((_, layout, Some(stitch))) = &self.last else {
            return String::new();
        };
        let names: &[&str] = match layout.format {
            PixelFormat::Rgba => &["R", "G", "B"],
            PixelFormat::Nv12 | PixelFormat::I420 => &["luma", "Cb", "Cr"],
        };
        let parts: Vec<String> = self
            .matching
            .apart(&stitch.components)
            .iter()
            .zip(names)
            .enumerate()
            .map(|(i, (x, name))| match (layout.format, i) {
                (PixelFormat::Rgba, _) | (_, 0) => format!("{name} x{x:.2}"),
                _ => format!("{name} {x:+.1}"),
            })
            .collect();
        let how = if self.matching.beyond_reach(&stitch.components) {
            format!(
                "more than the match corrects: each lens moved {MOST_GAIN}x or {MOST_OFFSET} \
                 codes at most; is one covered?"
            )
        } else {
            "each corrected halfway".to_string()
        };
        format!("second lens: {} ({how})", parts.join(", "))
    }

    /// How far apart the last pair's lenses are, by component (`gains::Matching::apart`):
    /// what the operator is told of the match. Empty before a pair's first frame.
    pub fn apart(&self) -> Vec<f64> {
        match self.last.as_ref().and_then(|(_, _, s)| s.as_ref()) {
            Some(stitch) => self.matching.apart(&stitch.components),
            None => Vec::new(),
        }
    }
}

impl Stitch {
    /// Each component's mean over the overlap as the first and the second lens see it.
    fn means(&self, data: &[u8]) -> Vec<(f64, f64)> {
        self.components
            .iter()
            .map(|c| {
                let plane = &self.planes[c.plane];
                let (ch, n) = (c.channel, plane.channels as usize);
                let stride = plane.rows.stride as usize;
                // Every MEAN_STRIDE-th tap: the overlap's mean is as good from a sample.
                let (a, b, count) = plane
                    .taps
                    .par_iter()
                    .step_by(MEAN_STRIDE)
                    .filter(|t| t.matched)
                    .map(|t| {
                        let own = data[t.dst as usize + ch] as f64;
                        let other = sample(data, t, (ch, n, stride), |v| v) as f64 / 65536.0;
                        let (a, b) = if t.second { (other, own) } else { (own, other) };
                        (a, b, 1.0)
                    })
                    .reduce(|| (0.0, 0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1, x.2 + y.2));
                (a / f64::max(count, 1.0), b / f64::max(count, 1.0))
            })
            .collect()
    }

    /// Where plane row `y` passes from one lens's part to the other's: the first column of
    /// the part that lies right, and whether that part is the second lens's.
    fn split(&self, plane: &PlaneTaps, y: u32, width: usize) -> (usize, bool) {
        let at = |x: usize| {
            let q = (DVec2::new(x as f64, y as f64) + 0.5) * plane.scale - 0.5;
            self.pair.side_at(q) == Side::Second
        };
        let (left, right) = (at(0), at(width - 1));
        if left == right {
            return (0, right);
        }
        // The side changes once along a row (a half plane): find where.
        let (mut lo, mut hi) = (0, width - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if at(mid) == left {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (hi, right)
    }
}

/// The other lens's bilinear sample of a tap's channel `ch`, each value put through
/// `through` first, in 65536ths.
fn sample(
    data: &[u8],
    t: &Tap,
    (ch, channels, stride): (usize, usize, usize),
    through: impl Fn(u8) -> u8,
) -> u64 {
    let (fx, fy) = (t.fx as u64, t.fy as u64);
    let s = t.src as usize;
    let at = |o: usize| through(data[s + o + ch]) as u64;
    let top = at(0) * (256 - fx) + at(channels) * fx;
    let bottom = at(stride) * (256 - fx) + at(stride + channels) * fx;
    top * (256 - fy) + bottom * fy
}

/// The taps of one plane whose pixels are `scale` frame pixels across.
fn plane_taps(pair: &Pair, rows: &PlaneRows, channels: u32, scale: f64) -> PlaneTaps {
    let width = rows.bytes / channels;
    let taps = (0..rows.rows)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..width).filter_map(move |x| {
                let at = |x: u32, y: u32| rows.offset + y * rows.stride + x * channels;
                let tap = tap_at(pair, (x, y), scale, (width, rows.rows))?;
                Some(Tap {
                    dst: at(x, y),
                    src: at(tap.src.0, tap.src.1),
                    fx: tap.fx,
                    fy: tap.fy,
                    weight: tap.weight,
                    second: tap.second,
                    matched: tap.matched,
                })
            })
        })
        .collect::<Vec<Tap>>();
    let mut row_starts = vec![0u32; rows.rows as usize + 1];
    for t in &taps {
        row_starts[((t.dst - rows.offset) / rows.stride) as usize + 1] += 1;
    }
    for y in 0..rows.rows as usize {
        row_starts[y + 1] += row_starts[y];
    }
    PlaneTaps {
        rows: *rows,
        channels,
        scale,
        taps,
        row_starts,
    }
}

/// Where a tap's other-lens sample starts: a plane pixel (x, y).
struct PlaneTap {
    src: (u32, u32),
    fx: u8,
    fy: u8,
    weight: u8,
    second: bool,
    matched: bool,
}

/// Plane pixel (x, y)'s tap, if it takes the blend: the other lens's sample's top-left
/// pixel and fractions, and its share; and whether the pixel is the second lens's.
fn tap_at(pair: &Pair, (x, y): (u32, u32), scale: f64, size: (u32, u32)) -> Option<PlaneTap> {
    // The plane pixel's centre in frame pixels, and back.
    let to_frame = |p: DVec2| (p + 0.5) * scale - 0.5;
    let to_plane = |q: DVec2| (q + 0.5) / scale - 0.5;
    let q = to_frame(DVec2::new(x as f64, y as f64));
    let side = pair.side_at(q);
    let ray = pair.unproject(q)?;
    let (_, d) = pair.best(ray);
    // The margin difference as this pixel's own lens sees it: positive where it is chosen.
    let own = if side == Side::First { d } else { -d };
    // No view reads a lens's pixels further than REACH past the feather into the other's part.
    if own < -(pair.feather / 2.0 + REACH) {
        return None;
    }
    let seam = own < pair.feather / 2.0;
    let airframe = pair.masked(side, q);
    if !seam && airframe <= 0.0 {
        return None;
    }
    let elsewhere = pair.project_in(other(side), ray)?;
    // The other lens's colour only where it does not see the airframe itself.
    let hidden_there = pair.masked(other(side), elsewhere) > 0.0;
    if !seam && hidden_there {
        return None;
    }
    let seam_share = if seam {
        1.0 - weight_of(own, pair.feather)
    } else {
        0.0
    };
    let share = seam_share.max(airframe);
    let there = to_plane(elsewhere);
    // The other lens's sample must lie within the plane with its right and lower neighbours.
    let max = DVec2::new(size.0 as f64 - 1.001, size.1 as f64 - 1.001);
    if there.x < 0.0 || there.y < 0.0 || there.x > max.x || there.y > max.y {
        return None;
    }
    let base = there.floor();
    let f = ((there - base) * 256.0).round().min(DVec2::splat(255.0));
    Some(PlaneTap {
        src: (base.x as u32, base.y as u32),
        fx: f.x as u8,
        fy: f.y as u8,
        weight: (share * 255.0).round() as u8,
        second: side == Side::Second,
        matched: seam && airframe <= 0.0 && !hidden_there,
    })
}

#[cfg(test)]
mod tests;
