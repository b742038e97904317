//! A view that follows a tracked object: what a ground station clicked in a camera's picture
//! (MAVLink's CAMERA_TRACK_POINT and CAMERA_TRACK_RECTANGLE), the object the detection stage
//! took it to be, and how the view is aimed at it. The command sets it, the detection stage
//! keeps it (the object found again by each scan, or lost), and the frame loop aims the view
//! where the object has got to by each frame's capture time.

use super::{Camera, State, Tracked};
use crate::geometry::GeoPoint;
use crate::geometry::ground::ray_to_target;
use crate::geometry::rotation::direction;
use crate::geometry::view::{aim, control};
use glam::DVec3;

/// What was clicked: a point (with a radius) or a rectangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Point,
    Rectangle,
}

/// What a camera follows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Follow {
    pub shape: Shape,
    /// Where it was clicked: a world direction (yaw, pitch) and angular size, radians.
    pub yaw: f64,
    pub pitch: f64,
    pub size: f64,
    /// Where that ray meets the ground (None above the horizon): what the view holds on
    /// until the detection stage takes the click on, so a spot stays put while the vehicle
    /// moves.
    pub ground: Option<GeoPoint>,
    /// When it was clicked (`crate::clock::clock_us`): tells one click from the next.
    pub since_us: u64,
    /// The tracked object it is, once the detection stage took it on.
    pub object: Option<u32>,
}

impl Camera {
    /// The camera is steered by hand (its angles, a gimbal command, a rate): it follows
    /// neither its geographic target nor an object any more.
    pub fn steer_by_hand(&mut self) {
        if matches!(self.control, control::PILOT | control::COORDINATE) {
            self.control = control::DIRECTIONAL;
        }
        self.follow = None;
    }
}

impl State {
    /// The object camera `i` follows, as the tracked list has it; None while it follows a
    /// click the detection stage has not taken on yet.
    pub fn followed(&self, i: usize) -> Option<&Tracked> {
        let id = self.cameras[i].follow?.object?;
        self.tracked.iter().find(|o| o.id == id)
    }

    /// The world direction camera `i` follows: its object's where the tracked list has it,
    /// else the clicked ground point's from the vehicle, else the clicked direction. None
    /// when it follows nothing.
    pub fn followed_ray(&self, i: usize) -> Option<DVec3> {
        let f = self.cameras[i].follow?;
        Some(match (self.followed(i), f.ground) {
            (Some(o), _) => direction(o.yaw, o.pitch),
            (None, Some(g)) => ray_to_target(&self.vehicle.position, g)
                .unwrap_or_else(|| direction(f.yaw, f.pitch)),
            (None, None) => direction(f.yaw, f.pitch),
        })
    }

    /// The state as a frame captured at `t_us` shows it: each tracked object moved on to
    /// then, and the following views aimed at what they follow.
    pub fn moved_on_to(&mut self, t_us: u64) {
        for o in &mut self.tracked {
            *o = o.at(t_us);
        }
        self.aim_followers();
    }

    /// Aims every following camera along [`State::followed_ray`] (the caller moves the
    /// tracked list on to the frame's time first: [`State::moved_on_to`]). Its roll, fov and
    /// lock flags are kept.
    pub fn aim_followers(&mut self) {
        let vehicle = self.vehicle.attitude.euler();
        for i in 0..self.cameras.len() {
            let Some(ray) = self.followed_ray(i) else {
                continue;
            };
            let c = &mut self.cameras[i];
            let a = aim(ray, c.euler(), c.locks(), vehicle);
            (c.yaw, c.pitch) = (a.yaw, a.pitch);
        }
    }

    /// After the tracked list changed: each camera whose object is no longer in it has lost
    /// it and stops following, aimed where it last was. Returns those cameras.
    pub fn drop_lost_followers(&mut self) -> Vec<usize> {
        let mut lost = vec![];
        for i in 0..self.cameras.len() {
            let gone = self.cameras[i]
                .follow
                .is_some_and(|f| f.object.is_some() && self.followed(i).is_none());
            if gone {
                self.cameras[i].follow = None;
                lost.push(i);
            }
        }
        lost
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation::yaw_pitch;

    fn clicked(yaw: f64, pitch: f64, object: Option<u32>) -> Follow {
        Follow {
            shape: Shape::Point,
            yaw,
            pitch,
            size: 0.05,
            ground: None,
            since_us: 1,
            object,
        }
    }

    fn view_direction(s: &State, i: usize) -> (f64, f64) {
        let v = &s.vehicle;
        let m = s.cameras[i]
            .steering()
            .world_from_view(v.attitude.euler(), &v.position);
        yaw_pitch(m * glam::DVec3::X)
    }

    #[test]
    fn a_follower_looks_at_its_object_then_at_the_click_once_the_object_is_gone() {
        let mut s = State::default();
        s.vehicle.attitude.yaw = 0.4;
        s.tracked = vec![Tracked {
            id: 7,
            yaw: 1.0,
            pitch: -0.6,
            ..Tracked::default()
        }];
        s.cameras[1].follow = Some(clicked(-2.0, -0.3, Some(7)));
        s.aim_followers();
        let (yaw, pitch) = view_direction(&s, 1);
        assert!((yaw - 1.0).abs() < 1e-9 && (pitch + 0.6).abs() < 1e-9);
        // The others are left alone.
        assert_eq!(s.cameras[0], State::default().cameras[0]);

        s.tracked.clear();
        assert_eq!(s.drop_lost_followers(), vec![1]);
        assert_eq!(s.cameras[1].follow, None);
        // Aimed where the object last was.
        let (yaw, _) = view_direction(&s, 1);
        assert!((yaw - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_click_not_taken_on_yet_holds_its_direction_and_is_not_lost() {
        let mut s = State::default();
        s.cameras[2].follow = Some(clicked(0.5, -1.0, None));
        s.aim_followers();
        let (yaw, pitch) = view_direction(&s, 2);
        assert!((yaw - 0.5).abs() < 1e-9 && (pitch + 1.0).abs() < 1e-9);
        assert!(s.drop_lost_followers().is_empty());
        // Steering by hand ends it.
        s.cameras[2].steer_by_hand();
        assert_eq!(s.cameras[2].follow, None);
    }
}
