//! The built-in detector, no model file: things that move. Each scan view keeps a background
//! (a slow average of what it showed); before each comparison the background is moved to
//! where the vehicle now is, point by point through the ground plane (the views are fixed in
//! the world, so the vehicle's rotation needs nothing). Pixels far from their background are
//! foreground; their connected blobs are the detections.

use super::angular::Detection;
use super::scan::{ScanView, clear_of_edges, to_world};
use crate::geometry::Projection;
use crate::render::FramePlan;
use crate::render::plan::ViewMap;
use glam::{DVec2, DVec3};
use std::collections::HashMap;

/// A pixel this many grey levels from its background is foreground.
const THRESHOLD: f32 = 18.0;
/// How fast the background follows the scene, per scan: background pixels, foreground ones.
const FOLLOW: f32 = 0.15;
const FOLLOW_FOREGROUND: f32 = 0.02;
/// Scans a view's background takes before it is compared with (what moved in the first
/// scan leaves a stain where it stood, which the stain rules below take back).
const WARM_UP: u32 = 2;
/// Where the background has edges, the threshold rises by this many times the edge's grey
/// levels per pixel: a background moved with the vehicle is a fraction of a pixel off.
const EDGE_SLACK: f32 = 2.0;
/// The fewest pixels a blob has.
const MIN_PIXELS: usize = 4;
/// The warp between backgrounds is computed on a grid this many pixels apart.
const GRID: usize = 8;
/// A blob's confidence: its mean difference over this (capped below 1).
const FULL_CONFIDENCE: f32 = 64.0;
/// Below this a pixel is taken for the black outside the lens's circle (16 in video-range
/// luma).
const DARK: f32 = 20.0;
/// How far from the rim of the circle (and from a view's edge) a pixel must be to count.
const EDGE: usize = 3;
/// The least width and height of a blob, pixels.
const MIN_SIDE: f64 = 2.0;
/// Blobs this many pixels apart or less are one.
const JOIN: usize = 3;
/// How wide a ring around a blob its surroundings are read from, pixels.
const RING: usize = 3;
/// The least and most pixels a thing's shift since the last scan is looked for over.
const MIN_SHIFT: i64 = 4;
const MAX_SHIFT: i64 = 24;
/// How many pixels a thing grows by into pixels the edge slack left out.
const GROW: usize = 2;
/// The least share of a blob's pixels that changed since the last scan for it to be moving.
const MOVED_SHARE: f64 = 0.1;
/// The class motion detections carry.
pub const MOVING: u16 = 0;

struct Background {
    luma: Vec<f32>,
    /// The picture the last scan showed.
    last: Vec<f32>,
    /// Where the vehicle was (world NED, ground at z = 0) when it was last brought up to date,
    /// and when (seconds).
    eye: DVec3,
    time: f64,
    scans: u32,
}

/// The moving-object detector over the scan views.
#[derive(Default)]
pub struct MotionDetector {
    backgrounds: HashMap<usize, Background>,
}

impl Background {
    fn new(luma: Vec<f32>, eye: DVec3, time: f64) -> Background {
        Background {
            last: luma.clone(),
            luma,
            eye,
            time,
            scans: 1,
        }
    }
}

impl MotionDetector {
    pub fn new() -> MotionDetector {
        MotionDetector::default()
    }

