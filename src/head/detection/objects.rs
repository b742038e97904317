//! The tracked objects on their way out of the detection stage: the crops a track step
//! renders around them, and the tracker's objects ordered into the tiles and put in the live
//! state with their labels.

use super::super::Head;
use crate::detect::Detector;
use crate::detect::Tracker;
use crate::detect::motion::MOVING;
use crate::detect::onnx::class_name;
use crate::detect::scan::{ScanView, crop_view};
use crate::geometry::rotation::{direction, yaw_pitch};
use crate::layout::layout;
use crate::lens::Lens;
use crate::render::FramePlan;
use crate::state::{Invalid, State, Tracked};
use tracing::warn;

/// The track step looks again for this many objects at most, those in the tiles first.
const MAX_CROPS: usize = 6;

impl Head {
    /// Orders the tracker's objects into the tiles and puts them in the live state.
    pub(super) fn show(&self, tracker: &mut Tracker, state: &State, labels: &[String]) {
        let o = &state.output;
        let shown = layout(o.width, o.height, o.layout, o.overlay).map_or(0, |l| l.tiles.len());
        let tiles = tracker.tiles(state.detection.sorting_mode, shown);
        let name = |class: u16| match self.cfg.detection.detector {
            Detector::External => labels.get(class as usize).cloned().unwrap_or_default(),
            Detector::Motion if class == MOVING => "moving".into(),
            _ => class_name(class),
        };
        self.publish(tracked(tracker, &tiles, name));
    }

    /// Puts the objects in the live state, unless detection was turned off meanwhile.
    fn publish(&self, list: Vec<Tracked>) {
        let result = self.live.update(|s| {
            if s.detection.run_ai {
                s.tracked = list;
            }
            Ok::<_, Invalid>(())
        });
        if let Err(e) = result {
            warn!("detection: the objects were not taken: {e}");
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
/// then the others by score.
fn tracked(tracker: &Tracker, tiles: &[Option<u32>], name: impl Fn(u16) -> String) -> Vec<Tracked> {
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
