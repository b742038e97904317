//! The payload SDK's camera parameters (its VIO header's names, PARAM_EXT with uint32 values)
//! and what each is for a view: the gimbal mode onto the view's locks ("mapping" looks
//! straight down), the zoom levels onto its field of view, OSD_MODE onto the overlay,
//! TRACK_MODE onto the detection, C_V_AE and C_V_SP onto the fisheye's exposure (CAM_SENSOR's
//! settings). Every change is a view operation or a settings change through the one gate.
//! What means nothing for a virtual view (focus, defog, iris, flip, white balance, the
//! rangefinder) or needs a sensor DigiView does not have (C_SOURCE's IR, the C_T_* thermal
//! parameters) is refused with the reason, never taken silently.

use crate::state::Gate;
use crate::state::view::{Op, Pointing, Zoom};
use std::f64::consts::FRAC_PI_2;

/// GB_MODE's values as the view keeps them (4, reset, is an act: the view comes back ahead
/// and level and follows).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GimbalMode {
    Off = 0,
    Lock = 1,
    Follow = 2,
    Mapping = 3,
}

/// The combined zoom levels (C_V_ZM_CB_LV's index → factor) and the super-resolution ones
/// (C_V_ZM_SR_LV).
const COMBINED: [f64; 22] = [
    1., 2., 4., 6., 8., 10., 12., 14., 16., 18., 20., 40., 60., 80., 100., 120., 140., 160., 180.,
    200., 220., 240.,
];
const SUPER_RESOLUTION: [f64; 12] = [1., 2., 4., 6., 8., 10., 12., 14., 16., 18., 20., 30.];

/// C_V_SP's index (6..=33) → the shutter time's denominator (6 is 1 s; 7 is 2/3 s).
const SHUTTER: [f64; 28] = [
    1., 1.5, 2., 3., 4., 6., 8., 10., 15., 20., 30., 50., 60., 90., 100., 125., 180., 250., 350.,
    500., 725., 1000., 1500., 2000., 3000., 4000., 6000., 10000.,
];
const FIRST_SHUTTER: u32 = 6;

/// The parameters a list gives, in index order.
pub const LISTED: [&str; 10] = [
    "GB_MODE",
    "C_SOURCE",
    "C_V_REC",
    "OSD_MODE",
    "TRACK_MODE",
    "C_V_ZM_MODE",
    "C_V_ZM_SR_LV",
    "C_V_ZM_CB_LV",
    "C_V_AE",
    "C_V_SP",
];

/// What the SDK set that is the profile's own (the rest is read from the state).
#[derive(Clone, Copy, Debug)]
pub struct Modes {
    pub gimbal: GimbalMode,
    /// TRACK_MODE: 0 object tracking, 1 object detection (the detection packets stream).
    pub track: u32,
    pub zoom_mode: u32,
    pub record_source: u32,
}

impl Default for Modes {
    fn default() -> Self {
        Modes {
            gimbal: GimbalMode::Follow,
            track: 0,
            zoom_mode: 0,
            record_source: 1,
        }
    }
}

/// Why a parameter is refused: the PARAM_EXT_ACK it gets, and the reason logged.
#[derive(Debug, PartialEq, Eq)]
pub enum Refusal {
    /// A parameter DigiView does not have (PARAM_ACK_FAILED).
    Unknown(String),
    /// A value it does not take (PARAM_ACK_VALUE_UNSUPPORTED).
    Value(String),
}

/// A change of the settings other than the view's.
pub type Change = Box<dyn FnOnce(&mut crate::state::Settings) -> Result<(), crate::state::Invalid>>;

/// What a parameter set asks of the view: done here on `modes`, or a view operation or a
/// settings change for the caller.
pub enum Set {
    Done,
    View(Op),
    /// The gimbal device's retract (GB_MODE off) or neutral (reset).
    Rest {
        neutral: bool,
    },
    Settings(Change),
}

