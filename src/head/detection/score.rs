//! How true the tracker is on the demo, scored against the scene's own movers (whose places
//! the demo knows at every instant): after each scan, every tracked object in the scan's field
//! is on a mover or not, each mover coming into the field is tracked after so long, and each
//! tile shows a mover or empty ground; and in every frame, each ring the page is given lies
//! so far from its mover in that frame. The figures go to the status (`/api/status`) and the
//! health line, so a machine's own load is measured as it runs, not a test bench's.

use crate::geometry::GeoPoint;
use crate::geometry::GeoPosition;
use crate::geometry::ground::to_ned;
use crate::geometry::rotation::direction;
use crate::plan::FramePlan;
use crate::scene::grid::Mover;
use crate::state::{State, Tracked};
use glam::DVec3;
use serde::Serialize;
use std::collections::HashMap;

/// A mover coming into the field is late when it is not tracked within this, seconds.
pub const ENTRY_LIMIT: f64 = 1.0;

/// Where the demo's movers are: its world's movers, the world's origin (the ground under the
/// hover point), and when its scene time 0 was on `crate::clock::clock_us`.
#[derive(Clone, Debug)]
pub struct DemoTruth {
    pub movers: Vec<Mover>,
    pub origin: GeoPoint,
    pub start_us: u64,
}

/// The figures since detection started on the demo.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Score {
    pub scans: u64,
    /// Tracked objects in the scans' fields, counted once a scan, and those on a mover.
    pub in_field: u64,
    pub on_movers: u64,
    /// `on_movers / in_field` (1 with none in the field).
    pub precision: f64,
    /// Seconds from each mover's coming into the field to its first track, in order.
    pub entries: Vec<f64>,
    /// Movers that came into the field and were not tracked within [`ENTRY_LIMIT`] (those
    /// still waiting past it included).
    pub late_entries: u64,
    /// The longest a tile went on showing an object on no mover, seconds.
    pub longest_false_tile: f64,
    pub rings: Rings,
}

/// The rings over the frames (each object on a mover, in each view showing it, placed as the
/// page is given them): how many, how many within [`RING_LIMIT`] pixels of their mover in the
/// frame they are drawn over, and the worst, pixels (of those whose mover the view shows:
/// a ring whose mover is outside its view counts as off).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Rings {
    pub count: u64,
    pub within: u64,
    pub worst: f64,
}

/// A ring is on its mover within this many output pixels.
pub const RING_LIMIT: f64 = 10.0;

impl DemoTruth {
    /// Each mover's direction from `position` at `t` seconds on the clock, and its angular
    /// diameter.
    fn movers_seen(&self, position: &GeoPosition, t: f64) -> Vec<(DVec3, f64)> {
        let scene_t = t - self.start_us as f64 * 1e-6;
        let eye = to_ned(self.origin, position.point());
        self.movers
            .iter()
            .map(|m| {
                let to = m.position(scene_t).extend(0.0) - eye;
                (to.normalize(), 2.0 * (m.radius / to.length()).atan())
            })
            .collect()
    }
}

/// Whether an object along `ray`, `size` across, is on the mover seen along `mover`,
/// `diameter` across: within the larger of the two sizes.
fn on((ray, size): (DVec3, f64), (mover, diameter): (DVec3, f64)) -> bool {
    ray.angle_between(mover) <= size.max(diameter)
}

/// Scores the rings of the frame `plan` draws with `state` (its vehicle and objects as at
/// the frame's capture, `t_us`) into `score`: each object on a mover, in each view of the
/// layout showing it, against where that view shows the mover.
pub fn rings(score: &mut Rings, truth: &DemoTruth, (plan, state): (&FramePlan, &State), t_us: u64) {
    let movers = truth.movers_seen(&state.vehicle.position, t_us as f64 * 1e-6);
    let shown = plan.layout.views.len();
    for o in &state.tracked {
        let object = (direction(o.yaw, o.pitch), o.size);
        let Some(&mover) = movers.iter().find(|&&m| on(object, m)) else {
            continue;
        };
        for view in &plan.views[..shown] {
            let Some(ring) = plan.view_point(view, object.0) else {
                continue;
            };
            let off = plan
                .view_point(view, mover.0)
                .map_or(f64::INFINITY, |m| m.distance(ring));
            score.count += 1;
            score.within += (off <= RING_LIMIT) as u64;
            if off.is_finite() {
                score.worst = score.worst.max(off);
            }
        }
    }
}

/// The score kept across scans.
pub struct Scorer {
    truth: DemoTruth,
    score: Score,
    /// Each mover: when it came into the field, while it is in it and not yet tracked; and
    /// whether it is tracked now.
    entered: Vec<Option<f64>>,
    was_in: Vec<bool>,
    /// Each tiled object on no mover: since when.
    false_since: HashMap<u32, f64>,
    last_t: Option<f64>,
}

impl Scorer {
    pub fn new(truth: DemoTruth) -> Scorer {
        let n = truth.movers.len();
        Scorer {
            truth,
            score: Score {
                precision: 1.0,
                ..Score::default()
            },
            entered: vec![None; n],
            was_in: vec![false; n],
            false_since: HashMap::new(),
            last_t: None,
        }
    }

    pub fn score(&self) -> &Score {
        &self.score
    }

