//! What one view of one frame shows, for its KLV: the frame's capture time, the vehicle's pose
//! at that time (the attitude sample and position the frame was rendered with), the view's
//! pointing relative to the airframe (an earth-locked view turned back into the airframe's
//! axes with that same sample), its fields of view, and where its centre and corners meet
//! the ground (the plane at the home altitude, as DETECTED_ROI and CAM_TARGET use), and the
//! tracked objects it shows, where. A view showing the thermal picture alone describes the
//! thermal camera's own footprint.

use super::vmti::{Target, Vmti};
use crate::geometry::Euler;
use crate::geometry::ground::{GeoPoint, ground_point};
use crate::geometry::rotation::direction;
use crate::plan::{FramePlan, PlannedView};
use crate::state::State;
use glam::{DMat3, DVec2, DVec3};

/// Yaw, pitch and roll in degrees.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Degrees {
    pub yaw: f64,
    pub pitch: f64,
    pub roll: f64,
}

impl From<Euler> for Degrees {
    fn from(e: Euler) -> Self {
        Degrees {
            yaw: e.yaw.to_degrees(),
            pitch: e.pitch.to_degrees(),
            roll: e.roll.to_degrees(),
        }
    }
}

/// Where a ray from the vehicle meets the ground, and how far away.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GroundHit {
    pub point: GeoPoint,
    /// Metres.
    pub range: f64,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ViewMetadata {
    /// The frame's capture time, µs since 1970.
    pub time_us: u64,
    /// Which view (tag 11): "DigiView cam N".
    pub source: String,
    /// The vehicle's heading, pitch and roll.
    pub platform: Degrees,
    /// The vehicle's position (the sensor's: the camera is on the vehicle).
    pub sensor: GeoPoint,
    /// Horizontal and vertical field of view, degrees: the angles between the rays at the
    /// middles of opposite edges.
    pub fov: (f64, f64),
    /// The view's pointing relative to the airframe: azimuth (clockwise from the nose),
    /// elevation (negative down) and twist about its axis.
    pub relative: Degrees,
    /// Where the view's centre meets the ground; None above the horizon or beyond 10 km.
    pub centre: Option<GroundHit>,
    /// Where its corners meet the ground, from the top left clockwise; None unless all four
    /// do.
    pub corners: Option<[GeoPoint; 4]>,
    /// The tracked objects it shows (ST 0903 VMTI); None leaves tag 74 out.
    pub objects: Option<Vmti>,
}

impl ViewMetadata {
    /// The metadata of `view` of `plan`, rendered with `state` (its vehicle and tracked
    /// objects as at the frame's capture, `time_us`), drawn in a frame of `frame` pixels
    /// (None where the frame does not draw it); None for a view that looks nowhere (an
    /// unknown crop mode).
    pub fn of(
        plan: &FramePlan,
        view: &PlannedView,
        state: &State,
        (time_us, frame): (u64, Option<(u32, u32)>),
        source: String,
    ) -> Option<ViewMetadata> {
        let pose = (state, time_us, source);
        // A view showing the thermal picture alone is the thermal camera's: its footprint
        // is the thermal frame's, and the tracked objects are not placed in it.
        if let Some((entry, origin, size)) =
            plan.thermal.as_ref().and_then(|l| l.alone_in(view.rect))
        {
            let ray = |x: f64, y: f64| Some(entry.world_ray(origin + DVec2::new(x, y)).normalize());
            return ViewMetadata::from_rays(ray, (size.x, size.y), pose);
        }
        let (w, h) = (view.rect.w as f64, view.rect.h as f64);
        let ray = |x: f64, y: f64| plan.view_ray(view, DVec2::new(x, y)).map(DVec3::normalize);
        let m = ViewMetadata::from_rays(ray, (w, h), pose)?;
        Some(ViewMetadata {
            objects: Some(objects(plan, view, state, frame)),
            ..m
        })
    }

