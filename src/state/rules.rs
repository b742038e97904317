//! The one table of what every field takes: for each field of each settable parameter type of
//! the control protocol, and each field of the state that no parameter type sets, its range,
//! its unit, what the protocol does with a value outside it (the seed's rules), and the
//! state-file key it sets. The protocol's handlers clamp, wrap and ignore by it;
//! [`State::validate`](super::State::validate) refuses by it what came from flags, state
//! files and the serve configuration; the entry-path tests enumerate it, and fail on a field
//! of a parameter type or of the state that it leaves out.

use super::{FPS_RANGE, MAX_CAMERAS, MAX_GAIN, MAX_OUTPUT, MAX_SENSOR, MIN_OUTPUT};
use crate::geometry::view::{control, fov_range};
use crate::layout::{LAYOUT_MODES, OVERLAY_MODES};
use crate::protocol::ParamType;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// What the protocol does with a value outside a field's range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outside {
    /// Set to the nearest end of the range.
    Clamp,
    /// Above the range: set to its top; below it: the field keeps its value.
    ClampAboveIgnoreBelow,
    /// Brought into (-π, π] by whole turns; a file takes one turn either way.
    Wrap,
    /// The field keeps its value (the rest of the SET applies).
    Ignore,
    /// Only the bits the range's top has are kept (lock flags: the low three).
    LowBits,
    /// The SET is refused (DATA_ERROR), naming the field.
    Refuse,
    /// Any value is taken as on (non-zero) or off (zero); a file takes a boolean.
    Flag,
    /// Not set over the protocol: a GET reports it, or it addresses (cam_id), or it is a
    /// step or a command rather than a setting (is_delta, zoom, offsets, CAPTURE's flags).
    NotState,
}

/// One field's rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule {
    /// The parameter type and field that set it; None: no SET sets it (the vehicle, from
    /// the autopilot; the scene's time; the tracked objects, from the detector).
    pub param: Option<(ParamType, &'static str)>,
    /// Its key in a state file (`camera.fov` for each `[[camera]]`'s `fov`); None: not in
    /// the state.
    pub key: Option<&'static str>,
    pub lo: f64,
    pub hi: f64,
    pub unit: &'static str,
    pub outside: Outside,
    /// A further bound, in words, checked beside the range (`State::validate`).
    pub also: &'static str,
}

impl Rule {
    /// Whether a state may hold `v` (files take what the protocol takes unchanged; a wrapped
    /// angle one turn either way; a milliradian of slack on angles, which the protocol
    /// carries in milliradians).
    pub fn holds(&self, v: f64) -> bool {
        let slack = if self.unit == "rad" { 1e-3 } else { 0.0 };
        match self.outside {
            Outside::Wrap => v.abs() <= TAU + slack,
            _ => v >= self.lo - slack && v <= self.hi + slack,
        }
    }

    /// `v` as the protocol sets it, given the field's value `was`: None where the SET is
    /// refused.
    pub fn apply(&self, v: f64, was: f64) -> Option<f64> {
        if v >= self.lo && v <= self.hi {
            return Some(v);
        }
        match self.outside {
            Outside::Clamp if v.is_nan() => Some(self.lo),
            Outside::Clamp => Some(v.clamp(self.lo, self.hi)),
            Outside::ClampAboveIgnoreBelow if v > self.hi => Some(self.hi),
            Outside::ClampAboveIgnoreBelow | Outside::Ignore => Some(was),
            Outside::Wrap => Some(crate::geometry::wrap_pi(v)),
            Outside::Flag => Some((v != 0.0) as u8 as f64),
            Outside::LowBits => Some(((v as u64) & (self.hi as u64)) as f64),
            Outside::Refuse => None,
            Outside::NotState => Some(v),
        }
    }

    /// The range as a reader takes it in: `5..=30`, `±π/2 rad`.
    pub fn range(&self) -> String {
        let named = |v: f64| match v {
            _ if v == PI => "π".to_string(),
            _ if v == FRAC_PI_2 => "π/2".to_string(),
            _ if v == TAU => "2π".to_string(),
            _ => format!("{v}"),
        };
        let unit = match self.unit {
            "" => String::new(),
            u => format!(" {u}"),
        };
        if self.outside == Outside::Wrap {
            // What a file takes: one turn either way.
            format!("±2π{unit}")
        } else if self.lo == -self.hi && self.hi != 0.0 {
            format!("±{}{unit}", named(self.hi))
        } else {
            format!("{}..={}{unit}", named(self.lo), named(self.hi))
        }
    }
}

