//! The seed's scored tracker. A scan ("var") over the whole field finds new objects and finds
//! known ones again; a track ("crop") step looks for one known object in the crop around it.
//! Each object carries a score in 0..=254: it starts at `creation_score_scale`, gains
//! `bonus_detection_scale` when a scan finds it again and `bonus_redetection_scale` when its
//! crop does, loses `missed_detection_penalty` when a scan that covered it misses it and
//! `missed_redetection_penalty` when its crop does, and is dropped at 0. Objects live in world
//! directions, so a vehicle turning between frames does not break an association, and are
//! looked for where their motion so far takes them. The tiles show the objects as
//! `sorting_mode` orders them.

use super::angular::{AngularBox, Detection, suppress};
use crate::state::{DetectionSettings, MAX_PREDICTION, moved_on};
use glam::DVec3;

/// The highest score.
pub const MAX_SCORE: u8 = 254;

/// The class of an object pointed at before any detector said what it is.
pub const UNKNOWN_CLASS: u16 = u16::MAX;

/// A detection belongs to an object when their boxes overlap at least this much, or when its
/// centre is within the larger box's size of the object's (objects move between scans).
const MATCH_OVERLAP: f64 = 0.1;

/// One tracked object.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// Unique for the tracker's life, never reused.
    pub id: u32,
    pub bbox: AngularBox,
    pub class: u16,
    /// The confidence of the detection last seen.
    pub confidence: f64,
    pub score: u8,
    /// When it was created and last found, seconds on the caller's clock.
    pub born: f64,
    pub seen: f64,
    /// How fast its centre moves across the sky (world NED, per second), from the times it
    /// was found: between scans it is looked for where it should have got to.
    pub velocity: DVec3,
    /// Its last few sightings (time, centre), oldest first, that the velocity is measured
    /// over.
    trail: Vec<(f64, DVec3)>,
}

/// How many sightings an object's velocity is measured over at most.
const TRAIL: usize = 4;

/// How fast (radians a second) an object not found where it was expected may have moved
/// across the sky since it was last seen, for a box near it to be taken as it: a car at
/// 30 km/h seen from 100 m.
const CATCH_UP_RATE: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// How much larger than the object a box must be, at once, to be it merged with something
/// else (see `merged`), radians.
const MERGED_GROWTH: f64 = 2.0 * std::f64::consts::PI / 180.0;

impl Object {
    /// Where the object should be at time `t`, moving as it did.
    pub fn at(&self, t: f64) -> AngularBox {
        AngularBox {
            centre: moved_on(self.bbox.centre, self.velocity, t - self.seen),
            ..self.bbox
        }
    }

    /// How close to `target` the object came between its last sighting and time `t` (its
    /// last box, then where it should have been on the way), in radians: what an operator
    /// clicked in a picture that lags the scans is somewhere on that way.
    pub fn nearest_since_seen(&self, t: f64, target: &AngularBox) -> f64 {
        const STEPS: u32 = 8;
        let span = (t - self.seen).max(0.0);
        (0..=STEPS)
            .map(|k| self.at(self.seen + span * f64::from(k) / f64::from(STEPS)))
            .map(|b| b.angle_to(target))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Why a score changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Why {
    Created,
    FoundByScan,
    FoundByTrack,
    MissedByScan,
    MissedByTrack,
}

/// One score change: object `id` went `from` → `to` (0: dropped).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Change {
    pub id: u32,
    pub why: Why,
    pub from: u8,
    pub to: u8,
}

#[derive(Clone, Debug, Default)]
pub struct Tracker {
    objects: Vec<Object>,
    next_id: u32,
    /// The object each detection tile shows, in tile order (sorting mode 2 keeps it).
    tiles: Vec<Option<u32>>,
}

/// Whether `d`, seen at time `t`, belongs to `o`: how well (higher is better), or None.
fn fit(o: &Object, d: &Detection, t: f64) -> Option<(bool, f64)> {
    let expected = o.at(t);
    let overlap = expected.overlap(&d.bbox);
    let near = expected.angle_to(&d.bbox) <= expected.size().max(d.bbox.size());
    (overlap >= MATCH_OVERLAP || near).then_some((o.class == d.class, overlap))
}

impl Tracker {
    pub fn new() -> Tracker {
        Tracker::default()
    }

    /// Every known object, oldest first.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    pub fn get(&self, id: u32) -> Option<&Object> {
        self.objects.iter().find(|o| o.id == id)
    }