    /// The metadata of a picture `w` × `h` whose point (x, y) looks along `ray(x, y)`, with
    /// no tracked objects.
    fn from_rays(
        ray: impl Fn(f64, f64) -> Option<DVec3>,
        (w, h): (f64, f64),
        (state, time_us, source): (&State, u64, String),
    ) -> Option<ViewMetadata> {
        let boresight = ray(w / 2.0, h / 2.0)?;
        let top = ray(w / 2.0, 0.0).unwrap_or(DVec3::NEG_Z);
        let angle = |a: Option<DVec3>, b: Option<DVec3>| match (a, b) {
            (Some(a), Some(b)) => a.angle_between(b).to_degrees(),
            _ => 0.0,
        };
        let fov = (
            angle(ray(0.0, h / 2.0), ray(w, h / 2.0)),
            angle(Some(top), ray(w / 2.0, h)),
        );
        // The picture's axes in the world (forward, right, down), its up taken from the ray
        // at the middle of its top edge.
        let down = -(top - boresight * top.dot(boresight)).normalize_or_zero();
        let world_from_view = DMat3::from_cols(boresight, down.cross(boresight), down);
        let vehicle = state.vehicle.attitude.euler();
        let body_from_view = vehicle.matrix().transpose() * world_from_view;
        let position = &state.vehicle.position;
        let hit = |ray: DVec3| ground_point(position, ray);
        let corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
            .map(|(x, y)| ray(x, y).and_then(hit).map(|(p, _)| p));
        Some(ViewMetadata {
            time_us,
            source,
            platform: vehicle.into(),
            sensor: position.point(),
            fov,
            relative: Euler::from_matrix(&body_from_view).into(),
            centre: hit(boresight).map(|(point, range)| GroundHit { point, range }),
            corners: corners
                .iter()
                .all(Option::is_some)
                .then(|| corners.map(|c| c.expect("all met the ground"))),
            objects: None,
        })
    }
}

impl ViewMetadata {
    /// The same without its tracked objects unless `keep` (`klv_objects`).
    pub fn with_objects(self, keep: bool) -> ViewMetadata {
        ViewMetadata {
            objects: self.objects.filter(|_| keep),
            ..self
        }
    }

    /// The metadata of camera `cam`'s view in the composed frame of `plan` (drawn with
    /// `state`, captured at `time_us`): its objects placed in the frame's pixels where the
    /// frame draws the camera, without pixels where it does not.
    pub fn of_camera(
        plan: &FramePlan,
        state: &State,
        cam: usize,
        time_us: u64,
    ) -> Option<ViewMetadata> {
        let frame = plan
            .shows_camera(cam)
            .then_some((state.settings.output.width, state.settings.output.height));
        let view = plan.camera_view(state, cam);
        ViewMetadata::of(
            plan,
            &view,
            state,
            (time_us, frame),
            format!("DigiView cam {cam}"),
        )
    }
}

/// The tracked objects whose centres `view` shows, placed in its frame of `frame` pixels.
fn objects(plan: &FramePlan, view: &PlannedView, state: &State, frame: Option<(u32, u32)>) -> Vmti {
    let targets = state.tracked.iter().filter_map(|t| {
        let ray = direction(t.yaw, t.pitch);
        let (centre, radius) = plan.view_circle(view, ray, t.size)?;
        let pixels = frame.map(|(w, h)| {
            let at = centre + DVec2::new(view.rect.x as f64, view.rect.y as f64);
            let px = |p: DVec2| {
                let p = p
                    .floor()
                    .clamp(DVec2::ZERO, DVec2::new(w as f64 - 1.0, h as f64 - 1.0));
                (p.x as u32, p.y as u32)
            };
            let r = DVec2::splat(radius);
            [px(at), px(at - r), px(at + r)]
        });
        Some(Target {
            id: t.id,
            pixels,
            score: t.score,
            label: t.label.clone(),
            ground: ground_point(&state.vehicle.position, ray).map(|(p, _)| p),
        })
    });
    Vmti {
        size: frame,
        total: state.tracked.len(),
        targets: targets.collect(),
    }
}