/// What setting `name` to `v` does, for a view whose widest fov is `widest`.
pub fn set(modes: &mut Modes, name: &str, v: u32, widest: f64) -> Result<Set, Refusal> {
    let value = |ok: bool, what: &str| match ok {
        true => Ok(()),
        false => Err(Refusal::Value(format!("{name} = {v}: {what}"))),
    };
    match name {
        "GB_MODE" => gimbal_mode(modes, v).ok_or_else(|| {
            Refusal::Value(format!(
                "GB_MODE = {v}: give 0 off, 1 lock, 2 follow, 3 mapping or 4 reset"
            ))
        }),
        "C_SOURCE" => {
            value(
                v == 1,
                "DigiView has only its fisheye (EO, 1): no IR sensor",
            )?;
            Ok(Set::Done)
        }
        "C_V_REC" => {
            value(
                v <= 1,
                "DigiView records its views (0 both or 1 EO): no IR or OSD source",
            )?;
            modes.record_source = v;
            Ok(Set::Done)
        }
        "OSD_MODE" => {
            value(v <= 2, "give 0 off, 1 debug or 2 status")?;
            let overlay = [0u8, 2, 1][v as usize];
            Ok(Set::Settings(Box::new(move |s| {
                s.output.overlay = crate::modes::OverlayMode::try_from(overlay)
                    .map_err(|e| crate::state::Invalid(e.to_string()))?;
                Ok(())
            })))
        }
        "TRACK_MODE" => {
            value(v <= 1, "give 0 object tracking or 1 object detection")?;
            modes.track = v;
            Ok(match v {
                1 => Set::Settings(Box::new(|s| {
                    s.detection.run_ai = true;
                    Ok(())
                })),
                _ => Set::Done,
            })
        }
        "C_V_ZM_MODE" => {
            value(v == 0 || v == 2, "give 0 combined or 2 super resolution")?;
            modes.zoom_mode = v;
            Ok(Set::Done)
        }
        "C_V_ZM_SR_LV" | "C_V_ZM_CB_LV" => {
            let levels = zoom_levels(name);
            let factor = levels.get(v as usize).copied();
            value(
                factor.is_some(),
                &format!("give a level 0 to {}", levels.len() - 1),
            )?;
            Ok(Set::View(Op::Zoom(Zoom::Fov(
                widest / factor.unwrap_or(1.0),
            ))))
        }
        // Shutter priority (10) is manual here: the fisheye's exposure has no auto gain beside
        // a given shutter.
        "C_V_AE" => {
            let modes = "DigiView's exposure is 0 auto, or 3 manual (10, shutter priority, too)";
            value(v == 0 || v == 3 || v == 10, modes)?;
            Ok(Set::Settings(Box::new(move |s| {
                s.sensor.ae = v == 0;
                Ok(())
            })))
        }
        "C_V_SP" => {
            let i = v.checked_sub(FIRST_SHUTTER).map(|i| i as usize);
            let den = i.and_then(|i| SHUTTER.get(i)).copied();
            value(
                den.is_some(),
                "give a shutter index 6 (1 s) to 33 (1/10000 s)",
            )?;
            let us = (1e6 / den.unwrap_or(1.0)).round() as u32;
            Ok(Set::Settings(Box::new(move |s| {
                s.sensor.ae = false;
                s.sensor.exposure_us = us.min(s.sensor.longest_exposure_us());
                Ok(())
            })))
        }
        _ => Err(Refusal::Unknown(unknown(name))),
    }
}

/// GB_MODE `v`, or None when it names no mode.
fn gimbal_mode(modes: &mut Modes, v: u32) -> Option<Set> {
    let (mode, set) = match v {
        0 => (GimbalMode::Off, Set::Rest { neutral: false }),
        1 => (GimbalMode::Lock, Set::View(Op::Locks(7.0))),
        2 => (GimbalMode::Follow, Set::View(Op::Locks(3.0))),
        3 => (GimbalMode::Mapping, Set::View(Op::Point(nadir()))),
        // A reset brings the view back ahead and level, then it follows.
        4 => (GimbalMode::Follow, Set::Rest { neutral: true }),
        _ => return None,
    };
    modes.gimbal = mode;
    Some(set)
}

/// Straight down, its top towards the nose, roll and pitch held to the horizon.
fn nadir() -> Pointing {
    Pointing {
        yaw: Some(0.0),
        pitch: Some(-FRAC_PI_2),
        roll: Some(0.0),
        earth: false,
        locks: crate::geometry::view::LockFlags(3),
    }
}

fn zoom_levels(name: &str) -> &'static [f64] {
    match name {
        "C_V_ZM_SR_LV" => &SUPER_RESOLUTION,
        _ => &COMBINED,
    }
}

/// Why a name the profile does not take is refused, in the operator's words.
fn unknown(name: &str) -> String {
    let why = if name.starts_with("C_T_") || name == "C_V_IR" {
        "DigiView has no thermal sensor"
    } else if name == "RC_MODE" {
        "DigiView takes no RC input: its views are steered over MAVLink, the DigiView protocol and its page"
    } else if name.starts_with("C_V_") || name.starts_with("LRF") {
        "a virtual view has no focus, iris, defog, flip, white balance, gain or rangefinder to set"
    } else {
        "no such parameter"
    };
    format!("{name}: {why}")
}

