//! The one table of what every field takes: for each field of each settable parameter type of
//! the control protocol, and each field of the state that no parameter type sets, its range,
//! its unit, what the protocol does with a value outside it (the seed's rules), the state-file
//! key it sets and where the state holds it. Each rule is a named constant
//! ([`CAMERA_YAW`], [`OUTPUT_FPS`]) that the code applies by name, so a field the table lacks
//! does not compile; [`RULES`] lists them all. The view operations (`super::view`) and the
//! protocol's handlers clamp, wrap and ignore by them; [`State::validate`](super::State::validate)
//! refuses by them what came from flags, state files and the serve configuration, reading
//! each field through its rule ([`Of`]); the entry-path tests enumerate the list, and fail on
//! a field of a parameter type or of the state that it leaves out.

use super::MAX_CAMERAS;
use super::detection::DetectionSettings;
use super::sensed::{Tracked, Vehicle};
use super::settings::{
    Angles, FPS_RANGE, MAX_GAIN, MAX_OUTPUT, MAX_SENSOR, MIN_OUTPUT, Output, Sensor, ThermalLook,
};
use super::view::Camera;
use crate::geometry::view::fov_range;
use crate::modes::{Control, Crop, LayoutMode, OverlayMode, ThermalShow};
use crate::protocol::ParamType;
use crate::thermal::Palette;
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

/// Where the state holds a field: how the one check reads it.
#[derive(Clone, Copy)]
pub enum Of {
    /// Nowhere: a field of a message, or a key a file gives that is checked where it is read
    /// (a camera table's `id`).
    Nowhere,
    Output(fn(&Output) -> f64),
    Lens,
    /// Each camera's (None: it has none, a target it was not given).
    Camera(fn(&Camera) -> Option<f64>),
    Mount(fn(&Angles) -> f64),
    Sensor(fn(&Sensor) -> f64),
    /// The sensor crop's four numbers, where there is one.
    SensorCrop,
    Detection(fn(&DetectionSettings) -> f64),
    Thermal(fn(&ThermalLook) -> f64),
    Vehicle(fn(&Vehicle) -> f64),
    /// Each tracked object's.
    Tracked(fn(&Tracked) -> f64),
    /// Each tracked object's three velocity components.
    TrackedVelocity,
    Time,
}

impl std::fmt::Debug for Of {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = match self {
            Of::Nowhere => "Nowhere",
            Of::Output(_) => "Output",
            Of::Lens => "Lens",
            Of::Camera(_) => "Camera",
            Of::Mount(_) => "Mount",
            Of::Sensor(_) => "Sensor",
            Of::SensorCrop => "SensorCrop",
            Of::Detection(_) => "Detection",
            Of::Thermal(_) => "Thermal",
            Of::Vehicle(_) => "Vehicle",
            Of::Tracked(_) => "Tracked",
            Of::TrackedVelocity => "TrackedVelocity",
            Of::Time => "Time",
        };
        f.write_str(name)
    }
}

/// One field's rule.
#[derive(Clone, Copy, Debug)]
pub struct Rule {
    /// The parameter type and field that set it; None: no SET sets it (the vehicle, from
    /// the autopilot; the scene's time; the tracked objects, from the detector).
    pub param: Option<(ParamType, &'static str)>,
    /// Its key in a state file (`camera.fov` for each `[[camera]]`'s `fov`); None: not in
    /// the state.
    pub key: Option<&'static str>,
    /// What it is to a reader, after its camera or object (`fov`, `lock flags`).
    pub label: &'static str,
    pub lo: f64,
    pub hi: f64,
    pub unit: &'static str,
    pub outside: Outside,
    /// A further bound, in words, checked beside the range (`State::validate`).
    pub also: &'static str,
    /// Where the state holds it.
    pub of: Of,
}

impl PartialEq for Rule {
    fn eq(&self, other: &Rule) -> bool {
        (self.param, self.key, self.label) == (other.param, other.key, other.label)
    }
}

impl Rule {
    /// Whether a state may hold `v` (files take what the protocol takes unchanged; a wrapped
    /// angle one turn either way; a milliradian of slack on angles, which the protocol
    /// carries in milliradians).
    pub fn holds(&self, v: f64) -> bool {
        let slack = if self.unit == "rad" { 1e-3 } else { 0.0 };
        // A lower bound that only says "more than 0" (an object's size) has no slack: 0 is
        // no size.
        let below = if self.lo > 0.0 && self.lo < slack {
            0.0
        } else {
            slack
        };
        match self.outside {
            Outside::Wrap => v.abs() <= TAU + slack,
            _ => v >= self.lo - below && v <= self.hi + slack,
        }
    }

