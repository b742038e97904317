//! The motion detector's blobs: the connected foreground pixels of one scan view, what of
//! them is a stain in the background rather than a thing, how far a thing moved since the
//! last scan, and the pixels it takes back that the edge slack dropped.

use super::{DARK, THRESHOLD};
use crate::image_ops::neighbours;
use glam::DVec2;

/// The fewest pixels a blob has.
const MIN_PIXELS: usize = 4;
/// Blobs this many pixels apart or less are one.
pub(super) const JOIN: usize = 3;
/// How wide a ring around a blob its surroundings are read from, pixels.
pub(super) const RING: usize = 3;
/// The least and most pixels a thing's shift since the last scan is looked for over.
const MIN_SHIFT: i64 = 4;
const MAX_SHIFT: i64 = 24;
/// How many pixels a thing grows by into pixels the edge slack left out.
const GROW: usize = 2;
/// The least share of a blob's pixels that changed since the last scan for it to be moving.
const MOVED_SHARE: f64 = 0.1;

/// A connected set of foreground pixels and its bounding box (pixel indices, inclusive).
pub(super) struct Blob {
    pub(super) pixels: Vec<usize>,
    pub(super) low: DVec2,
    pub(super) high: DVec2,
}

impl Blob {
    /// Pixel `i` (of a picture `w` wide) joins the blob and its box.
    fn add(&mut self, i: usize, w: usize) {
        let p = DVec2::new((i % w) as f64, (i / w) as f64);
        (self.low, self.high) = (self.low.min(p), self.high.max(p));
        self.pixels.push(i);
    }
}

/// Whether a blob differs from the ring of `known` pixels around it in the picture now
/// (by at least [`THRESHOLD`] on average).
pub(super) fn stands_out(blob: &Blob, current: &[f32], known: &[bool], w: usize, h: usize) -> bool {
    let inside = blob.pixels.iter().map(|&i| current[i]).sum::<f32>() / blob.pixels.len() as f32;
    let (mut sum, mut n) = (0f32, 0usize);
    for i in ring(blob, w, h) {
        if known[i] {
            sum += current[i];
            n += 1;
        }
    }
    n == 0 || (inside - sum / n as f32).abs() >= THRESHOLD
}

/// The pixels of `blob` that are a stain: the picture now is within [`THRESHOLD`] of the
/// ring of `known` pixels around the blob (their median), and the background is not.
pub(super) fn stain(
    blob: &Blob,
    current: &[f32],
    background: &[Option<f32>],
    known: &[bool],
    w: usize,
    h: usize,
) -> Vec<usize> {
    let (mut now, mut then) = (vec![], vec![]);
    for i in ring(blob, w, h) {
        if let Some(b) = background[i].filter(|_| known[i]) {
            now.push(current[i]);
            then.push(b);
        }
    }
    let (Some(now), Some(then)) = (median(&mut now), median(&mut then)) else {
        return vec![];
    };
    blob.pixels
        .iter()
        .copied()
        .filter(|&i| {
            (current[i] - now).abs() < THRESHOLD
                && background[i].is_some_and(|b| (b - then).abs() >= THRESHOLD)
        })
        .collect()
}

fn median(values: &mut [f32]) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let k = values.len() / 2;
    Some(*values.select_nth_unstable_by(k, f32::total_cmp).1)
}

/// The pixels of the box [`RING`] pixels wider than `blob`'s on each side (the blob's own
/// among them).
fn ring(blob: &Blob, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x0, y0) = (
        (blob.low.x as usize).saturating_sub(RING),
        (blob.low.y as usize).saturating_sub(RING),
    );
    let (x1, y1) = (
        (blob.high.x as usize + RING).min(w - 1),
        (blob.high.y as usize + RING).min(h - 1),
    );
    (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| y * w + x))
}

/// Whether enough of a blob's pixels changed since the last scan (`before`, moved to where
/// the vehicle is now; None where it was not seen) for it to be moving.
pub(super) fn changed(blob: &Blob, current: &[f32], before: &[Option<f32>]) -> bool {
    let moving = blob
        .pixels
        .iter()
        .filter(|&&i| before[i].is_none_or(|b| (current[i] - b).abs() > THRESHOLD))
        .count();
    moving as f64 >= MOVED_SHARE * blob.pixels.len() as f64
}

