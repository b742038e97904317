//! The payload SDK's camera parameters (its VIO header's names, PARAM_EXT with uint32 values)
//! and what each is for a view: the gimbal mode onto the view's locks ("mapping" looks
//! straight down), the zoom levels onto its field of view, OSD_MODE onto the overlay,
//! TRACK_MODE onto the detection, C_V_AE and C_V_SP onto the fisheye's exposure (CAM_SENSOR's
//! settings); with a thermal sensor, C_SOURCE onto how the view shows it, C_T_PALETTE onto
//! its palette and C_T_ZOOM onto its zoom. Every change is a view operation or a settings change through the one
//! gate. What means nothing for a virtual view (focus, defog, iris, flip, white balance, the
//! rangefinder) or needs a sensor the head does not have (C_SOURCE's IR, C_T_PALETTE and
//! C_T_ZOOM without a thermal sensor, the other C_T_* parameters) is refused with the
//! reason, never taken silently.

use crate::modes::ThermalShow;
use crate::state::Gate;
use crate::state::view::{Op, Pointing, Zoom};
use crate::thermal::Palette;
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

/// The parameters a list gives, in index order; with a thermal sensor, C_T_PALETTE and
/// C_T_ZOOM after them ([`listed`]).
const LISTED: [&str; 12] = [
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
    "C_T_PALETTE",
    "C_T_ZOOM",
];

/// The parameters a list gives, with a thermal sensor or without.
pub fn listed(thermal: bool) -> &'static [&'static str] {
    &LISTED[..LISTED.len() - 2 * !thermal as usize]
}

