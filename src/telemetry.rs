//! The vehicle as the frame path sees it, shared below the services: attitude and position
//! samples over time, so each frame is rendered (and its stills and KLV placed) with the
//! attitude and position at its own capture time. The MAVLink link (or the demo's simulated
//! flight) writes it, the frame loop reads it; neither knows the other.

use crate::clock::clock_us;
use crate::geometry::attitude::AttitudeTrack;
use crate::geometry::{Euler, GeoPosition, PositionSample, PositionTrack};
use crate::supervise::Locked;
use serde::{Deserialize, Serialize};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Attitude samples kept: a few seconds at autopilot rates.
const SAMPLES: usize = 512;

/// An autopilot heard within this long (µs) keeps the demo's simulated flight out.
const EXTERNAL_US: u64 = 1_000_000;

/// Which attitude a frame is rendered with (`[mavlink] attitude_sample`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AttitudeSample {
    /// Slerp between the samples around its capture time.
    #[default]
    Interpolated,
    /// The newest sample when it is rendered (only to see what interpolation is worth).
    Latest,
}

pub struct Telemetry {
    sample: AttitudeSample,
    track: Mutex<AttitudeTrack>,
    position: Mutex<PositionTrack>,
    /// Local time of the autopilot's newest attitude (0: none).
    external_us: AtomicU64,
}

impl Default for Telemetry {
    fn default() -> Self {
        Telemetry::new(AttitudeSample::Interpolated)
    }
}

impl Telemetry {
    pub fn new(sample: AttitudeSample) -> Self {
        Telemetry {
            sample,
            track: Mutex::new(AttitudeTrack::new(SAMPLES)),
            position: Mutex::default(),
            external_us: AtomicU64::new(0),
        }
    }

    /// An attitude measured at `t_us` (the sources' clock, [`crate::clock::clock_us`]).
    pub fn attitude(&self, t_us: u64, attitude: Euler) {
        self.track.locked().push(t_us, attitude);
    }

    /// An attitude from the autopilot, measured at `t_us`.
    pub fn external_attitude(&self, t_us: u64, attitude: Euler) {
        self.external_us.store(clock_us(), Ordering::Relaxed);
        self.attitude(t_us, attitude);
    }

    /// The demo's simulated flight at `t_us`: taken only while no autopilot feeds the
    /// telemetry, so the two never mix.
    pub fn simulated(&self, t_us: u64, attitude: Euler, position: GeoPosition) {
        let external = self.external_us.load(Ordering::Relaxed);
        if external != 0 && clock_us().saturating_sub(external) < EXTERNAL_US {
            return;
        }
        self.attitude(t_us, attitude);
        self.position(PositionSample {
            t_us,
            position,
            velocity: glam::DVec3::ZERO,
        });
    }

    /// A position sample (from the autopilot, or the demo's at rest with the frame's time).
    pub fn position(&self, sample: PositionSample) {
        self.position.locked().push(sample);
    }

    /// The attitude and the position at `t_us` (None before any sample).
    pub fn at(&self, t_us: u64) -> (Option<Euler>, Option<GeoPosition>) {
        let track = self.track.locked();
        let attitude = match self.sample {
            AttitudeSample::Interpolated => track.at(t_us),
            AttitudeSample::Latest => track.latest(),
        };
        drop(track);
        let position = self.position.locked().at(t_us);
        (attitude, position)
    }
}