/// Parameter `name`'s value now for view `i`: `modes` for the profile's own, the view's zoom
/// level for a view of fov `fov` (widest `widest`), the overlay and exposure from the
/// settings. Lock and follow are read from the view's yaw lock, whichever path set it; off
/// and mapping are what the SDK chose last.
pub fn value(
    modes: &Modes,
    name: &str,
    (fov, widest): (f64, f64),
    (s, i): (&crate::state::Settings, usize),
) -> u32 {
    match name {
        "GB_MODE" => match modes.gimbal {
            GimbalMode::Off | GimbalMode::Mapping => modes.gimbal as u32,
            _ if s.cameras[i].locks().yaw() => GimbalMode::Lock as u32,
            _ => GimbalMode::Follow as u32,
        },
        "C_SOURCE" => 1,
        "C_V_REC" => modes.record_source,
        "OSD_MODE" => match s.output.overlay.code() {
            0 => 0,
            1 => 2,
            _ => 1,
        },
        "TRACK_MODE" => modes.track,
        "C_V_ZM_MODE" => modes.zoom_mode,
        "C_V_ZM_SR_LV" | "C_V_ZM_CB_LV" => {
            let factor = widest / fov;
            let levels = zoom_levels(name);
            levels
                .iter()
                .rposition(|&l| l <= factor * 1.001)
                .unwrap_or(0) as u32
        }
        "C_V_AE" => {
            if s.sensor.ae {
                0
            } else {
                3
            }
        }
        _ => {
            let den = 1e6 / s.sensor.exposure_us.max(1) as f64;
            let nearest = SHUTTER
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - den).abs().total_cmp(&(b.1 - den).abs()))
                .map_or(0, |(i, _)| i);
            FIRST_SHUTTER + nearest as u32
        }
    }
}

/// Applies what a parameter asks of view `i` through `gate` (a rest through the cameras'
/// gimbal device, which the caller does).
pub fn apply(gate: &Gate, i: usize, set: Set) -> Result<(), String> {
    match set {
        Set::View(op) => gate.steer(i, op).map_err(|e| e.to_string()),
        Set::Settings(change) => gate.change(change).map_err(|e: crate::state::Invalid| e.0),
        Set::Done | Set::Rest { .. } => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_zoom_level_reads_back_as_the_level_set() {
        let widest = 2.0;
        let (modes, s) = (Modes::default(), crate::state::Settings::default());
        for name in ["C_V_ZM_SR_LV", "C_V_ZM_CB_LV"] {
            for (i, f) in zoom_levels(name).iter().enumerate() {
                assert_eq!(
                    value(&modes, name, (widest / f, widest), (&s, 0)),
                    i as u32,
                    "{name}"
                );
            }
        }
    }

    #[test]
    fn a_shutter_index_reads_back_as_itself_within_the_frame_time() {
        let mut s = crate::state::Settings::default();
        s.sensor.fps = 1;
        let longest = s.sensor.longest_exposure_us() as f64;
        for v in FIRST_SHUTTER..FIRST_SHUTTER + SHUTTER.len() as u32 {
            if 1e6 / SHUTTER[(v - FIRST_SHUTTER) as usize] > longest {
                continue;
            }
            let Ok(Set::Settings(change)) = set(&mut Modes::default(), "C_V_SP", v, 1.0) else {
                panic!("C_V_SP {v} refused");
            };
            change(&mut s).unwrap();
            assert_eq!(value(&Modes::default(), "C_V_SP", (1.0, 1.0), (&s, 0)), v);
        }
    }

    #[test]
    fn what_a_view_cannot_do_is_refused_with_the_reason() {
        let mut m = Modes::default();
        let refused = |r: Result<Set, Refusal>| match r {
            Err(Refusal::Unknown(w)) | Err(Refusal::Value(w)) => w,
            Ok(_) => "taken".into(),
        };
        assert!(refused(set(&mut m, "C_V_DEFOG", 2, 1.0)).contains("defog"));
        assert!(refused(set(&mut m, "C_T_PALETTE", 1, 1.0)).contains("thermal"));
        assert!(refused(set(&mut m, "C_SOURCE", 2, 1.0)).contains("no IR"));
        assert!(refused(set(&mut m, "GB_MODE", 9, 1.0)).contains("3 mapping"));
        assert_eq!(
            m.gimbal,
            GimbalMode::Follow,
            "a refused value changes nothing"
        );
    }
}
