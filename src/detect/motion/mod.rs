//! The built-in detector, no model file: things that move. Each scan view keeps a background
//! (a slow average of what it showed); before each comparison the background is moved to
//! where the vehicle now is, point by point through the ground plane (the views are fixed in
//! the world, so the vehicle's rotation needs nothing). Pixels far from their background are
//! foreground; their connected blobs are the detections.

mod blob;
mod warp;

use super::angular::Detection;
use super::scan::{ScanView, clear_of_edges, to_world};
use crate::geometry::Projection;
use crate::render::FramePlan;
use crate::render::plan::ViewMap;
use blob::{Blob, JOIN, RING, blobs, changed, grow, shift, stain, stands_out};
use glam::{DVec2, DVec3};
use std::collections::HashMap;
use warp::{resample, sources};

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
/// A blob's confidence: its mean difference over this (capped below 1).
const FULL_CONFIDENCE: f32 = 64.0;
/// Below this a pixel is taken for the black outside the lens's circle (16 in video-range
/// luma).
const DARK: f32 = 20.0;
/// How far from the rim of the circle (and from a view's edge) a pixel must be to count.
const EDGE: usize = 3;
/// The least width and height of a blob, pixels.
const MIN_SIDE: f64 = 2.0;
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
            for &i in stains.iter().flat_map(|b| &b.pixels).chain(&stained) {
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
            if !settled {
                bg.last = current;
                continue;
            }
            // How far each thing moved since the last scan, in this view's pixels.
            let shifts: Vec<Option<DVec2>> = things
                .iter()
                .map(|b| shift(b, &current, &before, w, h))
                .collect();
            bg.last = current;
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
