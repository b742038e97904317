//! GET of DETECTED_ROI (the tracked objects, one reply each for index 254 and 255). DETECTION
//! itself (how detections are kept and shown) is read and set by the state's own rules.

use super::Refusal;
use crate::geometry::ground::ground_point;
use crate::geometry::rotation::direction;
use crate::geometry::view::lens_from_world;
use crate::lens::Lenses;
use crate::plan::FramePlan;
use crate::protocol::params::DetectedRoi;
use crate::state::{RenderedFrame, State, Tracked};
use glam::DVec2;
use serde::Serialize;

/// DETECTED_ROI index: every detection shown in the overlay.
pub const SHOWN: u8 = 254;
/// DETECTED_ROI index: every known detection.
pub const KNOWN: u8 = 255;

/// Index 0..=253 is one known detection; 254 every one the overlay shows; 255 every known
/// one. Each reply's index is its position in the list it belongs to, and total_detections
/// that list's length; with nothing to report, one reply with total_detections 0.
pub fn detected_roi(state: &State, index: u8) -> Result<Vec<DetectedRoi>, Refusal> {
    let shown = || state.settings.output.layout().map_or(0, |l| l.tiles.len());
    let list: &[Tracked] = match index {
        SHOWN => &state.tracked[..shown().min(state.tracked.len())],
        KNOWN => &state.tracked,
        i => {
            let Some(t) = state.tracked.get(i as usize) else {
                return Err(Refusal::Data(format!(
                    "detection {i} does not exist ({} known)",
                    state.tracked.len()
                )));
            };
            return Ok(vec![roi(state, t, i, state.tracked.len())]);
        }
    };
    if list.is_empty() {
        return Ok(vec![DetectedRoi::default()]);
    }
    Ok(list
        .iter()
        .enumerate()
        .map(|(i, t)| roi(state, t, i as u8, list.len()))
        .collect())
}

fn roi(state: &State, t: &Tracked, index: u8, total: usize) -> DetectedRoi {
    let ray = direction(t.yaw, t.pitch);
    // The centre ray in the fisheye lens frame (x right, y down, z along the axis).
    let mount = state.settings.mount.euler();
    let lens = lens_from_world(state.vehicle.attitude.euler(), mount) * ray;
    let (lat, lon, alt, distance) = ground_point(&state.vehicle.position, ray)
        .map_or((0.0, 0.0, 0.0, 0.0), |(p, range)| {
            (p.lat, p.lon, p.alt, range)
        });
    DetectedRoi {
        index,
        score: t.score,
        total_detections: total.min(u8::MAX as usize) as u8,
        yaw_abs: t.yaw,
        pitch_abs: t.pitch,
        yaw_rel: lens.x.atan2(lens.z),
        pitch_rel: (-lens.y).atan2(lens.x.hypot(lens.z)),
        latitude: lat,
        longitude: lon,
        altitude: alt,
        distance,
    }
}

/// Where a tracked object shows in the output frame: which view (its camera number), and the
/// object's centre and radius there in output pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Seen {
    pub cam: u8,
    pub x: f64,
    pub y: f64,
    pub radius: f64,
    /// How fast the centre moves across the view, output pixels a second, as the tracker
    /// predicts the object (0 for one it has no velocity for): the page moves the ring on
    /// every frame it draws between updates.
    pub vx: f64,
    pub vy: f64,
}

/// How far ahead the ring's velocity is measured, µs.
const AHEAD_US: u64 = 100_000;

/// The smallest radius a mark is drawn with, in output pixels.
const MIN_RADIUS: f64 = 4.0;