    /// A scan at time `t`: `found` is the detector's raw boxes over the scanned views, and
    /// `covered` says whether a direction was inside them (an object outside was not
    /// expected, and is not penalised). Returns every score change, in order.
    pub fn scan(
        &mut self,
        s: &DetectionSettings,
        t: f64,
        found: Vec<Detection>,
        covered: impl Fn(&AngularBox) -> bool,
    ) -> Vec<Change> {
        let limit = s.var_box_limit as usize;
        let found = suppress(found, s.var_confidence_threshold, s.var_box_overlap, limit);
        let (object_found, used) = self.associate(&found, t);
        let mut changes = vec![];
        for (i, o) in self.objects.iter_mut().enumerate() {
            match object_found[i] {
                Some(j) => {
                    let change = found_again(o, &found[j], t, s.bonus_detection_scale);
                    changes.push(Change {
                        why: Why::FoundByScan,
                        ..change
                    });
                }
                None if covered(&o.at(t)) => {
                    changes.push(missed(o, s.missed_detection_penalty, Why::MissedByScan));
                }
                None => {}
            }
        }
        // New objects: boxes no object took that overlap no object more than the scan allows.
        for (j, d) in found.iter().enumerate() {
            let duplicate = self
                .objects
                .iter()
                .any(|o| o.score > 0 && o.bbox.overlap(&d.bbox) > s.var_box_overlap);
            if !(used[j] || duplicate || s.creation_score_scale == 0) {
                changes.push(self.create(d, s.creation_score_scale, t));
            }
        }
        self.objects.retain(|o| o.score > 0);
        changes
    }

    /// Which box each object is, if any, and which boxes an object took: pairs best first
    /// (same class, then overlap), each object and box used once; then a second chance.
    fn associate(&self, found: &[Detection], t: f64) -> (Vec<Option<usize>>, Vec<bool>) {
        let mut pairs: Vec<(usize, usize, (bool, f64))> = vec![];
        for (i, o) in self.objects.iter().enumerate() {
            for (j, d) in found.iter().enumerate() {
                if let Some(q) = fit(o, d, t) {
                    pairs.push((i, j, q));
                }
            }
        }
        pairs.sort_by(|a, b| b.2.0.cmp(&a.2.0).then(b.2.1.total_cmp(&a.2.1)));
        let mut object_found = vec![None; self.objects.len()];
        let mut used = vec![false; found.len()];
        for (i, j, _) in pairs {
            if object_found[i].is_none() && !used[j] {
                object_found[i] = Some(j);
                used[j] = true;
            }
        }
        // A second chance, for the objects still not found and the boxes no object took: a
        // box of the object's class within reach of how far the object could have gone
        // since it was last seen is the object found late (lost while two things crossed,
        // or moving faster than its size a scan), not a new object beside a stale one.
        // Surest objects first, then nearest boxes.
        let mut late: Vec<(usize, usize, f64)> = vec![];
        for (i, o) in self.objects.iter().enumerate() {
            for (j, d) in found.iter().enumerate() {
                let away = o.at(t).angle_to(&d.bbox).min(o.bbox.angle_to(&d.bbox));
                let since = (t - o.seen).clamp(0.0, MAX_PREDICTION);
                let reach = o.bbox.size().max(d.bbox.size()) + CATCH_UP_RATE * since;
                if object_found[i].is_none() && !used[j] && o.class == d.class && away <= reach {
                    late.push((i, j, away));
                }
            }
        }
        let score = |i: usize| self.objects[i].score;
        late.sort_by(|a, b| score(b.0).cmp(&score(a.0)).then(a.2.total_cmp(&b.2)));
        for (i, j, _) in late {
            if object_found[i].is_none() && !used[j] {
                object_found[i] = Some(j);
                used[j] = true;
            }
        }
        (object_found, used)
    }

    /// A new object where box `d` is, at the creation score.
    fn create(&mut self, d: &Detection, creation: u8, t: f64) -> Change {
        let score = creation.min(MAX_SCORE);
        let id = self.next_id;
        self.next_id += 1;
        self.objects.push(Object {
            id,
            bbox: d.bbox,
            class: d.class,
            confidence: d.confidence,
            score,
            born: t,
            seen: t,
            velocity: d.velocity.unwrap_or(DVec3::ZERO),
            trail: vec![(t, d.bbox.centre)],
        });
        Change {
            id,
            why: Why::Created,
            from: 0,
            to: score,
        }
    }

    /// An object pointed at (a ground station's click), at full score, where `bbox` is
    /// at time `t`: the scans that find something there take it as this object, whatever
    /// class they give it. Returns its id.
    pub fn seed(&mut self, bbox: AngularBox, class: u16, t: f64) -> u32 {
        let id = self.next_id;
        self.next_id += 1;
        self.objects.push(Object {
            id,
            bbox,
            class,
            confidence: 1.0,
            score: MAX_SCORE,
            born: t,
            seen: t,
            velocity: DVec3::ZERO,
            trail: vec![(t, bbox.centre)],
        });
        id
    }