    /// Compares one scan with the backgrounds and brings them up to date. `plan` is the
    /// mosaic `views` were rendered with, `luma` its picture (`stride` bytes a row), `eye`
    /// the vehicle's position in a world frame whose ground is z = 0 (NED, metres) and `time`
    /// when the picture was taken (seconds). Each thing found carries its velocity, measured
    /// against where it stood in the last scan.
    pub fn detect(
        &mut self,
        views: &[ScanView],
        plan: &FramePlan,
        luma: &[u8],
        stride: usize,
        eye: DVec3,
        time: f64,
    ) -> Vec<Detection> {
        // Views no longer seen lose their background.
        self.backgrounds
            .retain(|i, _| views.iter().any(|v| v.index == *i));
        let mut found: Vec<Sighting> = vec![];
        // JOIN pixels, as an angle.
        let mut join = 0f64;
        for (view, planned) in views.iter().zip(&plan.views) {
            let ViewMap::Rays {
                projection,
                world_from_view,
            } = planned.map
            else {
                continue;
            };
            let r = planned.rect;
            let (w, h) = (r.w as usize, r.h as usize);
            join = join.max(JOIN as f64 / Projection::focal(r.w as f64, view.fov));
            let current: Vec<f32> = (0..h)
                .flat_map(|y| {
                    let row = (r.y as usize + y) * stride + r.x as usize;
                    luma[row..row + w].iter().map(|&v| v as f32)
                })
                .collect();
            let Some(bg) = self.backgrounds.get_mut(&view.index) else {
                self.backgrounds
                    .insert(view.index, Background::new(current, eye, time));
                continue;
            };
            if bg.luma.len() != current.len() {
                *bg = Background::new(current, eye, time);
                continue;
            }
            let from = sources(w, h, projection, world_from_view, bg.eye, eye);
            let moved = resample(&bg.luma, w, h, &from);
            let before = resample(&bg.last, w, h, &from);
            let mut mask = vec![false; w * h];
            let mut weak = vec![false; w * h];
            let mut diff = vec![0f32; w * h];
            let lit = |i: usize| current[i] > DARK && moved[i].is_some_and(|b| b > DARK);
            for y in EDGE..h.saturating_sub(EDGE) {
                for x in EDGE..w.saturating_sub(EDGE) {
                    let i = y * w + x;
                    let Some(b) = moved[i] else {
                        continue;
                    };
                    let d = (current[i] - b).abs();
                    diff[i] = d;
                    let slope = |a: usize, c: usize| match (moved[a], moved[c]) {
                        (Some(a), Some(c)) => (a - c).abs() / 2.0,
                        _ => 0.0,
                    };
                    let edge = slope(i - 1, i + 1).max(slope(i - w, i + w));
                    // Outside the lens's circle the views are black, and the circle's rim
                    // moves with the vehicle's attitude: only pixels inside in both, with
                    // their neighbours, count.
                    weak[i] = d > THRESHOLD
                        && [i, i - EDGE, i + EDGE, i - EDGE * w, i + EDGE * w]
                            .into_iter()
                            .all(lit);
                    mask[i] = weak[i] && d > THRESHOLD + EDGE_SLACK * edge;
                }
            }
            // A blob's surroundings are read where the picture matches the background.
            let surroundings: Vec<bool> =
                (0..w * h).map(|i| lit(i) && diff[i] <= THRESHOLD).collect();
            // The pixels of a blob that look like its surroundings now where the background
            // did not are a stain: what stood there when the background was taken, joined to
            // the thing that moved away from it. They leave the blob before it is judged.
            let mut stained = vec![];
            for blob in blobs(&mask, w, h) {
                stained.extend(stain(&blob, &current, &moved, &surroundings, w, h));
            }
            for &i in &stained {
                mask[i] = false;
            }
            // A blob that looks like its surroundings now, or where nothing changed since the
            // last scan, is not a thing moving but a stain in the background (what stood
            // there when the view was first seen, or the wake of something that passed) or a
            // thing that stopped: the background takes the picture there at once.
            let (things, stains): (Vec<Blob>, Vec<Blob>) =
                blobs(&mask, w, h).into_iter().partition(|b| {
                    stands_out(b, &current, &surroundings, w, h) && changed(b, &current, &before)
                });
            for i in stains.iter().flat_map(|b| &b.pixels) {
                mask[*i] = false;
            }
            // Where a thing crosses a background's edges, the edge slack drops its pixels
            // there: a thing takes back the pixels beside it that differ by the plain
            // threshold, a few pixels out at most (a line of the background a fraction of a
            // pixel off would otherwise lead it along).
            for &i in &stained {
                weak[i] = false;
            }
            let things: Vec<Blob> = things
                .into_iter()
                .map(|b| grow(b, &weak, &mut mask, w, h))
                .collect();
            let settled = bg.scans >= WARM_UP;
            for i in 0..w * h {
                bg.luma[i] = match moved[i] {
                    Some(b) if b > DARK && current[i] > DARK => {
                        let follow = if mask[i] { FOLLOW_FOREGROUND } else { FOLLOW };
                        b + follow * (current[i] - b)
                    }
                    // Newly inside the circle (or the view), or a stain: taken as it is.
                    _ => current[i],
                };
            }
            for &i in stains.iter().flat_map(|b| &b.pixels).chain(&stained) {
                bg.luma[i] = current[i];
            }
            let since = time - bg.time;
            (bg.eye, bg.time) = (eye, time);
            bg.scans += 1;
            // How far each thing moved since the last scan, in this view's pixels.
            let shifts: Vec<Option<DVec2>> = things
                .iter()
                .map(|b| shift(b, &current, &before, w, h))
                .collect();
            bg.last = current;
            if !settled {
                continue;
            }
            for (blob, shift) in things.into_iter().zip(shifts) {
                let mean =
                    blob.pixels.iter().map(|&i| diff[i]).sum::<f32>() / blob.pixels.len() as f32;
                let Some(bbox) = to_world(view, planned, blob.low, blob.high + DVec2::ONE) else {
                    continue;
                };
                // Thin slivers are the edges of lines a fraction of a pixel off, not things.
                let extent = blob.high - blob.low + DVec2::ONE;
                if extent.min_element() < MIN_SIDE {
                    continue;
                }
                let was = shift.filter(|_| since > 1e-3).and_then(|m| {
                    to_world(view, planned, blob.low - m, blob.high + DVec2::ONE - m)
                });
                let margin = (EDGE + RING) as f64;
                found.push(Sighting {
                    view: view.index,
                    clear: clear_of_edges(view, planned, bbox.centre, bbox.size(), margin),
                    detection: Detection {
                        bbox,
                        confidence: (mean / FULL_CONFIDENCE).min(0.99) as f64,
                        class: MOVING,
                        velocity: was.map(|was| (bbox.centre - was.centre) / since),
                    },
                });
            }
        }
        one_per_thing(found, join)
    }
}

