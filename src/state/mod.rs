//! The live state, in three parts a running DigiView shares: what an operator sets (the
//! [`Settings`], validated whole, behind [`LiveSettings`]; a view's aim, zoom, target, lock
//! flags and crop change only through the view operations of `view`), what the head reports
//! ([`Report`]: status, failures, services, the last frame rendered) and what the vehicle
//! sends and the detector sees ([`Sensed`]: attitude, position, tracked objects; the attitude
//! at each capture time is `crate::telemetry`'s). Every control path changes the settings
//! through the one [`Gate`], which asks the policy once.
//!
//! A [`State`] is one moment of all that, plain data: what the renderer draws a frame with
//! and a reader answers from. It is also what a state file holds (`file`) and the command
//! line's flags change (`flags`), checked by the one validation (`validate`) against the one
//! table of rules (`rules`), so a bad value is an error naming the field, not a surprise in
//! the picture.

pub mod capture;
mod detection;
pub mod file;
pub mod flags;
mod gate;
mod live;
mod report;
pub mod rules;
pub mod sensed;
pub mod services;
mod settings;
mod validate;
pub mod view;

pub use detection::{DetectionSettings, KEEP};
pub use file::StateError;
pub use gate::{Gate, Refused};
pub use live::LiveSettings;
pub use report::{CaptureFailure, Failure, RenderedFrame, Report, RunStatus};
pub use sensed::{DEFAULT_POSITION, IN_SIGHT, MAX_PREDICTION, Sensed, Tracked, Vehicle, moved_on};
pub use settings::{
    Angles, FPS_RANGE, MAX_EXPOSURE_US, MAX_GAIN, MAX_OUTPUT, MAX_SENSOR, MIN_OUTPUT, Output,
    Sensor, Settings, ThermalGain, ThermalLook,
};
pub use validate::{Invalid, Place};
pub use view::Camera;

use glam::DVec3;
use serde::{Deserialize, Serialize};

pub const MAX_CAMERAS: usize = 4;

/// One moment: the operator's settings with the vehicle and the objects as they were then
/// (and, for the synthetic world, the scene's time). A state file's top-level keys are its
/// parts' (`[output]`, `[[camera]]`, `[vehicle]`, `[[tracked]]`, `time`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(from = "file::StateFile", into = "file::StateFile")]
pub struct State {
    pub settings: Settings,
    pub vehicle: Vehicle,
    /// Tracked objects in the tracker's sorted order: the first ones get the overlay's tiles.
    pub tracked: Vec<Tracked>,
    /// Scene time in seconds (moves the synthetic world's objects).
    pub time: f64,
}

impl State {
    /// Now: the settings with the vehicle and the objects as last sensed (none while
    /// detection is off: turning it off takes them with it at once, whether or not the
    /// detection stage gets the CPU to say so).
    pub fn now(settings: &LiveSettings, sensed: &Sensed) -> State {
        State::of(&settings.snapshot(), sensed.vehicle(), &sensed.tracked())
    }

    /// `settings` with `vehicle` and the objects `tracked` (none while detection is off).
    pub fn of(settings: &Settings, vehicle: Vehicle, tracked: &[Tracked]) -> State {
        let tracked = match settings.detection.run_ai {
            true => tracked.to_vec(),
            false => vec![],
        };
        State {
            settings: settings.clone(),
            vehicle,
            tracked,
            time: 0.0,
        }
    }

    /// What the view operations see in this state.
    pub fn seen(&self) -> view::Seen<'_> {
        view::Seen {
            vehicle: &self.vehicle,
            tracked: &self.tracked,
        }
    }

    /// The object camera `i` follows, as the tracked list has it; None while it follows a
    /// click the detection stage has not taken on yet.
    pub fn followed(&self, i: usize) -> Option<&Tracked> {
        view::follow::followed(&self.settings.cameras[i], &self.tracked)
    }

    /// The world direction camera `i` follows (`view::follow::followed_ray`).
    pub fn followed_ray(&self, i: usize) -> Option<DVec3> {
        let c = &self.settings.cameras[i];
        view::follow::followed_ray(c, &self.tracked, &self.vehicle.position)
    }

    /// The state as a frame captured at `t_us` shows it: each tracked object moved on to
    /// then, and the following views aimed at what they follow.
    pub fn moved_on_to(&mut self, t_us: u64) {
        for o in &mut self.tracked {
            *o = o.at(t_us);
        }
        self.aim_followers();
    }

    /// Aims every following view at what it follows (`view::follow::aim_followers`).
    pub fn aim_followers(&mut self) {
        let seen = view::Seen {
            vehicle: &self.vehicle,
            tracked: &self.tracked,
        };
        view::follow::aim_followers(&mut self.settings.cameras, &seen);
    }
}

#[cfg(test)]
mod tests;
