//! Click to track. CAMERA_TRACK_POINT and CAMERA_TRACK_RECTANGLE name a spot of the camera's
//! own picture (0..1 from its top left); the camera's view then follows the object there,
//! one of the detection stage's tracked objects (`state::follow`: seeded where clicked,
//! found again by each scan), until CAMERA_STOP_TRACKING, a hand on the gimbal, or the object
//! is lost. While it follows, CAMERA_TRACKING_IMAGE_STATUS (where the object is in the
//! picture) and CAMERA_TRACKING_GEO_STATUS (where it is on the ground and how it moves) go to
//! the ground station 5 times a second, and once more, idle, when it stops.

use super::Cameras;
use super::commands::{Answer, Command};
use crate::autopilot::Outbox;
use crate::geometry::ground::{ground_point, to_ned};
use crate::lens::LensError;
use crate::plan::FramePlan;
use crate::state::view::{Follow, Op, Shape};
use crate::state::{State, moved_on};
use glam::{DVec2, DVec3};
use mavlink::dialects::common::*;
use std::time::{Duration, Instant};

/// How often the statuses go out while a camera follows something.
const STATUS_EVERY: Duration = Duration::from_millis(200);
/// The smallest size a click is given (radians): a point with no radius.
const MIN_SIZE: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// Why a spot of a camera's picture has no ray.
#[derive(Debug, thiserror::Error)]
pub(super) enum Unseen {
    #[error(transparent)]
    Lens(#[from] LensError),
    #[error("({:.3}, {:.3}) of camera {camera}'s picture sees nothing (outside the lens)", .at.x, .at.y)]
    Outside { camera: usize, at: DVec2 },
}

/// Whether each of `v` is a number in 0..=1.
fn normalized(v: &[f32]) -> bool {
    v.iter().all(|x| (0.0..=1.0).contains(x))
}

/// A track command's values that name no spot of the picture.
#[derive(Debug, thiserror::Error)]
enum NoClick {
    #[error("track point ({0}, {1}) radius {2}")]
    Point(f32, f32, f32),
    #[error("track rectangle ({0}, {1}) to ({2}, {3})")]
    Rectangle(f32, f32, f32, f32),
}

/// What a track command clicked in the camera's picture (0..1 from its top left): its shape,
/// centre and two corners (a point's at its radius either side), or why it is no click.
fn clicked(cmd: &Command) -> Result<(Shape, DVec2, [DVec2; 2]), NoClick> {
    let p = &cmd.params;
    if cmd.command == MavCmd::MAV_CMD_CAMERA_TRACK_POINT {
        // MAVSDK and others leave the radius NaN when they have none.
        let radius = if p[2].is_nan() { 0.0 } else { p[2] };
        if !normalized(&[p[0], p[1], radius]) {
            return Err(NoClick::Point(p[0], p[1], p[2]));
        }
        let r = radius as f64;
        let (x, y) = (p[0] as f64, p[1] as f64);
        let corners = [DVec2::new(x - r, y), DVec2::new(x + r, y)];
        return Ok((Shape::Point, DVec2::new(x, y), corners));
    }
    if !normalized(&p[..4]) || p[0] >= p[2] || p[1] >= p[3] {
        return Err(NoClick::Rectangle(p[0], p[1], p[2], p[3]));
    }
    let (a, b) = (
        DVec2::new(p[0] as f64, p[1] as f64),
        DVec2::new(p[2] as f64, p[3] as f64),
    );
    Ok((Shape::Rectangle, (a + b) / 2.0, [a, b]))
}

impl Cameras {
    /// CAMERA_TRACK_POINT (x, y, radius), CAMERA_TRACK_RECTANGLE (top left x, y, bottom
    /// right x, y) and CAMERA_STOP_TRACKING for camera `i`.
    pub(super) fn tracking_command(
        &self,
        from: &mavlink::MavHeader,
        i: usize,
        cmd: &Command,
    ) -> Answer {
        if let Err(e) = self.in_control(from, i) {
            return Answer::denied(e);
        }
        if cmd.command == MavCmd::MAV_CMD_CAMERA_STOP_TRACKING {
            return match self.gate.steer(i, Op::StopFollowing) {
                Ok(()) => Answer::accepted(vec![self.tracking_image_status(&self.state(), i)]),
                Err(e) => Answer::denied(e),
            };
        }
        let (shape, centre, corners) = match clicked(cmd) {
            Ok(c) => c,
            Err(why) => return Answer::denied(why),
        };
        let snapshot = self.state();
        let (ray, a, b) = match self.picture_rays(&snapshot, i, centre, corners) {
            Ok(r) => r,
            Err(e) => return Answer::denied(e),
        };
        let size = match shape {
            Shape::Point => a.angle_between(b),
            // The larger side: the corners' rays span the diagonal.
            Shape::Rectangle => a.angle_between(b) / std::f64::consts::SQRT_2,
        }
        .max(MIN_SIZE);
        let (yaw, pitch) = crate::geometry::rotation::yaw_pitch(ray);
        let ground = ground_point(&snapshot.vehicle.position, ray).map(|(g, _)| g);
        let follow = Follow {
            shape,
            yaw,
            pitch,
            size,
            ground,
            since_us: crate::clock::clock_us(),
            object: None,
        };
        if let Err(e) = self.gate.steer(i, Op::Follow(follow)) {
            return Answer::denied(e);
        }
        self.periodic().cameras[i].rates = None;
        tracing::info!(
            "camera {i}: follows what is at ({:.3}, {:.3}) of its picture, {:.1}° across",
            centre.x,
            centre.y,
            size.to_degrees()
        );
        Answer::accepted(vec![self.tracking_image_status(&self.state(), i)])
    }

