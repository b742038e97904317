//! The vehicle as the frame path sees it: attitude samples over time (from the autopilot, or
//! the demo's simulated flight) and the latest position, so each frame is rendered with the
//! attitude at its own capture time.

use crate::geometry::attitude::AttitudeTrack;
use crate::geometry::{Euler, GeoPosition};
use std::sync::Mutex;

/// Attitude samples kept: a few seconds at autopilot rates.
const SAMPLES: usize = 512;

pub struct Telemetry {
    track: Mutex<AttitudeTrack>,
    position: Mutex<Option<GeoPosition>>,
}

impl Default for Telemetry {
    fn default() -> Self {
        Telemetry {
            track: Mutex::new(AttitudeTrack::new(SAMPLES)),
            position: Mutex::new(None),
        }
    }
}

impl Telemetry {
    /// An attitude measured at `t_us` (the sources' clock, [`crate::source::clock_us`]).
    pub fn attitude(&self, t_us: u64, attitude: Euler) {
        self.track
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(t_us, attitude);
    }

    pub fn position(&self, position: GeoPosition) {
        *self.position.lock().unwrap_or_else(|e| e.into_inner()) = Some(position);
    }

    /// The attitude at `t_us` (None before any sample) and the latest position.
    pub fn at(&self, t_us: u64) -> (Option<Euler>, Option<GeoPosition>) {
        let attitude = self
            .track
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .at(t_us);
        let position = *self.position.lock().unwrap_or_else(|e| e.into_inner());
        (attitude, position)
    }
}