/// For each tracked object (in DETECTED_ROI 255's order), every view of the layout showing its
/// centre, placed on `frame` (the frame last rendered; None before any: the state as it is).
/// No views for an object not sighted within [`IN_SIGHT`](crate::state::IN_SIGHT) of the
/// frame's capture (a scan running late): a ring on a guess marks empty ground. Empty lists
/// when the lens or the layout cannot be planned.
pub fn seen(lenses: &Lenses, state: &State, frame: Option<&RenderedFrame>) -> Vec<Vec<Seen>> {
    // Where each object will be AHEAD_US after the frame, as the tracker predicts it.
    let ahead: Vec<_> = match frame {
        Some(f) => state
            .tracked
            .iter()
            .map(|o| Some(o.at(f.captured_us + AHEAD_US)))
            .collect(),
        None => vec![None; state.tracked.len()],
    };
    // Placed as the frame shows them: with the vehicle's attitude then (a view that turns
    // with the vehicle, as the fisheye layout's, shows the world turned), each object where
    // it had got to by that frame's capture time.
    let state = &frame.map_or_else(|| state.clone(), |f| f.shown(state));
    let settings = &state.settings;
    let sensor = settings.sensor_size();
    let plan = lenses
        .for_frame(settings.lens, sensor, settings.sensor.roi())
        .ok()
        .and_then(|lens| FramePlan::new(state, &lens).ok())
        .map(|plan| plan.with_shutter(frame.and_then(|f| f.shutter_for(sensor))));
    let Some(plan) = plan else {
        return vec![vec![]; state.tracked.len()];
    };
    let shown = plan.layout.views.len();
    state
        .tracked
        .iter()
        .zip(ahead)
        .map(|(t, ahead)| {
            if frame.is_some_and(|f| !t.in_sight_at(f.captured_us)) {
                return vec![];
            }
            let ray = direction(t.yaw, t.pitch);
            plan.views[..shown]
                .iter()
                .enumerate()
                .filter_map(|(cam, view)| {
                    let (centre, radius) = plan.view_circle(view, ray, t.size)?;
                    let at = centre + DVec2::new(view.rect.x as f64, view.rect.y as f64);
                    let later = ahead
                        .as_ref()
                        .and_then(|a| plan.view_point(view, direction(a.yaw, a.pitch)));
                    let v = later.map_or(DVec2::ZERO, |p| (p - centre) / (AHEAD_US as f64 * 1e-6));
                    Some(Seen {
                        cam: cam as u8,
                        x: at.x,
                        y: at.y,
                        radius: radius.max(MIN_RADIUS),
                        vx: v.x,
                        vy: v.y,
                    })
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lens::LensCal;
    use crate::modes::{LayoutMode, OverlayMode};
    use crate::state::Report;

    /// Where `state`'s plan puts object 0 in its first view, in output pixels.
    fn placed(lenses: &Lenses, state: &State) -> DVec2 {
        let lens = lenses
            .for_frame(state.settings.lens, state.settings.sensor_size(), None)
            .unwrap();
        let plan = FramePlan::new(state, &lens).unwrap();
        let t = &state.tracked[0];
        let view = &plan.views[0];
        plan.view_point(view, direction(t.yaw, t.pitch)).unwrap()
            + DVec2::new(view.rect.x as f64, view.rect.y as f64)
    }

    #[test]
    fn rings_are_placed_with_the_vehicle_of_the_frame_they_are_drawn_over() {
        let cal = LensCal::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal"),
        )
        .unwrap();
        let lenses = Lenses::new(&cal);
        let live = Report::default();
        // The fisheye layout: its view turns with the vehicle.
        let mut state = State::default();
        let output = &mut state.settings.output;
        (output.layout, output.overlay) = (LayoutMode::Whole, OverlayMode::None);
        state.tracked = vec![Tracked {
            id: 1,
            yaw: 0.5,
            pitch: -1.0,
            size: 0.05,
            velocity: [0.0, 0.1, 0.0],
            seen_us: 1_000_000,
            ..Tracked::default()
        }];
        let ring = |live: &Report| {
            let s = &seen(&lenses, &state, live.rendered().as_ref())[0][0];
            DVec2::new(s.x, s.y)
        };
        // Before any frame: the state as it is.
        assert!(ring(&live).distance(placed(&lenses, &state)) < 1e-6);
        // A frame rendered 0.9 s after the sighting with the vehicle turned 40° and tilted.
        let mut then = state.clone();
        then.vehicle.attitude.yaw = 40f64.to_radians();
        then.vehicle.attitude.roll = 5f64.to_radians();
        live.set_rendered(RenderedFrame {
            captured_us: 1_900_000,
            pts_us: 0,
            vehicle: then.vehicle,
            shutter: None,
        });
        then.tracked[0] = then.tracked[0].at(1_900_000);
        let want = placed(&lenses, &then);
        assert!(
            ring(&live).distance(want) < 1e-6,
            "{} against {want}",
            ring(&live)
        );
        // Which is not where the state's own attitude would put it.
        assert!(want.distance(placed(&lenses, &state)) > 20.0);
        // Its velocity, for a frame 1 s after the sighting (within the prediction's reach):
        // where the tracker has it 0.1 s on, less where it is, per second.
        live.set_rendered(RenderedFrame {
            captured_us: 2_000_000,
            pts_us: 0,
            vehicle: then.vehicle,
            shutter: None,
        });
        let s = seen(&lenses, &state, live.rendered().as_ref())[0][0];
        let [mut now, mut later] = [then.clone(), then.clone()];
        now.tracked[0] = state.tracked[0].at(2_000_000);
        later.tracked[0] = state.tracked[0].at(2_100_000);
        let v = (placed(&lenses, &later) - placed(&lenses, &now)) / 0.1;
        assert!(v.length() > 1.0, "the object moves: {v}");
        assert!(
            DVec2::new(s.vx, s.vy).distance(v) < 1e-6,
            "{s:?} against {v}"
        );
        // A frame more than 1 s after the last sighting (the scans running late): where it
        // is is a guess, so no ring.
        for captured_us in [2_100_000, 5_000_000] {
            live.set_rendered(RenderedFrame {
                captured_us,
                pts_us: 0,
                vehicle: then.vehicle,
                shutter: None,
            });
            let rings = &seen(&lenses, &state, live.rendered().as_ref())[0];
            assert!(rings.is_empty(), "{captured_us}: {rings:?}");
        }
    }
}