    /// Camera `i`'s own picture as its stream draws it from `s`.
    pub(super) fn own_picture(&self, s: &State, i: usize) -> Result<FramePlan, Unseen> {
        let settings = &s.settings;
        let lens = self.gate.settings().lenses().for_frame(
            settings.lens,
            settings.sensor_size(),
            settings.sensor.roi(),
        )?;
        Ok(FramePlan::single_view(
            s,
            &lens,
            i,
            self.cfg.width,
            self.cfg.height,
        ))
    }

    /// The world rays through `centre` and the two `corners` of camera `i`'s picture
    /// (normalized, from its top left).
    fn picture_rays(
        &self,
        s: &State,
        i: usize,
        centre: DVec2,
        corners: [DVec2; 2],
    ) -> Result<(DVec3, DVec3, DVec3), Unseen> {
        let plan = self.own_picture(s, i)?;
        let view = &plan.views[0];
        let size = DVec2::new(self.cfg.width as f64, self.cfg.height as f64);
        let ray = |q: DVec2| {
            plan.world_ray(view, q * size)
                .ok_or(Unseen::Outside { camera: i, at: q })
        };
        let c = ray(centre)?;
        Ok((
            c,
            ray(corners[0]).unwrap_or(c),
            ray(corners[1]).unwrap_or(c),
        ))
    }

    /// `s` as of now, and what camera `i` follows in it: its direction and angular size,
    /// and its motion across the sky (world NED per second) where the tracker measured one.
    pub(super) fn followed_now(s: &State, i: usize) -> (State, Option<(DVec3, f64, DVec3)>) {
        let mut now = s.clone();
        now.moved_on_to(crate::clock::clock_us());
        let followed = now.settings.cameras[i]
            .follow()
            .zip(now.followed_ray(i))
            .map(|(f, ray)| match now.followed(i) {
                Some(o) => (ray, o.size, DVec3::from_array(o.velocity)),
                None => (ray, f.size, DVec3::ZERO),
            });
        (now, followed)
    }

