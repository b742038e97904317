//! The tracked objects on their way out of the detection stage: the crops a track step
//! renders around them, and the tracker's objects ordered into the tiles and put in the live
//! state with their labels.

use super::super::Head;
use crate::detect::Detector;
use crate::detect::motion::MOVING;
use crate::detect::onnx::class_name;
use crate::detect::scan::{ScanView, crop_view};
use crate::detect::tracker::Object;
use crate::detect::tracker::UNKNOWN_CLASS;
use crate::detect::{AngularBox, Tracker};
use crate::geometry::rotation::{direction, yaw_pitch};
use crate::lens::Lens;
use crate::plan::FramePlan;
use crate::state::view::{Seen, follow};
use crate::state::{IN_SIGHT, Invalid, State, Tracked};
use tracing::{info, warn};

/// The track step looks again for this many objects at most, those in the tiles first.
const MAX_CROPS: usize = 6;

/// Clicks taken on by the detection stage and not yet in the settings: the camera, the
/// click's time (`Follow::since_us`) and the object it became.
pub(super) type Adopted = Vec<(usize, u64, u32)>;

impl Head {
    /// Takes on each camera's click not taken on yet: the tracked object under it (its box
    /// reaching the clicked one; found more than once before seen once, then the nearest),
    /// else a new object seeded there at full score.
    /// The next [`Head::show`] makes the camera follow it.
    pub(super) fn adopt_clicks(&self, tracker: &mut Tracker, state: &State, adopted: &mut Adopted) {
        for (i, cam) in state.settings.cameras.iter().enumerate() {
            let Some(f) = cam.follow().filter(|f| f.object.is_none()) else {
                continue;
            };
            if adopted
                .iter()
                .any(|&(c, since, _)| c == i && since == f.since_us)
            {
                continue;
            }
            let t = f.since_us as f64 * 1e-6;
            let clicked = AngularBox::new(f.yaw, f.pitch, f.size, f.size);
            // Under the click (anywhere on its way since it was last seen: the operator's
            // picture and the scans both lag), a track found again since it was made before
            // one seen once (a blob of the last scan beside a mover is more often noise than
            // the mover), then the nearest.
            let under = tracker
                .objects()
                .iter()
                .map(|o| {
                    (
                        o.id,
                        o.nearest_since_seen(t, &clicked),
                        o.bbox.size(),
                        o.seen <= o.born,
                    )
                })
                .filter(|&(_, away, size, _)| away <= (size + f.size) / 2.0)
                .min_by(|a, b| a.3.cmp(&b.3).then(a.1.total_cmp(&b.1)))
                .map(|(id, ..)| id);
            let class = match self.cfg.detection.detector {
                Detector::Motion => MOVING,
                _ => UNKNOWN_CLASS,
            };
            let id = under.unwrap_or_else(|| tracker.seed(clicked, class, t));
            let how = if under.is_some() {
                "tracked already"
            } else {
                "new"
            };
            info!("camera {i}: follows object {id} ({how})");
            adopted.push((i, f.since_us, id));
        }
    }

    /// Orders the tracker's objects into the tiles and publishes them, with the clicks
    /// `adopted` since the last time, as of `now` (seconds on the clock): an object not seen
    /// for [`IN_SIGHT`] is left out (no tile, no ring, not in DETECTED_ROI) until a scan
    /// finds it again, unless a camera follows it. Returns the list and how many of it the
    /// tiles show.
    pub(super) fn show(
        &self,
        tracker: &mut Tracker,
        state: &State,
        labels: &[String],
        (adopted, now): (&mut Adopted, f64),
    ) -> (Vec<Tracked>, usize) {
        let shown = state.settings.output.layout().map_or(0, |l| l.tiles.len());
        let tiles = tracker.tiles(state.settings.detection.sorting_mode, shown);
        let name = |class: u16| match self.cfg.detection.detector {
            Detector::External => labels.get(class as usize).cloned().unwrap_or_default(),
            Detector::Motion if class == MOVING => "moving".into(),
            _ if class == UNKNOWN_CLASS => "pointed at".into(),
            _ => class_name(class),
        };
        let followed = |id: u32| {
            let id = Some(id);
            let camera = |c: &crate::state::Camera| c.follow().is_some_and(|f| f.object == id);
            state.settings.cameras.iter().any(camera) || adopted.iter().any(|a| Some(a.2) == id)
        };
        let in_sight = |o: &Object| now - o.seen <= IN_SIGHT || followed(o.id);
        let list = tracked(tracker, &tiles, name, in_sight);
        self.publish(list.clone(), std::mem::take(adopted));
        (list, shown)
    }

