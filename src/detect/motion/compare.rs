//! One scan view against its background: which pixels differ, which blobs of them are things
//! that moved and which are stains the background takes as they are, the background brought
//! up to date, and each thing as a sighting in the world with its velocity.

use super::blob::{Blob, RING, blobs, changed, grow, shift, stain, stands_out};
use super::{
    Background, DARK, EDGE, EDGE_SLACK, FOLLOW, FOLLOW_FOREGROUND, FULL_CONFIDENCE, MIN_SIDE,
    MOVING, Sighting, THRESHOLD,
};
use crate::detect::angular::Detection;
use crate::detect::scan::{ScanView, clear_of_edges, to_world};
use crate::layout::Rect;
use crate::plan::PlannedView;
use glam::DVec2;

/// A view's pixels of the mosaic's `luma` (`stride` bytes a row).
pub(super) fn view_luma(luma: &[u8], stride: usize, r: Rect) -> Vec<f32> {
    let (w, h) = (r.w as usize, r.h as usize);
    (0..h)
        .flat_map(|y| {
            let row = (r.y as usize + y) * stride + r.x as usize;
            luma[row..row + w].iter().map(|&v| v as f32)
        })
        .collect()
}

/// A view's picture now (`current`), its background moved to where the vehicle is now
/// (`moved`) and the last scan's picture moved alike (`before`); None where the background
/// does not reach.
pub(super) struct Scan {
    pub current: Vec<f32>,
    pub moved: Vec<Option<f32>>,
    pub before: Vec<Option<f32>>,
    pub w: usize,
    pub h: usize,
}

/// Where the picture differs from its background: by the threshold raised over the
/// background's edges (`mask`), by the plain threshold (`weak`), by how much (`diff`), and
/// where it matches a lit background (`surroundings`, what a blob is compared with).
pub(super) struct Differences {
    pub mask: Vec<bool>,
    weak: Vec<bool>,
    pub diff: Vec<f32>,
    surroundings: Vec<bool>,
}

impl Scan {
    /// Inside the lens's circle, now and in the background.
    fn lit(&self, i: usize) -> bool {
        self.current[i] > DARK && self.moved[i].is_some_and(|b| b > DARK)
    }

    pub(super) fn differences(&self) -> Differences {
        let (w, h) = (self.w, self.h);
        let (mut mask, mut weak, mut diff) =
            (vec![false; w * h], vec![false; w * h], vec![0f32; w * h]);
        for y in EDGE..h.saturating_sub(EDGE) {
            for x in EDGE..w.saturating_sub(EDGE) {
                let i = y * w + x;
                let Some(b) = self.moved[i] else {
                    continue;
                };
                let d = (self.current[i] - b).abs();
                diff[i] = d;
                let slope = |a: usize, c: usize| match (self.moved[a], self.moved[c]) {
                    (Some(a), Some(c)) => (a - c).abs() / 2.0,
                    _ => 0.0,
                };
                let edge = slope(i - 1, i + 1).max(slope(i - w, i + w));
                // Outside the lens's circle the views are black, and the circle's rim moves
                // with the vehicle's attitude: only pixels inside in both, with their
                // neighbours, count.
                weak[i] = d > THRESHOLD
                    && [i, i - EDGE, i + EDGE, i - EDGE * w, i + EDGE * w]
                        .into_iter()
                        .all(|k| self.lit(k));
                mask[i] = weak[i] && d > THRESHOLD + EDGE_SLACK * edge;
            }
        }
        let surroundings = (0..w * h)
            .map(|i| self.lit(i) && diff[i] <= THRESHOLD)
            .collect();
        Differences {
            mask,
            weak,
            diff,
            surroundings,
        }
    }

    /// The blobs that are things moving, grown into the pixels beside them the edge slack
    /// dropped; and the pixels of stains, which the background takes as they are.
    pub(super) fn things(&self, d: &mut Differences) -> (Vec<Blob>, Vec<usize>) {
        let (w, h, current) = (self.w, self.h, &self.current);
        // The pixels of a blob that look like its surroundings now where the background did
        // not are a stain: what stood there when the background was taken, joined to the
        // thing that moved away from it. They leave the blob before it is judged.
        let mut taken = vec![];
        for blob in blobs(&d.mask, w, h) {
            taken.extend(stain(&blob, current, &self.moved, &d.surroundings, w, h));
        }
        for &i in &taken {
            d.mask[i] = false;
        }
        // A blob that looks like its surroundings now, or where nothing changed since the last
        // scan, is not a thing moving but a stain in the background (what stood there when
        // the view was first seen, or the wake of something that passed) or a thing that
        // stopped: the background takes the picture there at once.
        let (things, stains): (Vec<Blob>, Vec<Blob>) =
            blobs(&d.mask, w, h).into_iter().partition(|b| {
                stands_out(b, current, &d.surroundings, w, h) && changed(b, current, &self.before)
            });
        taken.extend(stains.iter().flat_map(|b| &b.pixels));
        // Where a thing crosses a background's edges, the edge slack drops its pixels there:
        // a thing takes back the pixels beside it that differ by the plain threshold, a few
        // pixels out at most (a line of the background a fraction of a pixel off would
        // otherwise lead it along).
        for &i in &taken {
            (d.mask[i], d.weak[i]) = (false, false);
        }
        let things = things
            .into_iter()
            .map(|b| grow(b, &d.weak, &mut d.mask, w, h))
            .collect();
        (things, taken)
    }

    /// The background follows the picture: slowly, slower still under things (`mask`), and
    /// at once where it is new (inside the circle or the view) or a stain (`taken`).
    pub(super) fn follow(&self, bg: &mut Background, mask: &[bool], taken: &[usize]) {
        for (i, luma) in bg.luma.iter_mut().enumerate() {
            let now = self.current[i];
            *luma = match self.moved[i] {
                Some(b) if b > DARK && now > DARK => {
                    let follow = if mask[i] { FOLLOW_FOREGROUND } else { FOLLOW };
                    b + follow * (now - b)
                }
                _ => now,
            };
        }
        for &i in taken {
            bg.luma[i] = self.current[i];
        }
    }

    /// Each thing as its view sees it in the world, with its confidence and, where it can be
    /// laid over the last scan's picture (`since` seconds ago), its velocity.
    pub(super) fn sightings(
        &self,
        (view, planned): (&ScanView, &PlannedView),
        things: Vec<Blob>,
        diff: &[f32],
        since: f64,
    ) -> Vec<Sighting> {
        let (w, h) = (self.w, self.h);
        let mut found = vec![];
        for blob in things {
            let moved = shift(&blob, &self.current, &self.before, w, h);
            let mean = blob.pixels.iter().map(|&i| diff[i]).sum::<f32>() / blob.pixels.len() as f32;
            let Some(bbox) = to_world(view, planned, blob.low, blob.high + DVec2::ONE) else {
                continue;
            };
            // Thin slivers are the edges of lines a fraction of a pixel off, not things.
            let extent = blob.high - blob.low + DVec2::ONE;
            if extent.min_element() < MIN_SIDE {
                continue;
            }
            let was = moved
                .filter(|_| since > 1e-3)
                .and_then(|m| to_world(view, planned, blob.low - m, blob.high + DVec2::ONE - m));
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
        found
    }
}
