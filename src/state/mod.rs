//! The live state: everything an operator can set (what the control protocol, and later
//! MAVLink and the web page, reach) plus the vehicle's attitude, position and the camera mount,
//! the input of every render.
//!
//! `State` is plain data. It is read from a TOML state file (`file`), overridden by
//! command-line flags in the same `key=value` form (`flags`) and checked for range by one
//! validation every entry path goes through (`validate`), so a bad value is an error naming
//! the field, not a surprise in the picture. `live` is the handle a running DigiView shares:
//! writers change it whole, the frame loop snapshots it once per frame.

pub mod capture;
mod detection;
pub mod file;
pub mod flags;
pub mod follow;
pub mod live;
pub mod rules;
pub mod services;
mod validate;

pub use file::StateError;
pub use live::{Failure, Live, RenderedFrame, RunStatus};
pub use validate::Invalid;

use crate::geometry::view::{LockFlags, Steering, control, crop};
use crate::geometry::{Euler, GeoPoint, GeoPosition};
use crate::lens::Roi;
use crate::units::de_angle;
use serde::{Deserialize, Serialize};

pub use detection::{DetectionSettings, KEEP};

pub const MAX_CAMERAS: usize = 4;
/// The output sizes and frame rates VIDEO_OUTPUT allows (the seed's ranges).
pub const MIN_OUTPUT: (u32, u32) = (640, 480);
pub const MAX_OUTPUT: (u32, u32) = (1920, 1080);
pub const FPS_RANGE: (u32, u32) = (5, 30);

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Output {
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    pub layout: u8,
    pub overlay: u8,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            width: 1920,
            height: 1080,
            fps: 30,
            layout: 4,
            overlay: 2,
        }
    }
}

/// One user-controlled camera (a view).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    /// Which camera this table sets (0..=3); by default the table's position in the list.
    #[serde(skip_serializing)]
    pub id: Option<usize>,
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    #[serde(deserialize_with = "de_angle")]
    pub roll: f64,
    /// Horizontal field of view.
    #[serde(deserialize_with = "de_angle")]
    pub fov: f64,
    /// The last CAM_ZOOM step applied.
    pub zoom: i8,
    pub crop: u8,
    pub lock: u8,
    /// 0 pilot, 1 directional, 2 coordinate (aims at `target`), 3 pass.
    pub control: u8,
    pub target: Option<GeoPoint>,
    /// The object the view follows (a ground station's click), steering it while set. Not
    /// in state files.
    #[serde(skip)]
    pub follow: Option<follow::Follow>,
}

impl Camera {
    pub fn euler(&self) -> Euler {
        Euler::new(self.yaw, self.pitch, self.roll)
    }
    pub fn locks(&self) -> LockFlags {
        LockFlags(self.lock)
    }
    /// How the view is aimed, for `Steering::world_from_view`.
    pub fn steering(&self) -> Steering {
        Steering {
            control: self.control,
            angles: self.euler(),
            locks: self.locks(),
            target: self.target,
        }
    }
    fn numbered(i: usize) -> Camera {
        Camera {
            id: None,
            yaw: (i as f64 * 90.0).to_radians(),
            pitch: (-30f64).to_radians(),
            roll: 0.0,
            fov: 90f64.to_radians(),
            zoom: 0,
            crop: crop::RECTILINEAR,
            lock: 7,
            control: control::DIRECTIONAL,
            target: None,
            follow: None,
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera::numbered(0)
    }
}

/// Angles as written in a state file: radians or `"30deg"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Angles {
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    #[serde(deserialize_with = "de_angle")]
    pub roll: f64,
}

impl Angles {
    pub fn euler(&self) -> Euler {
        Euler::new(self.yaw, self.pitch, self.roll)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Vehicle {
    pub attitude: Angles,
    pub position: GeoPosition,
}

impl Default for Vehicle {
    fn default() -> Self {
        Vehicle {
            attitude: Angles::default(),
            position: DEFAULT_POSITION,
        }
    }
}

/// 50 m above a home at 100 m AMSL (the synthetic world's origin).
pub const DEFAULT_POSITION: GeoPosition = GeoPosition {
    lat: 58.0,
    lon: 15.0,
    alt: 150.0,
    relative_alt: 50.0,
};

/// The fisheye camera: its frame size and optional sensor crop (GENERAL_SETTINGS).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sensor {
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    /// Sensor crop [x, y, width, height] in pixels of the lens's calibration frame.
    pub roi: Option<[u32; 4]>,
    /// Automatic exposure (CAM_SENSOR).
    pub ae: bool,
    pub target_brightness: u8,
    /// Exposure in microseconds.
    pub exposure_us: u32,
    pub gain: u32,
}

/// CAM_SENSOR's longest exposure (µs) and highest gain (thousandths), the seed's.
pub const MAX_EXPOSURE_US: u32 = 40_000;
pub const MAX_GAIN: u32 = 50_000;

impl Sensor {
    /// The longest exposure at the camera's frame rate, microseconds.
    pub fn longest_exposure_us(&self) -> u32 {
        MAX_EXPOSURE_US.min(1_000_000 / self.fps.max(1))
    }