    /// The track step for object `id` at time `t`: `found` is the detector's raw boxes in
    /// the crop around it, of which one of its class near where it should be is it. None if
    /// there is no such object.
    pub fn track(
        &mut self,
        s: &DetectionSettings,
        t: f64,
        id: u32,
        found: Vec<Detection>,
    ) -> Option<Change> {
        let limit = s.crop_box_limit as usize;
        let found = suppress(
            found,
            s.crop_confidence_threshold,
            s.crop_box_overlap,
            limit,
        );
        let o = self.objects.iter_mut().find(|o| o.id == id)?;
        // The crop looks for its own object: another thing in it (of another class) is not it.
        let best = found
            .iter()
            .filter(|d| d.class == o.class)
            .filter_map(|d| fit(o, d, t).map(|q| (d, q.1)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let change = match best {
            Some((d, _)) => Change {
                why: Why::FoundByTrack,
                ..found_again(o, d, t, s.bonus_redetection_scale)
            },
            None => missed(o, s.missed_redetection_penalty, Why::MissedByTrack),
        };
        self.objects.retain(|o| o.score > 0);
        Some(change)
    }

    /// The objects the `count` detection tiles show, in tile order, as `sorting_mode` orders
    /// them: 0 by score, 1 by age (oldest first), 2 by score with each object kept in its
    /// tile for its life (a freed tile takes the best object not shown).
    pub fn tiles(&mut self, sorting_mode: u8, count: usize) -> Vec<Option<u32>> {
        let mut order: Vec<&Object> = self.objects.iter().collect();
        match sorting_mode {
            1 => order.sort_by(|a, b| a.born.total_cmp(&b.born).then(b.score.cmp(&a.score))),
            _ => order.sort_by(|a, b| b.score.cmp(&a.score).then(a.born.total_cmp(&b.born))),
        }
        let ids: Vec<u32> = order.iter().map(|o| o.id).collect();
        if sorting_mode != 2 {
            self.tiles = ids.into_iter().take(count).map(Some).collect();
        } else {
            let alive = |id: &u32| self.objects.iter().any(|o| o.id == *id);
            let mut tiles: Vec<Option<u32>> = self.tiles.iter().map(|t| t.filter(alive)).collect();
            tiles.resize(count, None);
            let waiting: Vec<u32> = ids
                .into_iter()
                .filter(|id| !tiles.contains(&Some(*id)))
                .collect();
            let mut waiting = waiting.into_iter();
            for tile in tiles.iter_mut().filter(|t| t.is_none()) {
                *tile = waiting.next();
            }
            while tiles.last() == Some(&None) {
                tiles.pop();
            }
            self.tiles = tiles;
        }
        self.tiles.clone()
    }
}

/// `o` found again by `d`: its place, size, class and confidence taken from `d`, its score
/// raised by `bonus` (up to [`MAX_SCORE`]).
fn found_again(o: &mut Object, d: &Detection, t: f64, bonus: u8) -> Change {
    let from = o.score;
    let merged = merged(o, d);
    if merged {
        // Two things crossing, seen as one blob: the object is there, going as it went.
        o.bbox.centre = o.at(t).centre;
    } else if t > o.seen + 1e-3 {
        // Measured from the oldest sighting within the last MAX_PREDICTION seconds: a
        // detector's boxes wander by a fraction of their size, and over a longer baseline
        // that wander is a smaller part of the motion.
        o.trail.retain(|&(seen, _)| t - seen <= MAX_PREDICTION);
        o.trail.push((t, d.bbox.centre));
        if o.trail.len() > TRAIL {
            o.trail.remove(0);
        }
        let (first, from_centre) = o.trail[0];
        o.velocity = if t > first + 1e-3 {
            (d.bbox.centre - from_centre) / (t - first)
        } else {
            DVec3::ZERO
        };
    }
    if !merged {
        o.bbox = d.bbox;
    }
    o.class = d.class;
    o.confidence = d.confidence;
    o.seen = t;
    o.score = o.score.saturating_add(bonus).min(MAX_SCORE);
    Change {
        id: o.id,
        why: Why::FoundByScan,
        from,
        to: o.score,
    }
}

/// Whether box `d`, taken as object `o`, is `o` merged with something beside it: grown at
/// once by more than half and by more than [`MERGED_GROWTH`] (a detector's boxes wander by a
/// pixel or two of a scan view, about a third of a degree). Its centre lies between the two
/// and its size is neither's, so it moves the object nowhere (two movers crossing gave the
/// one it was taken as a velocity 4° off, and its ring left it while they were one blob).
fn merged(o: &Object, d: &Detection) -> bool {
    let (was, is) = (o.bbox.size(), d.bbox.size());
    is > 1.5 * was && is - was > MERGED_GROWTH
}

/// `o` missed: its score lowered by `penalty` (0 drops it).
fn missed(o: &mut Object, penalty: u8, why: Why) -> Change {
    let from = o.score;
    o.score = o.score.saturating_sub(penalty);
    Change {
        id: o.id,
        why,
        from,
        to: o.score,
    }
}