/// A thing as one scan view saw it.
struct Sighting {
    view: usize,
    /// Whether the view shows it clear of its edges.
    clear: bool,
    detection: Detection,
}

/// Views overlap, so one thing is seen by several: sightings `join` radians apart or less
/// are one thing, reported as the view that saw most of it saw it (of the views showing it
/// clear of their edges, the largest box), its pieces in that view joined. Each view loses
/// some of a thing's pixels (where the rim of the lens's circle has just uncovered them, where
/// it crosses a line of the background as bright as itself, or where the view samples it
/// coarsest), and rarely gains any once stains are taken out.
fn one_per_thing(found: Vec<Sighting>, join: f64) -> Vec<Detection> {
    let mut groups: Vec<Vec<Sighting>> = vec![];
    for s in found {
        let mut group = vec![s];
        while let Some(k) = groups.iter().position(|g| {
            g.iter().any(|a| {
                group
                    .iter()
                    .any(|b| a.detection.bbox.gap(&b.detection.bbox) <= join)
            })
        }) {
            group.extend(groups.swap_remove(k));
        }
        groups.push(group);
    }
    groups
        .into_iter()
        .filter_map(|group| {
            let best = group
                .iter()
                .min_by(|a, b| {
                    let area = |s: &Sighting| s.detection.bbox.width * s.detection.bbox.height;
                    b.clear.cmp(&a.clear).then(area(b).total_cmp(&area(a)))
                })?
                .view;
            group
                .into_iter()
                .filter(|s| s.view == best)
                .map(|s| s.detection)
                .reduce(|a, b| Detection {
                    bbox: a.bbox.union(&b.bbox),
                    confidence: a.confidence.max(b.confidence),
                    class: MOVING,
                    velocity: a.velocity.or(b.velocity),
                })
        })
        .collect()
}

/// For each pixel of a view seen from `to` (world NED), where the view seen from `from`
/// showed the same thing: through the ground point it shows (the sky, through no point,
/// stays where it is). None where that is outside the view. Computed on a grid and
/// interpolated.
fn sources(
    w: usize,
    h: usize,
    projection: Projection,
    world_from_view: glam::DMat3,
    from: DVec3,
    to: DVec3,
) -> Vec<Option<DVec2>> {
    let still = from.distance(to) < 1e-3;
    let view_from_world = world_from_view.transpose();
    let source = |p: DVec2| -> Option<DVec2> {
        if still {
            return Some(p);
        }
        let ray = world_from_view * projection.ray(p);
        let seen = if ray.z > 1e-6 && to.z < 0.0 {
            let ground = to + ray * (-to.z / ray.z);
            (ground - from).normalize()
        } else {
            ray
        };
        projection.point(view_from_world * seen)
    };
    let (gw, gh) = (w.div_ceil(GRID) + 1, h.div_ceil(GRID) + 1);
    let nodes: Vec<Option<DVec2>> = (0..gh)
        .flat_map(|j| (0..gw).map(move |i| (i, j)))
        .map(|(i, j)| source(DVec2::new((i * GRID) as f64, (j * GRID) as f64) + 0.5))
        .collect();
    let mut out = vec![None; w * h];
    for y in 0..h {
        for x in 0..w {
            let (i, j) = (x / GRID, y / GRID);
            let (fx, fy) = (
                (x % GRID) as f64 / GRID as f64,
                (y % GRID) as f64 / GRID as f64,
            );
            let corners = [
                nodes[j * gw + i],
                nodes[j * gw + i + 1],
                nodes[(j + 1) * gw + i],
                nodes[(j + 1) * gw + i + 1],
            ];
            if let [Some(a), Some(b), Some(c), Some(d)] = corners {
                out[y * w + x] =
                    Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy);
            }
        }
    }
    out
}

