//! The views' thermal range over MAVLink: with a thermal sensor beside the fisheye, each
//! view's camera answers REQUEST_MESSAGE of CAMERA_THERMAL_RANGE (277) with the hottest and
//! coldest point of what the view shows (°C, the points normalized to its picture, NaN where
//! the view shows none of the thermal camera's field), says so in CAMERA_INFORMATION
//! (CAMERA_CAP_FLAGS_HAS_THERMAL_RANGE) and flags its streams as able to report it. What is
//! read comes from the video head through [`ThermalReader`], which the assembly gives. And
//! MAV_CMD_SET_CAMERA_SOURCE, which picks what the view shows (its THERMAL setting) by its
//! primary and picture-in-picture sources.

use super::commands::{Answer, Command};
use super::{Cameras, boot_ms};
use crate::modes::ThermalShow;
use crate::state::view::Op;
use mavlink::dialects::common::*;
use std::sync::Arc;

/// A point of a view's picture and its temperature: kelvin, x and y from 0 (left, top) to 1
/// (right, bottom).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub kelvin: f64,
    pub x: f64,
    pub y: f64,
}

/// What the cameras read of the thermal sensor.
pub trait ThermalReader: Send + Sync {
    /// View `camera`'s hottest and coldest point (None where it shows none of the thermal
    /// camera's field), or why nothing can be read.
    fn range(&self, camera: usize) -> Result<(Option<Point>, Option<Point>), String>;

    /// The thermal camera's horizontal field of view, radians.
    fn hfov(&self) -> f64;
}

const ZERO_CELSIUS: f64 = 273.15;

impl Cameras {
    /// The thermal sensor's reader, once the head runs one.
    pub fn set_thermal(&self, reader: Arc<dyn ThermalReader>) {
        let _ = self.thermal.set(reader);
    }

    /// The thermal camera's horizontal field of view, radians (None without a sensor).
    pub(super) fn thermal_hfov(&self) -> Option<f64> {
        self.thermal.get().map(|r| r.hfov())
    }

    /// Whether the views report a thermal range.
    pub fn has_thermal(&self) -> bool {
        self.thermal.get().is_some()
    }

    /// REQUEST_MESSAGE of CAMERA_THERMAL_RANGE for camera `i`; None without a sensor (the
    /// message is not supported then).
    pub(super) fn thermal_range(&self, i: usize) -> Option<Answer> {
        let reader = self.thermal.get()?;
        Some(match reader.range(i) {
            Ok((hottest, coldest)) => {
                let (max, max_point_x, max_point_y) = celsius(hottest);
                let (min, min_point_x, min_point_y) = celsius(coldest);
                let range = CAMERA_THERMAL_RANGE_DATA {
                    time_boot_ms: boot_ms(),
                    stream_id: super::info::VIEW_STREAM,
                    camera_device_id: 0,
                    max,
                    max_point_x,
                    max_point_y,
                    min,
                    min_point_x,
                    min_point_y,
                };
                Answer::accepted(vec![MavMessage::CAMERA_THERMAL_RANGE(range)])
            }
            Err(why) => Answer::failed(why),
        })
    }
}

/// CAMERA_SOURCE's numbers.
const SOURCE_DEFAULT: u32 = 0;
const SOURCE_RGB: u32 = 1;
const SOURCE_IR: u32 = 2;

impl Cameras {
    /// MAV_CMD_SET_CAMERA_SOURCE to camera `i` (param 1: 0, every camera, or its own
    /// component id; 2 the primary source; 3 the picture-in-picture's, 0 for none): RGB (or
    /// the default) alone shows the fisheye, IR alone the thermal picture, RGB with IR the
    /// thermal picture in the fisheye view's corner; the view's THERMAL setting, through the
    /// view operations.
    pub(super) fn camera_source(&self, i: usize, cmd: &Command) -> Answer {
        let me = super::FIRST_COMPONENT as u32 + i as u32;
        match cmd.whole(1, 255.0) {
            Some(0) => {}
            Some(id) if id == me => {}
            _ => {
                return Answer::denied(format!(
                    "device {} is not this camera: give 0 or {me}",
                    cmd.params[0]
                ));
            }
        }
        let (primary, secondary) = (cmd.whole(2, 255.0), cmd.whole(3, 255.0));
        let show = match (primary, secondary) {
            (Some(SOURCE_DEFAULT | SOURCE_RGB), Some(SOURCE_DEFAULT)) => ThermalShow::Off,
            (Some(SOURCE_IR), Some(SOURCE_DEFAULT)) => ThermalShow::Thermal,
            (Some(SOURCE_DEFAULT | SOURCE_RGB), Some(SOURCE_IR)) => ThermalShow::Pip,
            (Some(SOURCE_IR), Some(SOURCE_RGB)) => {
                return Answer::denied(
                    "the thermal picture with the fisheye in its corner is not drawn: give IR \
                     alone, or RGB with IR in the corner",
                );
            }
            _ => {
                return Answer::denied(format!(
                    "sources {} and {}: give RGB (1) or IR (2), and for the corner none (0) or \
                     the other",
                    cmd.params[1], cmd.params[2]
                ));
            }
        };
        if show != ThermalShow::Off && !self.has_thermal() {
            return Answer::denied("there is no thermal camera: start serve with --thermal");
        }
        match self.gate.steer(i, Op::Thermal(show.code())) {
            Ok(()) => Answer::accepted(self.stream_information(&self.state(), i, 0)),
            Err(e) => Answer::denied(e),
        }
    }
}

/// A point as CAMERA_THERMAL_RANGE gives it: °C, x, y; NaN where there is none.
fn celsius(p: Option<Point>) -> (f32, f32, f32) {
    match p {
        Some(p) => ((p.kelvin - ZERO_CELSIUS) as f32, p.x as f32, p.y as f32),
        None => (f32::NAN, f32::NAN, f32::NAN),
    }
}