    /// The sensor crop as a lens takes it.
    pub fn roi(&self) -> Option<Roi> {
        self.roi.map(|[x, y, width, height]| Roi {
            x: x as f64,
            y: y as f64,
            width: width as f64,
            height: height as f64,
        })
    }
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor {
            width: 3840,
            height: 2160,
            fps: 30,
            roi: None,
            ae: true,
            target_brightness: 128,
            exposure_us: 10_000,
            gain: 1_000,
        }
    }
}

/// A tracked object that gets a detection tile: its centre ray in the world and its angular size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tracked {
    pub id: u32,
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    /// Angular diameter.
    #[serde(deserialize_with = "de_angle")]
    pub size: f64,
    pub score: u8,
    /// What it is, as its detector names it ("moving", a model's class); empty if not said.
    pub label: String,
    /// How fast its centre moves across the sky (world NED, per second) and when it was
    /// last seen (`crate::clock::clock_us`): each frame shows it where it has got to by the
    /// time that frame was captured. The tracker's alone; not in state files.
    #[serde(skip)]
    pub velocity: [f64; 3],
    #[serde(skip)]
    pub seen_us: u64,
}

/// An object no scan or crop has found for this long, seconds, is lost to sight: where it is
/// is a guess, and a tile or a ring placed on the guess shows empty ground.
pub const IN_SIGHT: f64 = 1.0;

/// Prediction reaches this far from an object's last sighting at most, seconds.
pub const MAX_PREDICTION: f64 = 2.0;

/// Where a thing seen at `centre` (a unit direction), its direction moving at `velocity` a
/// second, should be `seconds` later (before, for a negative `seconds`: a frame captured
/// before the scan that saw it): up to [`MAX_PREDICTION`] of that motion either way.
pub fn moved_on(centre: glam::DVec3, velocity: glam::DVec3, seconds: f64) -> glam::DVec3 {
    let seconds = seconds.clamp(-MAX_PREDICTION, MAX_PREDICTION);
    (centre + velocity * seconds)
        .try_normalize()
        .unwrap_or(centre)
}

impl Tracked {
    /// Whether a frame captured at `t_us` shows the object where the tracker has it: within
    /// [`IN_SIGHT`] of its last sighting, either way. An object with no sighting time (given
    /// by a state file or a flag, held still) always is.
    pub fn in_sight_at(&self, t_us: u64) -> bool {
        self.seen_us == 0 || (t_us as f64 - self.seen_us as f64).abs() * 1e-6 <= IN_SIGHT
    }

    /// The object where it should be at `t_us` (`crate::clock::clock_us`), moving as it did:
    /// after its sighting, or before it (a frame captured before the scan that saw it shows
    /// it further back).
    pub fn at(&self, t_us: u64) -> Tracked {
        let since = (t_us as f64 - self.seen_us as f64) * 1e-6;
        if since == 0.0 || self.velocity == [0.0; 3] {
            return self.clone();
        }
        let seen = crate::geometry::rotation::direction(self.yaw, self.pitch);
        let now = moved_on(seen, glam::DVec3::from_array(self.velocity), since);
        let (yaw, pitch) = crate::geometry::rotation::yaw_pitch(now);
        Tracked {
            yaw,
            pitch,
            ..self.clone()
        }
    }
}

impl Default for Tracked {
    fn default() -> Self {
        Tracked {
            id: 0,
            yaw: 0.0,
            pitch: -FRAC_PI_4,
            size: 0.05,
            score: 100,
            label: String::new(),
            velocity: [0.0; 3],
            seen_us: 0,
        }
    }
}

/// The largest fisheye frame, each way (GENERAL_SETTINGS's camera size).
pub const MAX_SENSOR: u32 = 8192;

const FRAC_PI_4: f64 = std::f64::consts::FRAC_PI_4;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct State {
    pub output: Output,
    /// lens_id in lens.cal (0 CIL216, 1 CIL018, 2 LN007); a state file may give the name.
    #[serde(deserialize_with = "file::lens_id")]
    pub lens: u8,
    #[serde(rename = "camera")]
    pub cameras: Vec<Camera>,
    pub vehicle: Vehicle,
    pub mount: Angles,
    pub sensor: Sensor,
    pub detection: DetectionSettings,
    /// Tracked objects in the tracker's sorted order: the first ones get the overlay's tiles.
    #[serde(rename = "tracked")]
    pub tracked: Vec<Tracked>,
    /// Scene time in seconds (moves the synthetic world's objects).
    pub time: f64,
}

impl Default for State {
    fn default() -> Self {
        State {
            output: Output::default(),
            lens: 0,
            cameras: (0..MAX_CAMERAS).map(Camera::numbered).collect(),
            vehicle: Vehicle::default(),
            mount: Angles {
                yaw: 0.0,
                pitch: -std::f64::consts::FRAC_PI_2,
                roll: 0.0,
            },
            sensor: Sensor::default(),
            detection: DetectionSettings::default(),
            tracked: vec![],
            time: 0.0,
        }
    }
}