    /// Puts the objects in what is sensed, unless detection was turned off meanwhile: each
    /// camera whose click was adopted (and not replaced by another since) follows its
    /// object, each whose object is gone stops, and the followers are aimed (`view::follow`).
    fn publish(&self, list: Vec<Tracked>, adopted: Adopted) {
        if !self.settings().detection.run_ai {
            return;
        }
        let vehicle = self.gate.sensed().vehicle();
        let result = self.gate.change(|s| {
            for (i, since, id) in adopted {
                follow::adopt(&mut s.cameras, i, since, id);
            }
            let lost = follow::drop_lost(&mut s.cameras, &list);
            let seen = Seen {
                vehicle: &vehicle,
                tracked: &list,
            };
            follow::aim_followers(&mut s.cameras, &seen);
            Ok::<_, Invalid>(lost)
        });
        self.gate.sensed().set_tracked(list);
        for i in result.as_ref().map_or(&[][..], |l| &l[..]) {
            info!("camera {i}: lost the object it followed; it stays aimed where it last was");
        }
        if let Err(e) = result {
            warn!("detection: the followers were not aimed: {e}");
        }
    }
}

/// The crops of a track step for `state`'s objects, tiles first, where they should be at
/// `t_us`: square views of the model's `side`, those the lens images. Their ids, and the
/// mosaic that renders them.
pub(super) fn crop_plan(
    state: &State,
    lens: &Lens,
    to_lens: glam::DMat3,
    side: u32,
    t_us: u64,
) -> (Vec<ScanView>, Vec<u32>, FramePlan) {
    let (mut views, mut ids) = (vec![], vec![]);
    for o in state.tracked.iter().take(MAX_CROPS) {
        let o = o.at(t_us);
        let ray = direction(o.yaw, o.pitch);
        if lens
            .project(to_lens * ray)
            .is_some_and(|q| lens.in_frame(q))
        {
            views.push(crop_view(o.id, o.yaw, o.pitch, o.size));
            ids.push(o.id);
        }
    }
    let aims: Vec<_> = views.iter().map(|v| (v.yaw, v.pitch, v.fov)).collect();
    let columns = (views.len() as f64).sqrt().ceil() as u32;
    let plan = FramePlan::mosaic(lens, to_lens, &aims, (side, side), columns);
    (views, ids, plan)
}

/// The tracker's objects as the state lists them: those in the tiles first, in tile order,
/// then the others by score; of them, those `in_sight`.
fn tracked(
    tracker: &Tracker,
    tiles: &[Option<u32>],
    name: impl Fn(u16) -> String,
    in_sight: impl Fn(&Object) -> bool,
) -> Vec<Tracked> {
    let mut ids: Vec<u32> = tiles.iter().flatten().copied().collect();
    let mut rest: Vec<_> = tracker
        .objects()
        .iter()
        .filter(|o| !ids.contains(&o.id))
        .collect();
    rest.sort_by_key(|o| std::cmp::Reverse(o.score));
    ids.extend(rest.iter().map(|o| o.id));
    ids.iter()
        .filter_map(|&id| tracker.get(id))
        .filter(|o| in_sight(o))
        .map(|o| {
            let (yaw, pitch) = yaw_pitch(o.bbox.centre);
            Tracked {
                id: o.id,
                yaw,
                pitch,
                size: o.bbox.size(),
                score: o.score,
                label: name(o.class),
                velocity: o.velocity.to_array(),
                seen_us: (o.seen * 1e6) as u64,
            }
        })
        .collect()
}
