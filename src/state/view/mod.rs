//! A view's settings, and the one set of operations that change them. Every way a view is
//! steered (the DigiView protocol, MAVLink's camera and gimbal commands, the web API, the
//! detection stage that keeps a click on its object) turns its request into an [`Op`] and
//! applies it here (`ops`), through the one gate (`super::Gate`) that asks the policy; the
//! fields are private, so nothing else can set a view's aim, zoom, target, lock flags or crop.
//! A view that follows an object is `follow`'s.

pub mod follow;
pub mod ops;
pub mod zoom;

pub use follow::{Follow, Shape};
pub use ops::{Op, Pointing, Seen, ViewError, Zoom, apply};

use crate::geometry::view::{LockFlags, Steering};
use crate::geometry::{Euler, GeoPoint};
use crate::modes::{Control, Crop, NotAMode, ThermalShow};
use crate::units::de_angle;
use serde::{Deserialize, Serialize};

/// One user-controlled camera (a view).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    /// Which camera a state file's table sets (0..=3); by default the table's place.
    #[serde(skip_serializing)]
    pub id: Option<usize>,
    #[serde(deserialize_with = "de_angle")]
    yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pitch: f64,
    #[serde(deserialize_with = "de_angle")]
    roll: f64,
    /// Horizontal field of view.
    #[serde(deserialize_with = "de_angle")]
    fov: f64,
    /// The last CAM_ZOOM step applied.
    zoom: i8,
    crop: Crop,
    /// How it shows the thermal camera, where there is one.
    #[serde(default)]
    thermal: ThermalShow,
    lock: LockFlags,
    control: Control,
    target: Option<GeoPoint>,
    /// The object the view follows (a ground station's click), steering it while set. Not
    /// in state files.
    #[serde(skip)]
    follow: Option<Follow>,
}

impl Camera {
    /// Camera `i` as DigiView starts: 90° views to the four quarters, 30° down, held in the
    /// world.
    pub fn numbered(i: usize) -> Camera {
        Camera {
            id: None,
            yaw: (i as f64 * 90.0).to_radians(),
            pitch: (-30f64).to_radians(),
            roll: 0.0,
            fov: 90f64.to_radians(),
            zoom: 0,
            crop: Crop::Rectilinear,
            thermal: ThermalShow::Off,
            lock: LockFlags::ALL,
            control: Control::Directional,
            target: None,
            follow: None,
        }
    }

    pub fn yaw(&self) -> f64 {
        self.yaw
    }
    pub fn pitch(&self) -> f64 {
        self.pitch
    }
    pub fn roll(&self) -> f64 {
        self.roll
    }
    pub fn euler(&self) -> Euler {
        Euler::new(self.yaw, self.pitch, self.roll)
    }
    pub fn fov(&self) -> f64 {
        self.fov
    }
    pub fn zoom(&self) -> i8 {
        self.zoom
    }
    pub fn crop(&self) -> Crop {
        self.crop
    }
    pub fn thermal(&self) -> ThermalShow {
        self.thermal
    }
    pub fn locks(&self) -> LockFlags {
        self.lock
    }
    pub fn control(&self) -> Control {
        self.control
    }
    pub fn target(&self) -> Option<GeoPoint> {
        self.target
    }
    pub fn follow(&self) -> Option<Follow> {
        self.follow
    }

    /// How the view is aimed, for `Steering::world_from_view`.
    pub fn steering(&self) -> Steering {
        Steering {
            control: self.control,
            angles: self.euler(),
            locks: self.lock,
            target: self.target,
        }
    }

    /// Sets `field` to `v` as given, for a flag or a test that describes a view: nothing is
    /// clamped or wrapped, and the one check (`State::validate`) refuses what is out of range.
    /// Only a mode that has no number refuses here.
    pub fn put(&mut self, field: Field, v: f64) -> Result<(), NotAMode> {
        match field {
            Field::Yaw => self.yaw = v,
            Field::Pitch => self.pitch = v,
            Field::Roll => self.roll = v,
            Field::Fov => self.fov = v,
            Field::Zoom => self.zoom = v as i8,
            Field::Crop => self.crop = Crop::from(v as u8),
            Field::Lock => self.lock = LockFlags(v as u8),
            Field::Control => self.control = Control::try_from(v as u8)?,
            Field::Thermal => self.thermal = ThermalShow::try_from(v as u8)?,
        }
        Ok(())
    }

    /// [`Camera::put`] of several fields, for a view described whole.
    pub fn with(mut self, fields: &[(Field, f64)]) -> Result<Camera, NotAMode> {
        for &(f, v) in fields {
            self.put(f, v)?;
        }
        Ok(self)
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera::numbered(0)
    }
}

/// A view's fields that a flag (`--cam 0:yaw=45deg,crop=2`) or a test sets as given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    Yaw,
    Pitch,
    Roll,
    Fov,
    Zoom,
    Crop,
    Lock,
    Control,
    Thermal,
}

impl Field {
    pub const ALL: &'static [Field] = &[
        Field::Yaw,
        Field::Pitch,
        Field::Roll,
        Field::Fov,
        Field::Zoom,
        Field::Crop,
        Field::Lock,
        Field::Control,
        Field::Thermal,
    ];

    /// Its name in a flag and a state file.
    pub fn name(self) -> &'static str {
        self.rule()
            .key
            .and_then(|k| k.strip_prefix("camera."))
            .unwrap_or("")
    }

    /// Its rule in the one table.
    pub fn rule(self) -> &'static super::rules::Rule {
        use super::rules::*;
        match self {
            Field::Yaw => &CAMERA_YAW,
            Field::Pitch => &CAMERA_PITCH,
            Field::Roll => &CAMERA_ROLL,
            Field::Fov => &CAMERA_FOV,
            Field::Zoom => &CAMERA_ZOOM,
            Field::Crop => &CAMERA_CROP,
            Field::Lock => &CAMERA_LOCK,
            Field::Control => &CAMERA_CONTROL,
            Field::Thermal => &CAMERA_THERMAL,
        }
    }

    /// Whether it is an angle (a flag may give it in degrees).
    pub fn angle(self) -> bool {
        self.rule().unit == "rad"
    }

    /// The field a flag names.
    pub fn parse(name: &str) -> Option<Field> {
        Field::ALL.iter().copied().find(|f| f.name() == name)
    }
}

#[cfg(test)]
mod tests;