/// `picture` (w × h) sampled bilinearly at each of `at` (view points); None outside it.
fn resample(picture: &[f32], w: usize, h: usize, at: &[Option<DVec2>]) -> Vec<Option<f32>> {
    let sample = |q: DVec2| -> Option<f32> {
        let q = q - 0.5;
        let (x0, y0) = (q.x.floor(), q.y.floor());
        if x0 < 0.0 || y0 < 0.0 || x0 + 1.0 >= w as f64 || y0 + 1.0 >= h as f64 {
            return None;
        }
        let (fx, fy) = ((q.x - x0) as f32, (q.y - y0) as f32);
        let v = |x: f64, y: f64| picture[y as usize * w + x as usize];
        let top = v(x0, y0) * (1.0 - fx) + v(x0 + 1.0, y0) * fx;
        let bottom = v(x0, y0 + 1.0) * (1.0 - fx) + v(x0 + 1.0, y0 + 1.0) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    };
    at.iter().map(|q| q.and_then(sample)).collect()
}

/// A connected set of foreground pixels and its bounding box (pixel indices, inclusive).
struct Blob {
    pixels: Vec<usize>,
    low: DVec2,
    high: DVec2,
}

/// Whether a blob differs from the ring of `known` pixels around it in the picture now
/// (by at least [`THRESHOLD`] on average).
fn stands_out(blob: &Blob, current: &[f32], known: &[bool], w: usize, h: usize) -> bool {
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
fn stain(
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
fn changed(blob: &Blob, current: &[f32], before: &[Option<f32>]) -> bool {
    let moving = blob
        .pixels
        .iter()
        .filter(|&&i| before[i].is_none_or(|b| (current[i] - b).abs() > THRESHOLD))
        .count();
    moving as f64 >= MOVED_SHARE * blob.pixels.len() as f64
}

/// How far `blob` moved since the last scan (`before`, moved to where the vehicle is now),
/// in pixels: the shift that best lays its pixels now over the picture then, looked for up to
/// the blob's own size (at least [`MIN_SHIFT`] pixels) each way, to a tenth of a pixel. None
/// when no shift lays it well (within [`THRESHOLD`] on average) or too little of it was seen.
fn shift(
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
fn grow(mut blob: Blob, weak: &[bool], mask: &mut [bool], w: usize, h: usize) -> Blob {
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
            let p = DVec2::new((n % w) as f64, (n / w) as f64);
            (blob.low, blob.high) = (blob.low.min(p), blob.high.max(p));
        }
        blob.pixels.extend(&next);
        edge = next;
    }
    blob
}

/// The 8 pixels around pixel `i` of a w × h picture, those inside it.
fn neighbours(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((i % w) as i64, (i / w) as i64);
    [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ]
    .into_iter()
    .map(move |(dx, dy)| (x + dx, y + dy))
    .filter(move |&(x, y)| x >= 0 && y >= 0 && x < w as i64 && y < h as i64)
    .map(move |(x, y)| y as usize * w + x as usize)
}

/// The 8-connected blobs of `mask` with at least [`MIN_PIXELS`] pixels.
fn blobs(mask: &[bool], w: usize, h: usize) -> Vec<Blob> {
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
            blob.pixels.push(i);
            let p = DVec2::new((i % w) as f64, (i / w) as f64);
            (blob.low, blob.high) = (blob.low.min(p), blob.high.max(p));
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
    joined.retain(|b| b.pixels.len() >= MIN_PIXELS);
    joined
}