/// How far `blob` moved since the last scan (`before`, moved to where the vehicle is now),
/// in pixels: the shift that best lays its pixels now over the picture then, looked for up to
/// the blob's own size (at least [`MIN_SHIFT`] pixels) each way, between pixels. None
/// when no shift lays it well (within [`THRESHOLD`] on average) or too little of it was seen.
pub(super) fn shift(
    blob: &Blob,
    current: &[f32],
    before: &[Option<f32>],
    w: usize,
    h: usize,
) -> Option<DVec2> {
    let reach = ((blob.high - blob.low).max_element() as i64 + 1).clamp(MIN_SHIFT, MAX_SHIFT);
    let cost = |dx: i64, dy: i64| -> Option<f32> {
        let (mut sum, mut n) = (0f32, 0usize);
        for &i in &blob.pixels {
            let (x, y) = ((i % w) as i64 - dx, (i / w) as i64 - dy);
            if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                continue;
            }
            if let Some(b) = before[y as usize * w + x as usize].filter(|&b| b > DARK) {
                sum += (current[i] - b).abs();
                n += 1;
            }
        }
        (2 * n >= blob.pixels.len()).then(|| sum / n as f32)
    };
    // Every second shift first, then the shifts around the best of those.
    let least = |shifts: &mut dyn Iterator<Item = (i64, i64)>| {
        shifts
            .filter_map(|(x, y)| cost(x, y).map(|c| (x, y, c)))
            .min_by(|a, b| a.2.total_cmp(&b.2))
    };
    let coarse = (-reach..=reach).step_by(2);
    let (cx, cy, _) = least(
        &mut coarse
            .clone()
            .flat_map(|y| coarse.clone().map(move |x| (x, y))),
    )?;
    let (x, y, c) = least(&mut (-1..=1).flat_map(|j| (-1..=1).map(move |i| (cx + i, cy + j))))?;
    if c > THRESHOLD {
        return None;
    }
    // A parabola through the least cost and its neighbours puts the shift between pixels.
    let refine = |low: Option<f32>, high: Option<f32>| match (low, high) {
        (Some(l), Some(h)) if l + h > 2.0 * c => {
            (0.5 * (l - h) / (l + h - 2.0 * c)).clamp(-0.5, 0.5) as f64
        }
        _ => 0.0,
    };
    let fx = refine(cost(x - 1, y), cost(x + 1, y));
    let fy = refine(cost(x, y - 1), cost(x, y + 1));
    Some(DVec2::new(x as f64 + fx, y as f64 + fy))
}

/// `blob` grown by up to [`GROW`] pixels into the `weak` pixels around it, which join `mask`.
pub(super) fn grow(mut blob: Blob, weak: &[bool], mask: &mut [bool], w: usize, h: usize) -> Blob {
    let mut edge = blob.pixels.clone();
    for _ in 0..GROW {
        let mut next = vec![];
        for i in edge {
            for n in neighbours(i, w, h) {
                if weak[n] && !mask[n] {
                    mask[n] = true;
                    next.push(n);
                }
            }
        }
        for &n in &next {
            blob.add(n, w);
        }
        edge = next;
    }
    blob
}

/// The 8-connected blobs of `mask` with at least [`MIN_PIXELS`] pixels.
pub(super) fn blobs(mask: &[bool], w: usize, h: usize) -> Vec<Blob> {
    let mut seen = vec![false; w * h];
    let mut out = vec![];
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start];
        let mut blob = Blob {
            pixels: vec![],
            low: DVec2::splat(f64::MAX),
            high: DVec2::splat(f64::MIN),
        };
        while let Some(i) = stack.pop() {
            blob.add(i, w);
            for n in neighbours(i, w, h) {
                if mask[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            }
        }
        out.push(blob);
    }
    // Pieces of one thing (cut by the lines it crosses) within a few pixels join; stray
    // pixels (a line's edge a fraction of a pixel off) do not.
    out.retain(|b| b.pixels.len() >= MIN_PIXELS);
    let near = |a: &Blob, b: &Blob| {
        let gap = (a.low - b.high).max(b.low - a.high);
        gap.x <= JOIN as f64 && gap.y <= JOIN as f64
    };
    let mut joined: Vec<Blob> = vec![];
    for mut blob in out {
        while let Some(k) = joined.iter().position(|j| near(j, &blob)) {
            let other = joined.swap_remove(k);
            blob.pixels.extend(other.pixels);
            blob.low = blob.low.min(other.low);
            blob.high = blob.high.max(other.high);
        }
        joined.push(blob);
    }
    joined
}