    /// Scores the scan captured at `t` (seconds on the clock) from `position`: `objects` are
    /// the tracked list as published (the first `tiled` in the tiles), `covered` says whether
    /// the scan's views see a world direction.
    pub fn scan(
        &mut self,
        (t, position): (f64, &GeoPosition),
        objects: &[Tracked],
        tiled: usize,
        covered: impl Fn(DVec3) -> bool,
    ) {
        let first = self.last_t.is_none();
        self.last_t = Some(t);
        let movers = self.truth.movers_seen(position, t);
        let at = (t * 1e6) as u64;
        let rays: Vec<(DVec3, f64)> = objects
            .iter()
            .map(|o| {
                let o = o.at(at);
                (direction(o.yaw, o.pitch), o.size)
            })
            .collect();
        let on_a_mover = |o: (DVec3, f64)| movers.iter().any(|&m| on(o, m));
        let s = &mut self.score;
        s.scans += 1;
        for &o in rays.iter().filter(|o| covered(o.0)) {
            s.in_field += 1;
            s.on_movers += on_a_mover(o) as u64;
        }
        s.precision = match s.in_field {
            0 => 1.0,
            n => s.on_movers as f64 / n as f64,
        };
        for (k, &m) in movers.iter().enumerate() {
            let inside = covered(m.0);
            let tracked = rays.iter().any(|&o| on(o, m));
            match (inside, self.was_in[k], self.entered[k]) {
                (false, ..) => self.entered[k] = None,
                // In the field when scoring began: it did not come in.
                (true, false, _) if first => {}
                (true, false, None) if !tracked => self.entered[k] = Some(t),
                (true, _, Some(since)) if tracked => {
                    s.entries.push(t - since);
                    self.entered[k] = None;
                }
                _ => {}
            }
            self.was_in[k] = inside;
        }
        let waiting = self
            .entered
            .iter()
            .flatten()
            .filter(|&&since| t - since > ENTRY_LIMIT)
            .count();
        let came_late = s.entries.iter().filter(|&&e| e > ENTRY_LIMIT).count();
        s.late_entries = (came_late + waiting) as u64;
        let mut still_false = HashMap::new();
        for (o, &ray) in objects.iter().zip(&rays).take(tiled) {
            if !on_a_mover(ray) {
                let nearest = movers
                    .iter()
                    .map(|m| m.0.angle_between(ray.0).to_degrees())
                    .fold(f64::INFINITY, f64::min);
                tracing::debug!(
                    "demo score: tiled object {} ({:.1}° across, score {}, seen {:.2} s ago) is \
                     {nearest:.1}° from the nearest mover",
                    o.id,
                    o.size.to_degrees(),
                    o.score,
                    t - o.seen_us as f64 * 1e-6
                );
                let since = self.false_since.get(&o.id).copied().unwrap_or(t);
                s.longest_false_tile = s.longest_false_tile.max(t - since);
                still_false.insert(o.id, since);
            }
        }
        self.false_since = still_false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation::yaw_pitch;
    use glam::{DVec2, DVec3};

    /// One mover 40 m north of the hover point's ground, still; the vehicle 50 m over it.
    fn scene() -> (Scorer, GeoPosition, DVec3) {
        let position = crate::state::DEFAULT_POSITION;
        let origin = crate::scene::synth::world_origin(&position);
        let mover = Mover {
            centre: DVec2::new(40.0, 0.0),
            orbit: 0.0,
            speed: 0.0,
            phase: 0.0,
            radius: 1.5,
            colour: DVec3::ONE,
        };
        let eye = to_ned(origin, position.point());
        let ray = (DVec3::new(40.0, 0.0, 0.0) - eye).normalize();
        let truth = DemoTruth {
            movers: vec![mover],
            origin,
            start_us: 0,
        };
        (Scorer::new(truth), position, ray)
    }

    fn object(id: u32, ray: DVec3) -> Tracked {
        let (yaw, pitch) = yaw_pitch(ray);
        Tracked {
            id,
            yaw,
            pitch,
            size: 0.02,
            ..Tracked::default()
        }
    }

    #[test]
    fn objects_on_no_mover_lower_the_precision_and_keep_a_tile_false() {
        let (mut scorer, position, ray) = scene();
        let off = (ray + DVec3::new(0.0, 0.3, 0.0)).normalize();
        for k in 0..4 {
            let t = 1.0 + 0.5 * k as f64;
            let objects = [object(1, off), object(2, ray)];
            scorer.scan((t, &position), &objects, 1, |_| true);
        }
        let s = scorer.score();
        assert_eq!((s.in_field, s.on_movers), (8, 4));
        assert_eq!(s.precision, 0.5);
        assert_eq!(
            s.longest_false_tile, 1.5,
            "object 1 in the tile, false for 1.5 s"
        );
    }

    #[test]
    fn a_mover_coming_into_the_field_is_timed_until_tracked() {
        let (mut scorer, position, ray) = scene();
        let outside = |_: DVec3| false;
        scorer.scan((1.0, &position), &[], 0, outside);
        scorer.scan((1.3, &position), &[], 0, |_| true);
        scorer.scan((1.6, &position), &[], 0, |_| true);
        assert_eq!(scorer.score().late_entries, 0);
        scorer.scan((2.5, &position), &[], 0, |_| true);
        assert_eq!(scorer.score().late_entries, 1, "waiting 1.2 s");
        scorer.scan((2.8, &position), &[object(3, ray)], 1, |_| true);
        let s = scorer.score();
        assert_eq!(s.entries.len(), 1);
        assert!((s.entries[0] - 1.5).abs() < 1e-9, "{:?}", s.entries);
        assert_eq!((s.late_entries, s.longest_false_tile), (1, 0.0));
    }
}