    /// `v` as a refusal says it: an angle in radians and in degrees (whichever the user gave
    /// it in), a huge number in exponent form.
    pub fn shown(&self, v: f64) -> String {
        let trimmed = |x: String| x.trim_end_matches('0').trim_end_matches('.').to_string();
        match (v.abs() < 1e6, self.unit) {
            (false, _) => format!("{v:e}"),
            (true, "rad") => format!(
                "{} rad ({}°)",
                trimmed(format!("{v:.6}")),
                trimmed(format!("{:.3}", v.to_degrees()))
            ),
            (true, _) => format!("{v}"),
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

    /// `v` as the protocol sets it over `was`; where the rule refuses `v`, `was` (a handler
    /// refuses such a SET before it gets here).
    pub fn take(&self, v: f64, was: f64) -> f64 {
        self.apply(v, was).unwrap_or(was)
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

/// A field a SET sets, kept in the state under `key`.
const fn set(
    (param, field): (ParamType, &'static str),
    (key, label): (&'static str, &'static str),
    (lo, hi): (f64, f64),
    unit: &'static str,
    outside: Outside,
    of: Of,
) -> Rule {
    Rule {
        param: Some((param, field)),
        key: Some(key),
        label,
        lo,
        hi,
        unit,
        outside,
        also: "",
        of,
    }
}

/// A field of a SET that is not kept in the state (a step, an address, a command).
const fn wire(
    param: ParamType,
    field: &'static str,
    (lo, hi): (f64, f64),
    outside: Outside,
) -> Rule {
    Rule {
        param: Some((param, field)),
        key: None,
        label: field,
        lo,
        hi,
        unit: "",
        outside,
        also: "",
        of: Of::Nowhere,
    }
}

/// A field of the state no SET sets.
const fn state(
    (key, label): (&'static str, &'static str),
    (lo, hi): (f64, f64),
    unit: &'static str,
    of: Of,
) -> Rule {
    Rule {
        param: None,
        key: Some(key),
        label,
        lo,
        hi,
        unit,
        outside: Outside::Refuse,
        also: "",
        of,
    }
}

const fn also(r: Rule, also: &'static str) -> Rule {
    Rule { also, ..r }
}

const fn top(n: usize) -> (f64, f64) {
    (0.0, (n - 1) as f64)
}

const U8: (f64, f64) = (0.0, 255.0);
/// DETECTION's scores: 255 ([`KEEP`](super::KEEP)) keeps the current value.
const SCORE: (f64, f64) = (0.0, (super::KEEP - 1) as f64);
/// Ratios: [0, 0.99), the top open (checked as at most 0.98999...).
const RATIO: (f64, f64) = (0.0, 0.989_999_999_999);
/// Altitudes and heights: from below the Dead Sea to above any drone's ceiling.
pub const HEIGHTS: (f64, f64) = (-1000.0, 20_000.0);
const CAM: (f64, f64) = top(MAX_CAMERAS);
/// A thermal span's ends: what the gain takes (`thermal::GainMode::checked`).
const KELVIN: (f64, f64) = (0.0, 2000.0);
const FOV: (f64, f64) = (fov_range(Crop::Rectilinear).0, TAU);
/// A view's pitch: from straight down to straight up (docs/decisions.md, "One rule for a
/// view's pitch").
const PITCH: (f64, f64) = (-FRAC_PI_2, FRAC_PI_2);

use Outside::*;
use ParamType::*;

pub use named::*;

/// Each rule by name, one a line as a table (left as written by rustfmt).
#[rustfmt::skip]
mod named {
    use super::*;

    /// A camera's field as the one check reads it.
    macro_rules! cam {
        ($f:expr) => {
            Of::Camera(|c: &Camera| Some($f(c) as f64))
        };
    }

    pub const OUTPUT_WIDTH: Rule = set((VideoOutput, "width"), ("output.width", "output width"), (MIN_OUTPUT.0 as f64, MAX_OUTPUT.0 as f64), "px", ClampAboveIgnoreBelow, Of::Output(|o| o.width as f64));
    pub const OUTPUT_HEIGHT: Rule = set((VideoOutput, "height"), ("output.height", "output height"), (MIN_OUTPUT.1 as f64, MAX_OUTPUT.1 as f64), "px", ClampAboveIgnoreBelow, Of::Output(|o| o.height as f64));
    pub const OUTPUT_FPS: Rule = set((VideoOutput, "fps"), ("output.fps", "output fps"), (FPS_RANGE.0 as f64, FPS_RANGE.1 as f64), "fps", Clamp, Of::Output(|o| o.fps as f64));
    pub const OUTPUT_LAYOUT: Rule = set((VideoOutput, "layout_mode"), ("output.layout", "output layout"), top(LayoutMode::ALL.len()), "", Ignore, Of::Output(|o| o.layout.code() as f64));
    pub const OUTPUT_OVERLAY: Rule = set((VideoOutput, "detection_overlay_mode"), ("output.overlay", "output overlay"), top(OverlayMode::ALL.len()), "", Ignore, Of::Output(|o| o.overlay.code() as f64));
    pub const DETECTION_MODE: Rule = also(set((Detection, "mode"), ("detection.mode", "detection mode"), (0.0, 0.0), "", Ignore, Of::Detection(|d| d.mode as f64)), "unused by the seed");
    pub const DETECTION_SORTING: Rule = set((Detection, "sorting_mode"), ("detection.sorting_mode", "detection sorting_mode"), (0.0, 2.0), "", Ignore, Of::Detection(|d| d.sorting_mode as f64));
    pub const DETECTION_CROP_CONFIDENCE: Rule = set((Detection, "crop_confidence_threshold"), ("detection.crop_confidence_threshold", "detection crop_confidence_threshold"), RATIO, "", Ignore, Of::Detection(|d| d.crop_confidence_threshold));
    pub const DETECTION_VAR_CONFIDENCE: Rule = set((Detection, "var_confidence_threshold"), ("detection.var_confidence_threshold", "detection var_confidence_threshold"), RATIO, "", Ignore, Of::Detection(|d| d.var_confidence_threshold));
    pub const DETECTION_CROP_BOX_LIMIT: Rule = set((Detection, "crop_box_limit"), ("detection.crop_box_limit", "detection crop_box_limit"), (10.0, 500.0), "", Clamp, Of::Detection(|d| d.crop_box_limit as f64));
    pub const DETECTION_VAR_BOX_LIMIT: Rule = set((Detection, "var_box_limit"), ("detection.var_box_limit", "detection var_box_limit"), (10.0, 500.0), "", Clamp, Of::Detection(|d| d.var_box_limit as f64));
    pub const DETECTION_CROP_BOX_OVERLAP: Rule = set((Detection, "crop_box_overlap"), ("detection.crop_box_overlap", "detection crop_box_overlap"), RATIO, "", Ignore, Of::Detection(|d| d.crop_box_overlap));
    pub const DETECTION_VAR_BOX_OVERLAP: Rule = set((Detection, "var_box_overlap"), ("detection.var_box_overlap", "detection var_box_overlap"), RATIO, "", Ignore, Of::Detection(|d| d.var_box_overlap));
    pub const DETECTION_CREATION_SCORE: Rule = set((Detection, "creation_score_scale"), ("detection.creation_score_scale", "detection creation_score_scale"), SCORE, "", Ignore, Of::Detection(|d| d.creation_score_scale as f64));
    pub const DETECTION_BONUS_DETECTION: Rule = set((Detection, "bonus_detection_scale"), ("detection.bonus_detection_scale", "detection bonus_detection_scale"), SCORE, "", Ignore, Of::Detection(|d| d.bonus_detection_scale as f64));
    pub const DETECTION_BONUS_REDETECTION: Rule = set((Detection, "bonus_redetection_scale"), ("detection.bonus_redetection_scale", "detection bonus_redetection_scale"), SCORE, "", Ignore, Of::Detection(|d| d.bonus_redetection_scale as f64));
    pub const DETECTION_MISSED_DETECTION: Rule = set((Detection, "missed_detection_penalty"), ("detection.missed_detection_penalty", "detection missed_detection_penalty"), SCORE, "", Ignore, Of::Detection(|d| d.missed_detection_penalty as f64));
    pub const DETECTION_MISSED_REDETECTION: Rule = set((Detection, "missed_redetection_penalty"), ("detection.missed_redetection_penalty", "detection missed_redetection_penalty"), SCORE, "", Ignore, Of::Detection(|d| d.missed_redetection_penalty as f64));
    pub const LENS_ID: Rule = also(set((Lens, "lens_id"), ("lens", "lens_id"), U8, "", Refuse, Of::Lens), "a lens_id of lens.cal");
    pub const CAMERA_YAW: Rule = set((CamEuler, "yaw"), ("camera.yaw", "yaw"), (-PI, PI), "rad", Wrap, cam!(Camera::yaw));
    pub const CAMERA_PITCH: Rule = set((CamEuler, "pitch"), ("camera.pitch", "pitch"), PITCH, "rad", Clamp, cam!(Camera::pitch));
    pub const CAMERA_ROLL: Rule = set((CamEuler, "roll"), ("camera.roll", "roll"), (-FRAC_PI_2, FRAC_PI_2), "rad", Clamp, cam!(Camera::roll));
    pub const CAMERA_ZOOM: Rule = set((CamZoom, "zoom"), ("camera.zoom", "zoom"), (-128.0, 127.0), "", NotState, cam!(Camera::zoom));
    pub const CAMERA_LOCK: Rule = set((CamLockFlags, "flags"), ("camera.lock", "lock flags"), (0.0, 7.0), "", LowBits, cam!(|c: &Camera| c.locks().0));
    pub const CAMERA_CONTROL: Rule = also(set((CamControlMode, "mode"), ("camera.control", "control mode"), top(Control::ALL.len()), "", Refuse, cam!(|c: &Camera| c.control().code())), "2 needs a target");
    pub const CAMERA_CROP: Rule = also(set((CamCropMode, "mode"), ("camera.crop", "crop mode"), U8, "", Ignore, cam!(|c: &Camera| c.crop().code())), "above 4 renders black");
    pub const CAMERA_THERMAL: Rule = also(set((CamThermal, "show"), ("camera.thermal", "thermal display"), top(ThermalShow::ALL.len()), "", Refuse, cam!(|c: &Camera| c.thermal().code())), "with a thermal sensor");
    pub const CAMERA_FOV: Rule = also(set((CamFov, "fov"), ("camera.fov", "fov"), FOV, "rad", Clamp, cam!(Camera::fov)), "the crop mode's range");
    pub const CAMERA_TARGET_LAT: Rule = set((CamTarget, "t_latitude"), ("camera.target.lat", "target latitude"), (-90.0, 90.0), "°", Refuse, Of::Camera(|c| c.target().map(|t| t.lat)));
    pub const CAMERA_TARGET_LON: Rule = set((CamTarget, "t_longitude"), ("camera.target.lon", "target longitude"), (-180.0, 180.0), "°", Refuse, Of::Camera(|c| c.target().map(|t| t.lon)));
    pub const CAMERA_TARGET_ALT: Rule = set((CamTarget, "t_altitude"), ("camera.target.alt", "target altitude"), HEIGHTS, "m", Refuse, Of::Camera(|c| c.target().map(|t| t.alt)));
    pub const SENSOR_AE: Rule = set((CamSensor, "ae"), ("sensor.ae", "sensor ae"), U8, "", Flag, Of::Sensor(|s| s.ae as u8 as f64));
    pub const SENSOR_BRIGHTNESS: Rule = set((CamSensor, "target_brightness"), ("sensor.target_brightness", "sensor target brightness"), (1.0, 254.0), "", Clamp, Of::Sensor(|s| s.target_brightness as f64));
    pub const SENSOR_EXPOSURE: Rule = also(set((CamSensor, "exposure_value"), ("sensor.exposure_us", "sensor exposure"), (1.0, crate::state::MAX_EXPOSURE_US as f64), "µs", Clamp, Of::Sensor(|s| s.exposure_us as f64)), "the frame time at the camera's fps");
    pub const SENSOR_GAIN: Rule = set((CamSensor, "gain_value"), ("sensor.gain", "sensor gain"), (1.0, MAX_GAIN as f64), "", Clamp, Of::Sensor(|s| s.gain as f64));
    pub const SENSOR_WIDTH: Rule = set((GeneralSettings, "camera_width"), ("sensor.width", "sensor width"), (1.0, MAX_SENSOR as f64), "px", Refuse, Of::Sensor(|s| s.width as f64));
    pub const SENSOR_HEIGHT: Rule = set((GeneralSettings, "camera_height"), ("sensor.height", "sensor height"), (1.0, MAX_SENSOR as f64), "px", Refuse, Of::Sensor(|s| s.height as f64));
    pub const SENSOR_CROP: Rule = also(set((GeneralSettings, "roi_width"), ("sensor.roi", "sensor crop"), (0.0, MAX_SENSOR as f64), "px", Refuse, Of::SensorCrop), "fits the lens's calibration frame");
    pub const SENSOR_FPS: Rule = set((GeneralSettings, "camera_fps"), ("sensor.fps", "sensor fps"), (1.0, 240.0), "fps", Refuse, Of::Sensor(|s| s.fps as f64));
    pub const MOUNT_YAW: Rule = set((GeneralSettings, "mount_yaw"), ("mount.yaw", "mount yaw"), (-PI, PI), "rad", Wrap, Of::Mount(|m| m.yaw));
    pub const MOUNT_PITCH: Rule = set((GeneralSettings, "mount_pitch"), ("mount.pitch", "mount pitch"), PITCH, "rad", Refuse, Of::Mount(|m| m.pitch));
    pub const MOUNT_ROLL: Rule = set((GeneralSettings, "mount_roll"), ("mount.roll", "mount roll"), (-PI, PI), "rad", Refuse, Of::Mount(|m| m.roll));
    pub const THERMAL_PALETTE: Rule = set((Thermal, "palette"), ("thermal.palette", "thermal palette"), top(Palette::ALL.len()), "", Refuse, Of::Thermal(|t| t.palette.code() as f64));
    pub const THERMAL_GAIN: Rule = set((Thermal, "gain"), ("thermal.gain", "thermal gain"), (0.0, 1.0), "", Refuse, Of::Thermal(|t| t.gain as u8 as f64));
    pub const THERMAL_LOW: Rule = also(set((Thermal, "span_low"), ("thermal.low", "thermal span low"), KELVIN, "K", Refuse, Of::Thermal(|t| t.low)), "below the span's high");
    pub const THERMAL_HIGH: Rule = also(set((Thermal, "span_high"), ("thermal.high", "thermal span high"), KELVIN, "K", Refuse, Of::Thermal(|t| t.high)), "above the span's low");
    pub const THERMAL_BLEND: Rule = set((Thermal, "blend"), ("thermal.blend", "thermal blend"), RATIO, "", Clamp, Of::Thermal(|t| t.blend));
    pub const THERMAL_ZOOM: Rule = set((Thermal, "zoom"), ("thermal.zoom", "thermal zoom"), (1.0, 8.0), "", Clamp, Of::Thermal(|t| t.zoom as f64));
    pub const DETECTION_RUN: Rule = set((GeneralSettings, "run_ai"), ("detection.run_ai", "detection run_ai"), U8, "", Flag, Of::Detection(|d| d.run_ai as u8 as f64));
    pub const VEHICLE_YAW: Rule = state(("vehicle.attitude.yaw", "vehicle attitude yaw"), (-TAU, TAU), "rad", Of::Vehicle(|v| v.attitude.yaw));
    pub const VEHICLE_PITCH: Rule = state(("vehicle.attitude.pitch", "vehicle attitude pitch"), PITCH, "rad", Of::Vehicle(|v| v.attitude.pitch));
    pub const VEHICLE_ROLL: Rule = state(("vehicle.attitude.roll", "vehicle attitude roll"), (-PI, PI), "rad", Of::Vehicle(|v| v.attitude.roll));
    pub const VEHICLE_LAT: Rule = state(("vehicle.position.lat", "vehicle latitude"), (-90.0, 90.0), "°", Of::Vehicle(|v| v.position.lat));
    pub const VEHICLE_LON: Rule = state(("vehicle.position.lon", "vehicle longitude"), (-180.0, 180.0), "°", Of::Vehicle(|v| v.position.lon));
    pub const VEHICLE_ALT: Rule = state(("vehicle.position.alt", "vehicle altitude"), HEIGHTS, "m", Of::Vehicle(|v| v.position.alt));
    pub const VEHICLE_HEIGHT: Rule = state(("vehicle.position.relative_alt", "vehicle height above home"), HEIGHTS, "m", Of::Vehicle(|v| v.position.relative_alt));
    pub const TIME: Rule = state(("time", "scene time"), (-1e9, 1e9), "s", Of::Time);
    pub const TRACKED_YAW: Rule = state(("tracked.yaw", "yaw"), (-TAU, TAU), "rad", Of::Tracked(|t| t.yaw));
    pub const TRACKED_PITCH: Rule = state(("tracked.pitch", "pitch"), (-PI, PI), "rad", Of::Tracked(|t| t.pitch));
    pub const TRACKED_SIZE: Rule = also(state(("tracked.size", "size"), (1e-6, PI), "rad", Of::Tracked(|t| t.size)), "more than 0");
    pub const TRACKED_ID: Rule = state(("tracked.id", "id"), (0.0, u32::MAX as f64), "", Of::Tracked(|t| t.id as f64));
    pub const TRACKED_SCORE: Rule = state(("tracked.score", "score"), U8, "", Of::Tracked(|t| t.score as f64));
    pub const TRACKED_VELOCITY: Rule = state(("tracked.velocity", "velocity"), (-100.0, 100.0), "rad/s", Of::TrackedVelocity);
    pub const TRACKED_SEEN: Rule = state(("tracked.seen_us", "sighting time"), (0.0, u64::MAX as f64), "µs", Of::Tracked(|t| t.seen_us as f64));
    pub const CAMERA_ID: Rule = state(("camera.id", "camera id"), CAM, "", Of::Nowhere);
}

/// Every field's rule: a parameter type's fields in wire order (with those of its fields the
/// state does not keep), the state's own after.
#[rustfmt::skip]
pub const RULES: &[Rule] = &[
    OUTPUT_WIDTH, OUTPUT_HEIGHT, OUTPUT_FPS, OUTPUT_LAYOUT, OUTPUT_OVERLAY,
    wire(VideoOutput, "views", U8, NotState),
    wire(VideoOutput, "detection_overlay_box", U8, NotState),
    wire(VideoOutput, "single_detection_size", (0.0, 65535.0), NotState),
    wire(Capture, "flags", (0.0, 3.0), NotState),
    wire(Capture, "images_captured", (0.0, 65535.0), NotState),
    wire(Capture, "videos_captured", (0.0, 65535.0), NotState),
    DETECTION_MODE, DETECTION_SORTING, DETECTION_CROP_CONFIDENCE, DETECTION_VAR_CONFIDENCE,
    DETECTION_CROP_BOX_LIMIT, DETECTION_VAR_BOX_LIMIT, DETECTION_CROP_BOX_OVERLAP,
    DETECTION_VAR_BOX_OVERLAP, DETECTION_CREATION_SCORE, DETECTION_BONUS_DETECTION,
    DETECTION_BONUS_REDETECTION, DETECTION_MISSED_DETECTION, DETECTION_MISSED_REDETECTION,
    LENS_ID,
    wire(CamEuler, "cam_id", CAM, Refuse), wire(CamEuler, "is_delta", U8, NotState),
    CAMERA_YAW, CAMERA_PITCH, CAMERA_ROLL,
    wire(CamZoom, "cam_id", CAM, Refuse), CAMERA_ZOOM,
    wire(CamLockFlags, "cam_id", CAM, Refuse), CAMERA_LOCK,
    wire(CamControlMode, "cam_id", CAM, Refuse), CAMERA_CONTROL,
    wire(CamCropMode, "cam_id", CAM, Refuse), CAMERA_CROP,
    wire(CamOffset, "cam_id", CAM, Refuse),
    wire(CamOffset, "x", (-0.5, 0.5), NotState), wire(CamOffset, "y", (-0.5, 0.5), NotState),
    wire(CamOffset, "frame_rel", U8, NotState),
    wire(CamOffset, "yaw", (-PI, PI), NotState), wire(CamOffset, "pitch", (-PI, PI), NotState),
    wire(CamFov, "cam_id", CAM, Refuse), CAMERA_FOV,
    wire(CamTarget, "cam_id", CAM, Refuse),
    wire(CamTarget, "x", (-0.5, 0.5), NotState), wire(CamTarget, "y", (-0.5, 0.5), NotState),
    CAMERA_TARGET_LAT, CAMERA_TARGET_LON, CAMERA_TARGET_ALT,
    SENSOR_AE, SENSOR_BRIGHTNESS, SENSOR_EXPOSURE, SENSOR_GAIN,
    SENSOR_WIDTH, SENSOR_HEIGHT, SENSOR_CROP,
    also(wire(GeneralSettings, "roi_height", (0.0, MAX_SENSOR as f64), NotState), "with roi_width"),
    SENSOR_FPS, MOUNT_YAW, MOUNT_PITCH, MOUNT_ROLL, DETECTION_RUN,
    THERMAL_PALETTE, THERMAL_GAIN, THERMAL_LOW, THERMAL_HIGH, THERMAL_BLEND, THERMAL_ZOOM,
    wire(CamThermal, "cam_id", CAM, Refuse), CAMERA_THERMAL,
    VEHICLE_YAW, VEHICLE_PITCH, VEHICLE_ROLL, VEHICLE_LAT, VEHICLE_LON, VEHICLE_ALT, VEHICLE_HEIGHT,
    TIME,
    TRACKED_YAW, TRACKED_PITCH, TRACKED_SIZE, TRACKED_ID, TRACKED_SCORE, TRACKED_VELOCITY,
    TRACKED_SEEN,
    CAMERA_ID,
];