const fn rule(
    param: Option<(ParamType, &'static str)>,
    key: Option<&'static str>,
    (lo, hi): (f64, f64),
    unit: &'static str,
    outside: Outside,
) -> Rule {
    Rule {
        param,
        key,
        lo,
        hi,
        unit,
        outside,
        also: "",
    }
}

/// A field a SET sets, kept in the state under `key`.
const fn set(
    param: ParamType,
    field: &'static str,
    key: &'static str,
    range: (f64, f64),
    unit: &'static str,
    outside: Outside,
) -> Rule {
    rule(Some((param, field)), Some(key), range, unit, outside)
}

/// A field of a SET that is not kept in the state.
const fn step(param: ParamType, field: &'static str, range: (f64, f64)) -> Rule {
    rule(Some((param, field)), None, range, "", Outside::NotState)
}

/// A field of the state no SET sets.
const fn state(key: &'static str, range: (f64, f64), unit: &'static str) -> Rule {
    rule(None, Some(key), range, unit, Outside::Refuse)
}

const fn also(r: Rule, also: &'static str) -> Rule {
    Rule { also, ..r }
}

const U8: (f64, f64) = (0.0, 255.0);
/// DETECTION's scores: 255 ([`KEEP`](super::KEEP)) keeps the current value.
const SCORE: (f64, f64) = (0.0, (super::KEEP - 1) as f64);
/// Ratios: [0, 0.99), the top open (checked as at most 0.98999...).
const RATIO: (f64, f64) = (0.0, 0.989_999_999_999);
/// Altitudes and heights: from below the Dead Sea to above any drone's ceiling.
pub const HEIGHTS: (f64, f64) = (-1000.0, 20_000.0);
const CAM: (f64, f64) = (0.0, (MAX_CAMERAS - 1) as f64);
const FOV: (f64, f64) = (fov_range(0).0, TAU);

use Outside::*;
use ParamType::*;

/// Every field's rule. A parameter type's fields in wire order; the state's own after.
#[rustfmt::skip]
pub const RULES: &[Rule] = &[
    set(VideoOutput, "width", "output.width", (MIN_OUTPUT.0 as f64, MAX_OUTPUT.0 as f64), "px", ClampAboveIgnoreBelow),
    set(VideoOutput, "height", "output.height", (MIN_OUTPUT.1 as f64, MAX_OUTPUT.1 as f64), "px", ClampAboveIgnoreBelow),
    set(VideoOutput, "fps", "output.fps", (FPS_RANGE.0 as f64, FPS_RANGE.1 as f64), "fps", Clamp),
    set(VideoOutput, "layout_mode", "output.layout", (0.0, (LAYOUT_MODES - 1) as f64), "", Ignore),
    set(VideoOutput, "detection_overlay_mode", "output.overlay", (0.0, (OVERLAY_MODES - 1) as f64), "", Ignore),
    step(VideoOutput, "views", U8),
    step(VideoOutput, "detection_overlay_box", U8),
    step(VideoOutput, "single_detection_size", (0.0, 65535.0)),
    step(Capture, "flags", (0.0, 3.0)),
    step(Capture, "images_captured", (0.0, 65535.0)),
    step(Capture, "videos_captured", (0.0, 65535.0)),
    also(set(Detection, "mode", "detection.mode", (0.0, 0.0), "", Ignore), "unused by the seed"),
    set(Detection, "sorting_mode", "detection.sorting_mode", (0.0, 2.0), "", Ignore),
    set(Detection, "crop_confidence_threshold", "detection.crop_confidence_threshold", RATIO, "", Ignore),
    set(Detection, "var_confidence_threshold", "detection.var_confidence_threshold", RATIO, "", Ignore),
    set(Detection, "crop_box_limit", "detection.crop_box_limit", (10.0, 500.0), "", Clamp),
    set(Detection, "var_box_limit", "detection.var_box_limit", (10.0, 500.0), "", Clamp),
    set(Detection, "crop_box_overlap", "detection.crop_box_overlap", RATIO, "", Ignore),
    set(Detection, "var_box_overlap", "detection.var_box_overlap", RATIO, "", Ignore),
    set(Detection, "creation_score_scale", "detection.creation_score_scale", SCORE, "", Ignore),
    set(Detection, "bonus_detection_scale", "detection.bonus_detection_scale", SCORE, "", Ignore),
    set(Detection, "bonus_redetection_scale", "detection.bonus_redetection_scale", SCORE, "", Ignore),
    set(Detection, "missed_detection_penalty", "detection.missed_detection_penalty", SCORE, "", Ignore),
    set(Detection, "missed_redetection_penalty", "detection.missed_redetection_penalty", SCORE, "", Ignore),
    also(set(Lens, "lens_id", "lens", U8, "", Refuse), "a lens_id of lens.cal"),
    rule(Some((CamEuler, "cam_id")), None, CAM, "", Refuse),
    step(CamEuler, "is_delta", U8),
    set(CamEuler, "yaw", "camera.yaw", (-PI, PI), "rad", Wrap),
    set(CamEuler, "pitch", "camera.pitch", (-PI, PI), "rad", Wrap),
    set(CamEuler, "roll", "camera.roll", (-FRAC_PI_2, FRAC_PI_2), "rad", Clamp),
    rule(Some((CamZoom, "cam_id")), None, CAM, "", Refuse),
    set(CamZoom, "zoom", "camera.zoom", (-128.0, 127.0), "", NotState),
    rule(Some((CamLockFlags, "cam_id")), None, CAM, "", Refuse),
    set(CamLockFlags, "flags", "camera.lock", (0.0, 7.0), "", LowBits),
    rule(Some((CamControlMode, "cam_id")), None, CAM, "", Refuse),
    also(set(CamControlMode, "mode", "camera.control", (0.0, control::PASS as f64), "", Refuse), "2 needs a target"),
    rule(Some((CamCropMode, "cam_id")), None, CAM, "", Refuse),
    also(set(CamCropMode, "mode", "camera.crop", U8, "", Ignore), "above 4 renders black"),
    rule(Some((CamOffset, "cam_id")), None, CAM, "", Refuse),
    step(CamOffset, "x", (-0.5, 0.5)),
    step(CamOffset, "y", (-0.5, 0.5)),
    step(CamOffset, "frame_rel", U8),
    step(CamOffset, "yaw", (-PI, PI)),
    step(CamOffset, "pitch", (-PI, PI)),
    rule(Some((CamFov, "cam_id")), None, CAM, "", Refuse),
    also(set(CamFov, "fov", "camera.fov", FOV, "rad", Clamp), "the crop mode's range"),
    rule(Some((CamTarget, "cam_id")), None, CAM, "", Refuse),
    step(CamTarget, "x", (-0.5, 0.5)),
    step(CamTarget, "y", (-0.5, 0.5)),
    set(CamTarget, "t_latitude", "camera.target.lat", (-90.0, 90.0), "°", Refuse),
    set(CamTarget, "t_longitude", "camera.target.lon", (-180.0, 180.0), "°", Refuse),
    set(CamTarget, "t_altitude", "camera.target.alt", HEIGHTS, "m", Refuse),
    set(CamSensor, "ae", "sensor.ae", U8, "", Flag),
    set(CamSensor, "target_brightness", "sensor.target_brightness", (1.0, 254.0), "", Clamp),
    also(set(CamSensor, "exposure_value", "sensor.exposure_us", (1.0, super::MAX_EXPOSURE_US as f64), "µs", Clamp), "the frame time at the camera's fps"),
    set(CamSensor, "gain_value", "sensor.gain", (1.0, MAX_GAIN as f64), "", Clamp),
    set(GeneralSettings, "camera_width", "sensor.width", (1.0, MAX_SENSOR as f64), "px", Refuse),
    set(GeneralSettings, "camera_height", "sensor.height", (1.0, MAX_SENSOR as f64), "px", Refuse),
    also(set(GeneralSettings, "roi_width", "sensor.roi", (0.0, MAX_SENSOR as f64), "px", Refuse), "fits the lens's calibration frame"),
    also(step(GeneralSettings, "roi_height", (0.0, MAX_SENSOR as f64)), "with roi_width"),
    set(GeneralSettings, "camera_fps", "sensor.fps", (1.0, 240.0), "fps", Refuse),
    set(GeneralSettings, "mount_yaw", "mount.yaw", (-PI, PI), "rad", Wrap),
    set(GeneralSettings, "mount_pitch", "mount.pitch", (-FRAC_PI_2, FRAC_PI_2), "rad", Refuse),
    set(GeneralSettings, "mount_roll", "mount.roll", (-PI, PI), "rad", Refuse),
    set(GeneralSettings, "run_ai", "detection.run_ai", U8, "", Flag),
    state("vehicle.attitude.yaw", (-TAU, TAU), "rad"),
    state("vehicle.attitude.pitch", (-FRAC_PI_2, FRAC_PI_2), "rad"),
    state("vehicle.attitude.roll", (-PI, PI), "rad"),
    state("vehicle.position.lat", (-90.0, 90.0), "°"),
    state("vehicle.position.lon", (-180.0, 180.0), "°"),
    state("vehicle.position.alt", HEIGHTS, "m"),
    state("vehicle.position.relative_alt", HEIGHTS, "m"),
    state("time", (-1e9, 1e9), "s"),
    state("tracked.yaw", (-TAU, TAU), "rad"),
    state("tracked.pitch", (-PI, PI), "rad"),
    also(state("tracked.size", (1e-6, PI), "rad"), "more than 0"),
    state("tracked.id", (0.0, u32::MAX as f64), ""),
    state("tracked.score", U8, ""),
    state("tracked.velocity", (-100.0, 100.0), "rad/s"),
    state("tracked.seen_us", (0.0, u64::MAX as f64), "µs"),
    state("camera.id", CAM, ""),
];

/// The rule of `field` of `param`. Every field of every parameter type has one (a test
/// checks), so a missing one is a bug, said as such.
pub fn of(param: ParamType, field: &str) -> &'static Rule {
    RULES
        .iter()
        .find(|r| r.param == Some((param, field)))
        .unwrap_or_else(|| panic!("no rule for {param} {field} in state::rules::RULES"))
}

/// `v` for `field` of `param` as the protocol sets it, given the field's value `was` (which
/// it keeps where the rule refuses `v`: a handler refuses such a SET before it gets here).
pub fn take(param: ParamType, field: &str, v: f64, was: f64) -> f64 {
    of(param, field).apply(v, was).unwrap_or(was)
}

/// The rule of the state-file key `key` (`camera.fov`).
pub fn of_key(key: &str) -> Option<&'static Rule> {
    RULES.iter().find(|r| r.key == Some(key))
}