    /// CAMERA_TRACKING_IMAGE_STATUS: where what camera `i` follows is in its picture.
    pub(super) fn tracking_image_status(&self, s: &State, i: usize) -> MavMessage {
        let mut m = CAMERA_TRACKING_IMAGE_STATUS_DATA {
            tracking_status: CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE,
            tracking_mode: CameraTrackingMode::CAMERA_TRACKING_MODE_NONE,
            target_data: CameraTrackingTargetData::empty(),
            point_x: f32::NAN,
            point_y: f32::NAN,
            radius: f32::NAN,
            rec_top_x: f32::NAN,
            rec_top_y: f32::NAN,
            rec_bottom_x: f32::NAN,
            rec_bottom_y: f32::NAN,
            camera_device_id: 0,
        };
        // Aimed as the next frame will be.
        let (now, followed) = Self::followed_now(s, i);
        let (Some(f), Some((ray, size, _))) = (now.settings.cameras[i].follow(), followed) else {
            return MavMessage::CAMERA_TRACKING_IMAGE_STATUS(m);
        };
        m.tracking_status = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE;
        m.target_data = CameraTrackingTargetData::CAMERA_TRACKING_TARGET_DATA_IN_STATUS;
        let Some(at) = self.seen_at(&now, i, ray, size) else {
            return MavMessage::CAMERA_TRACKING_IMAGE_STATUS(m);
        };
        let (x, y, half_w, half_h) = (at.centre.x, at.centre.y, at.half.x, at.half.y);
        match f.shape {
            Shape::Point => {
                m.tracking_mode = CameraTrackingMode::CAMERA_TRACKING_MODE_POINT;
                (m.point_x, m.point_y, m.radius) = (x as f32, y as f32, half_w as f32);
            }
            Shape::Rectangle => {
                m.tracking_mode = CameraTrackingMode::CAMERA_TRACKING_MODE_RECTANGLE;
                m.rec_top_x = (x - half_w) as f32;
                m.rec_top_y = (y - half_h) as f32;
                m.rec_bottom_x = (x + half_w) as f32;
                m.rec_bottom_y = (y + half_h) as f32;
            }
        }
        MavMessage::CAMERA_TRACKING_IMAGE_STATUS(m)
    }

    /// CAMERA_TRACKING_GEO_STATUS: where what camera `i` follows is on the ground, how far,
    /// and how fast it moves there.
    pub(super) fn tracking_geo_status(&self, s: &State, i: usize) -> MavMessage {
        let nan = f32::NAN;
        let mut m = CAMERA_TRACKING_GEO_STATUS_DATA {
            tracking_status: CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_IDLE,
            lat: 0,
            lon: 0,
            alt: nan,
            h_acc: nan,
            v_acc: nan,
            vel_n: nan,
            vel_e: nan,
            vel_d: nan,
            vel_acc: nan,
            dist: nan,
            hdg: nan,
            hdg_acc: nan,
            camera_device_id: 0,
        };
        let Some((ray, _, velocity)) = Self::followed_now(s, i).1 else {
            return MavMessage::CAMERA_TRACKING_GEO_STATUS(m);
        };
        m.tracking_status = CameraTrackingStatusFlags::CAMERA_TRACKING_STATUS_FLAGS_ACTIVE;
        let position = &s.vehicle.position;
        let Some((g, dist)) = ground_point(position, ray) else {
            return MavMessage::CAMERA_TRACKING_GEO_STATUS(m);
        };
        (m.lat, m.lon) = ((g.lat * 1e7).round() as i32, (g.lon * 1e7).round() as i32);
        (m.alt, m.dist) = (g.alt as f32, dist as f32);
        // Where its motion across the sky takes it on the ground in a second.
        if velocity != DVec3::ZERO
            && let Some((later, _)) = ground_point(position, moved_on(ray, velocity, 1.0))
        {
            let v = to_ned(g, later);
            (m.vel_n, m.vel_e, m.vel_d) = (v.x as f32, v.y as f32, v.z as f32);
            m.hdg = v.y.atan2(v.x).rem_euclid(std::f64::consts::TAU) as f32;
        }
        MavMessage::CAMERA_TRACKING_GEO_STATUS(m)
    }

    /// Streams camera `i`'s tracking statuses while it follows something, and once more
    /// when it stops.
    pub(super) fn report_tracking(&self, out: &Outbox, s: &State, i: usize, now: Instant) {
        let following = s.settings.cameras[i].follow().is_some();
        let due = {
            let mut p = self.periodic();
            let c = &mut p.cameras[i];
            let due = (following || c.was_following)
                && c.tracking_sent.is_none_or(|t| now - t >= STATUS_EVERY);
            if due {
                (c.tracking_sent, c.was_following) = (Some(now), following);
            }
            due
        };
        if due {
            let component = super::FIRST_COMPONENT + i as u8;
            out.send(component, &self.tracking_image_status(s, i));
            out.send(component, &self.tracking_geo_status(s, i));
        }
    }
}