/// C_T_PALETTE's values (the FLIR-core numbering of the SDK's list) as DigiView's palettes;
/// RainbowHC, Globow, Gradedfire and Hottest (3, 7, 8, 9) it does not have.
const PALETTES: [(u32, Palette); 6] = [
    (0, Palette::WhiteHot),
    (1, Palette::BlackHot),
    (2, Palette::Rainbow),
    (4, Palette::Ironbow),
    (5, Palette::Lava),
    (6, Palette::Arctic),
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

/// What setting `name` to `v` does, for a view whose widest fov is `widest`, on a head with
/// a thermal sensor or without.
pub fn set(
    modes: &mut Modes,
    name: &str,
    v: u32,
    (widest, thermal): (f64, bool),
) -> Result<Set, Refusal> {
    let value = |ok, what: &str| taken(ok, (name, v), what);
    match name {
        "GB_MODE" => gimbal_mode(modes, v).ok_or_else(|| {
            refusal(
                (name, v),
                "give 0 off, 1 lock, 2 follow, 3 mapping or 4 reset",
            )
        }),
        "C_SOURCE" | "C_T_ZOOM" | "C_T_PALETTE" if thermal => thermal_set(name, v),
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
        "C_V_AE" | "C_V_SP" => exposure_set(name, v),
        _ => Err(Refusal::Unknown(unknown(name, thermal))),
    }
}

/// The refusal of `name` = `v`, saying `what` is taken.
fn refusal((name, v): (&str, u32), what: &str) -> Refusal {
    Refusal::Value(format!("{name} = {v}: {what}"))
}

/// Nothing when `ok`; else [`refusal`].
fn taken(ok: bool, set: (&str, u32), what: &str) -> Result<(), Refusal> {
    if ok { Ok(()) } else { Err(refusal(set, what)) }
}

/// What C_V_AE or C_V_SP set to `v` does: the fisheye's exposure, automatic or manual.
fn exposure_set(name: &str, v: u32) -> Result<Set, Refusal> {
    let value = |ok, what: &str| taken(ok, (name, v), what);
    match name {
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
        // C_V_SP.
        _ => {
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
    }
}

/// What C_SOURCE, C_T_ZOOM or C_T_PALETTE set to `v` does with a thermal sensor: how the view
/// shows it, its zoom, its palette.
fn thermal_set(name: &str, v: u32) -> Result<Set, Refusal> {
    let refused = |what: &str| Err(refusal((name, v), what));
    let shows = [ThermalShow::Pip, ThermalShow::Off, ThermalShow::Thermal];
    match name {
        "C_SOURCE" => match shows.get(v as usize) {
            Some(show) => Ok(Set::View(Op::Thermal(show.code()))),
            None => refused(
                "give 0 EO with the IR inset, 1 EO or 2 IR (no IR with an EO inset, no sync)",
            ),
        },
        "C_T_ZOOM" if v <= 7 => Ok(Set::Settings(Box::new(move |s| {
            s.thermal.zoom = v as u8 + 1;
            Ok(())
        }))),
        "C_T_ZOOM" => refused("give 0 (1x) to 7 (8x)"),
        _ => match PALETTES.iter().find(|(n, _)| *n == v) {
            Some(&(_, palette)) => Ok(Set::Settings(Box::new(move |s| {
                s.thermal.palette = palette;
                Ok(())
            }))),
            None => {
                refused("give 0 white hot, 1 black hot, 2 rainbow, 4 ironbow, 5 lava or 6 arctic")
            }
        },
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
fn unknown(name: &str, thermal: bool) -> String {
    let why = if (name.starts_with("C_T_") || name == "C_V_IR") && !thermal {
        "DigiView has no thermal sensor: start serve with --thermal SOURCE"
    } else if name.starts_with("C_T_") || name == "C_V_IR" {
        "of the thermal parameters DigiView takes C_T_PALETTE and C_T_ZOOM; the thermal \
         picture's other settings are on the DigiView protocol, MAVLink's camera settings \
         and its page"
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
        "C_SOURCE" => match s.cameras[i].thermal() {
            ThermalShow::Pip => 0,
            ThermalShow::Thermal => 2,
            ThermalShow::Off | ThermalShow::Blend => 1,
        },
        "C_T_ZOOM" => s.thermal.zoom.saturating_sub(1) as u32,
        "C_T_PALETTE" => PALETTES
            .iter()
            .find(|(_, p)| *p == s.thermal.palette)
            .map_or(0, |(n, _)| *n),
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
    use crate::state::view::Field;

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
            let Ok(Set::Settings(change)) = set(&mut Modes::default(), "C_V_SP", v, (1.0, false))
            else {
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
        assert!(refused(set(&mut m, "C_V_DEFOG", 2, (1.0, false))).contains("defog"));
        assert!(refused(set(&mut m, "C_T_PALETTE", 1, (1.0, false))).contains("thermal"));
        assert!(refused(set(&mut m, "C_SOURCE", 2, (1.0, false))).contains("no IR"));
        assert!(refused(set(&mut m, "GB_MODE", 9, (1.0, false))).contains("3 mapping"));
        assert_eq!(
            m.gimbal,
            GimbalMode::Follow,
            "a refused value changes nothing"
        );
    }

    /// With a thermal sensor, C_SOURCE picks how the view shows it, C_T_PALETTE its palette
    /// and C_T_ZOOM its zoom; each reads back as set, and what DigiView does not draw is
    /// refused.
    #[test]
    fn with_a_thermal_sensor_the_source_and_palette_are_taken_and_read_back() {
        let mut m = Modes::default();
        let mut s = crate::state::Settings::default();
        for v in 0..=2 {
            let Ok(Set::View(Op::Thermal(show))) = set(&mut m, "C_SOURCE", v, (1.0, true)) else {
                panic!("C_SOURCE {v} refused");
            };
            let shown = s.cameras[0].clone().with(&[(Field::Thermal, show as f64)]);
            s.cameras[0] = shown.unwrap();
            assert_eq!(value(&m, "C_SOURCE", (1.0, 1.0), (&s, 0)), v);
        }
        assert!(matches!(
            set(&mut m, "C_SOURCE", 3, (1.0, true)),
            Err(Refusal::Value(_))
        ));
        for (v, palette) in PALETTES {
            let Ok(Set::Settings(change)) = set(&mut m, "C_T_PALETTE", v, (1.0, true)) else {
                panic!("C_T_PALETTE {v} refused");
            };
            change(&mut s).unwrap();
            assert_eq!(s.thermal.palette, palette);
            assert_eq!(value(&m, "C_T_PALETTE", (1.0, 1.0), (&s, 0)), v);
        }
        let why = match set(&mut m, "C_T_PALETTE", 3, (1.0, true)) {
            Err(Refusal::Value(w)) => w,
            _ => panic!("RainbowHC taken"),
        };
        assert!(why.contains("4 ironbow"), "{why}");
        for v in 0..=7 {
            let Ok(Set::Settings(change)) = set(&mut m, "C_T_ZOOM", v, (1.0, true)) else {
                panic!("C_T_ZOOM {v} refused");
            };
            change(&mut s).unwrap();
            assert_eq!(s.thermal.zoom as u32, v + 1);
            assert_eq!(value(&m, "C_T_ZOOM", (1.0, 1.0), (&s, 0)), v);
        }
        assert!(set(&mut m, "C_T_ZOOM", 8, (1.0, true)).is_err());
        assert!(listed(true).ends_with(&["C_T_PALETTE", "C_T_ZOOM"]));
        assert!(!listed(false).contains(&"C_T_PALETTE"));
    }
}
