//! What the payload SDK's profile (`crate::payload`) asks of one view beyond the messages it
//! hands the cameras as they are: its gimbal device's attitude in and out, a box to follow
//! given in the SDK's pixels, where what it follows is, the tracked objects in its picture,
//! and the rates and continuous zoom kept moving while no autopilot link ticks the cameras.
//! Every change is a view operation through the one gate, as from every other path.

use super::Cameras;
use super::commands::{Answer, Command};
use super::info::view_quaternion;
use crate::geometry::ground::ground_point;
use crate::geometry::rotation::direction;
use crate::geometry::{GeoPoint, GeoPosition};
use crate::state::State;
use glam::{DQuat, DVec2, DVec3};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavCmd, MavMessage};
use std::time::Instant;

/// Where something is in a view's picture: its box as parts of the picture's width and
/// height (0..1 from the top left; a box may reach past the edges).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PictureBox {
    pub centre: DVec2,
    pub half: DVec2,
}

/// A tracked object seen in a view's picture.
#[derive(Clone, Debug)]
pub struct InPicture {
    pub id: u32,
    pub score: u8,
    pub label: String,
    pub at: PictureBox,
}

impl Cameras {
    /// View `i`'s GIMBAL_DEVICE_ATTITUDE_STATUS now.
    pub(crate) fn view_attitude(&self, i: usize) -> MavMessage {
        self.device_attitude(&self.state(), i)
    }

    /// View `i`'s horizontal field of view now and the widest its crop mode takes, radians.
    pub(crate) fn view_fov(&self, i: usize) -> (f64, f64) {
        let s = self.state();
        let cam = &s.settings.cameras[i.min(s.settings.cameras.len() - 1)];
        (cam.fov(), crate::geometry::view::fov_range(cam.crop()).1)
    }

    /// Where the centre of view `i` meets the ground (None above the horizon), and the
    /// vehicle's position.
    pub(crate) fn view_target(&self, i: usize) -> (Option<GeoPoint>, GeoPosition) {
        let s = self.state();
        let [w, x, y, z] = view_quaternion(&s, i).map(|v| v as f64);
        let ray = DQuat::from_xyzw(x, y, z, w) * DVec3::X;
        let position = s.vehicle.position;
        (ground_point(&position, ray).map(|g| g.0), position)
    }

    /// Follows what is in `corners` (top left, bottom right: parts of view `i`'s picture),
    /// as CAMERA_TRACK_RECTANGLE does.
    pub(crate) fn follow_box(&self, from: &MavHeader, i: usize, corners: [f32; 4]) -> Answer {
        let rectangle = MavCmd::MAV_CMD_CAMERA_TRACK_RECTANGLE;
        self.tracking_command(from, i, &track(rectangle, corners))
    }

    /// Stops view `i` following anything, as CAMERA_STOP_TRACKING does.
    pub(crate) fn unfollow(&self, from: &MavHeader, i: usize) -> Answer {
        let stop = MavCmd::MAV_CMD_CAMERA_STOP_TRACKING;
        self.tracking_command(from, i, &track(stop, [0.0; 4]))
    }

    /// Where what view `i` follows is in its picture, while it follows something.
    pub(crate) fn followed_box(&self, i: usize) -> Option<PictureBox> {
        let s = self.state();
        let (now, followed) = Self::followed_now(&s, i);
        let (ray, size, _) = followed?;
        self.seen_at(&now, i, ray, size)
    }

    /// Where something `size` across (radians) along the world `ray` is in view `i`'s own
    /// picture as `s` draws it, if the picture shows that direction.
    pub(super) fn seen_at(&self, s: &State, i: usize, ray: DVec3, size: f64) -> Option<PictureBox> {
        let plan = self.own_picture(s, i).ok()?;
        let p = plan.view_point(&plan.views[0], ray)?;
        Some(self.picture_box(s, i, p, size))
    }

    /// The tracked objects view `i`'s picture shows, where it shows them.
    pub(crate) fn objects_in_picture(&self, i: usize) -> Vec<InPicture> {
        let mut s = self.state();
        s.moved_on_to(crate::clock::clock_us());
        let Ok(plan) = self.own_picture(&s, i) else {
            return vec![];
        };
        let view = &plan.views[0];
        let (w, h) = (self.cfg.width as f64, self.cfg.height as f64);
        s.tracked
            .iter()
            .filter_map(|o| {
                let p = plan.view_point(view, direction(o.yaw, o.pitch))?;
                let inside = (0.0..=w).contains(&p.x) && (0.0..=h).contains(&p.y);
                inside.then(|| InPicture {
                    id: o.id,
                    score: o.score,
                    label: o.label.clone(),
                    at: self.picture_box(&s, i, p, o.size),
                })
            })
            .collect()
    }

    /// The box of something `size` across (radians) at pixel `p` of view `i`'s picture.
    fn picture_box(&self, s: &State, i: usize, p: DVec2, size: f64) -> PictureBox {
        let (w, h) = (self.cfg.width as f64, self.cfg.height as f64);
        let half_w = (size / 2.0) / s.settings.cameras[i].fov();
        PictureBox {
            centre: DVec2::new(p.x / w, p.y / h),
            half: DVec2::new(half_w, half_w * w / h),
        }
    }

    /// The gimbal rates and continuous zoom, moved on to now: what the autopilot link's tick
    /// does, for a link that runs without one. Ticked from both, each moves by the time since
    /// the other.
    pub(crate) fn keep_moving(&self) {
        let n = Cameras::count(&self.state());
        let now = Instant::now();
        let dt = {
            let mut p = self.periodic();
            let dt = p.ticked.map_or(0.0, |t| (now - t).as_secs_f64().min(0.2));
            p.ticked = Some(now);
            dt
        };
        self.apply_motion(n, dt);
    }
}

/// A tracking command with its first four parameters.
fn track(command: MavCmd, [a, b, c, d]: [f32; 4]) -> Command {
    Command {
        command,
        params: [a, b, c, d, 0.0, 0.0, 0.0],
        location: (0.0, 0.0, 0.0),
        above_home: false,
    }
}
