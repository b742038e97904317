//! What the vehicle sends and the detector sees: the vehicle's attitude and position as the
//! autopilot link last gave them (the attitude history at capture times is the telemetry's,
//! beside it), and the tracked objects; and what the frame loop measures that services
//! report: the rate each view's own stream runs at. Written many times a second by the
//! autopilot link, the detection stage and the views' encoders, never through the settings:
//! a sample is checked against its own rules and stored, nothing of the operator's settings
//! copied or checked again.

use super::Invalid;
use super::rules::{
    Rule, VEHICLE_ALT, VEHICLE_HEIGHT, VEHICLE_LAT, VEHICLE_LON, VEHICLE_PITCH, VEHICLE_ROLL,
    VEHICLE_YAW,
};
use super::settings::Angles;
use crate::geometry::{Euler, GeoPosition};
use crate::supervise::Locked;
use crate::units::de_angle;
use arc_swap::ArcSwap;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
            pitch: -std::f64::consts::FRAC_PI_4,
            size: 0.05,
            score: 100,
            label: String::new(),
            velocity: [0.0; 3],
            seen_us: 0,
        }
    }
}

/// The live handle of what is sensed: the vehicle as last reported, and the tracked objects
/// (in the tracker's sorted order: the first ones get the overlay's tiles). Readers copy the
/// vehicle (a few numbers) and share the objects' list.
pub struct Sensed {
    vehicle: Mutex<Vehicle>,
    tracked: ArcSwap<Vec<Tracked>>,
    /// Each view's own stream's rate, frames per second as f32 bits (0: not measured).
    view_rates: [AtomicU32; super::MAX_CAMERAS],
}

impl Default for Sensed {
    fn default() -> Self {
        Sensed::new(Vehicle::default(), vec![])
    }
}

/// `v` checked against `rule` (a sample of the vehicle), naming it when outside.
fn checked(rule: &Rule, v: f64) -> Result<f64, Invalid> {
    match rule.holds(v) {
        true => Ok(v),
        false => Err(Invalid(format!(
            "{} {} is outside {}",
            rule.label,
            rule.shown(v),
            rule.range()
        ))),
    }
}

impl Sensed {
    pub fn new(vehicle: Vehicle, tracked: Vec<Tracked>) -> Sensed {
        Sensed {
            vehicle: Mutex::new(vehicle),
            tracked: ArcSwap::from_pointee(tracked),
            view_rates: Default::default(),
        }
    }

    /// The vehicle as last reported.
    pub fn vehicle(&self) -> Vehicle {
        *self.vehicle.locked()
    }

    /// The vehicle's attitude now; refused (and nothing kept) outside the vehicle's rules.
    pub fn set_attitude(&self, a: Euler) -> Result<(), Invalid> {
        let attitude = Angles {
            yaw: checked(&VEHICLE_YAW, a.yaw)?,
            pitch: checked(&VEHICLE_PITCH, a.pitch)?,
            roll: checked(&VEHICLE_ROLL, a.roll)?,
        };
        self.vehicle.locked().attitude = attitude;
        Ok(())
    }

    /// The vehicle's position now; refused (and nothing kept) outside the vehicle's rules.
    pub fn set_position(&self, p: GeoPosition) -> Result<(), Invalid> {
        checked(&VEHICLE_LAT, p.lat)?;
        checked(&VEHICLE_LON, p.lon)?;
        checked(&VEHICLE_ALT, p.alt)?;
        checked(&VEHICLE_HEIGHT, p.relative_alt)?;
        self.vehicle.locked().position = p;
        Ok(())
    }

    /// The tracked objects now.
    pub fn tracked(&self) -> Arc<Vec<Tracked>> {
        self.tracked.load_full()
    }

    pub fn set_tracked(&self, list: Vec<Tracked>) {
        self.tracked.store(Arc::new(list));
    }

    /// The rate view `i`'s own stream runs at, as last measured; None while it is not drawn
    /// or not yet measured.
    pub fn view_rate(&self, i: usize) -> Option<f32> {
        let bits = self.view_rates.get(i)?.load(Ordering::Relaxed);
        (bits != 0).then(|| f32::from_bits(bits))
    }

    /// View `i`'s own stream's rate now (None: not drawn, or not yet measured).
    pub fn set_view_rate(&self, i: usize, fps: Option<f64>) {
        if let Some(r) = self.view_rates.get(i) {
            let fps = fps.filter(|f| f.is_finite() && *f > 0.0);
            r.store(fps.map_or(0, |f| (f as f32).to_bits()), Ordering::Relaxed);
        }
    }
}
