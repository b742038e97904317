//! What an operator sets: the output, the lens, the four views, the camera's mount and
//! sensor, the detection's settings and how a thermal sensor's picture is coloured. Validated
//! whole by the one check (`validate`), whichever way it came in, and changed live only
//! through [`LiveSettings`](super::LiveSettings) (a view's aim, zoom, target, locks, crop
//! and thermal display only through the view operations, `view`).

use super::MAX_CAMERAS;
use super::detection::DetectionSettings;
use super::view::Camera;
use crate::geometry::Euler;
use crate::lens::Roi;
use crate::modes::{LayoutMode, NotAMode, OverlayMode};
use crate::thermal::palette::NameOrCode;
use crate::thermal::{GainMode, Palette};
use crate::units::de_angle;
use serde::{Deserialize, Serialize};

/// The output sizes and frame rates VIDEO_OUTPUT allows (the seed's ranges).
pub const MIN_OUTPUT: (u32, u32) = (640, 480);
pub const MAX_OUTPUT: (u32, u32) = (1920, 1080);
pub const FPS_RANGE: (u32, u32) = (5, 30);
/// The largest fisheye frame, each way (GENERAL_SETTINGS's camera size).
pub const MAX_SENSOR: u32 = 8192;
/// CAM_SENSOR's longest exposure (µs) and highest gain (thousandths), the seed's.
pub const MAX_EXPOSURE_US: u32 = 40_000;
pub const MAX_GAIN: u32 = 50_000;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Output {
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    pub layout: LayoutMode,
    pub overlay: OverlayMode,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            width: 1920,
            height: 1080,
            fps: 30,
            layout: LayoutMode::Four,
            overlay: OverlayMode::Right,
        }
    }
}

impl Output {
    /// The rectangles of the output frame.
    pub fn layout(&self) -> Result<crate::layout::Layout, crate::layout::LayoutError> {
        crate::layout::layout(self.width, self.height, self.layout, self.overlay)
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

/// The fisheye camera: its frame size and optional sensor crop (GENERAL_SETTINGS), and its
/// exposure (CAM_SENSOR).
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

/// How a thermal sensor's picture is coloured, in every view that shows it (THERMAL;
/// `[thermal]` in a state file); each view picks how it shows it (`Camera::thermal`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ThermalLook {
    pub palette: Palette,
    pub gain: ThermalGain,
    /// The span's coldest and hottest temperature, kelvin (`gain = "span"`).
    pub low: f64,
    pub high: f64,
    /// The thermal colour's share of a blended view's pixel.
    pub blend: f64,
    /// The thermal picture's zoom (1 to 8 times) where a view shows it whole or inset: its
    /// middle 1/zoom fills it. A blend stays registered, unzoomed.
    pub zoom: u8,
}

/// How counts become levels (`thermal::gain`); a file gives `"auto"` or `"span"`, or the
/// number THERMAL carries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", try_from = "NameOrCode")]
pub enum ThermalGain {
    /// Plateau equalisation of each frame.
    #[default]
    Auto = 0,
    /// Levels spread evenly over the span: one colour is one temperature.
    Span = 1,
}

/// Its number, THERMAL's gain.
impl TryFrom<u8> for ThermalGain {
    type Error = NotAMode;

    fn try_from(v: u8) -> Result<ThermalGain, NotAMode> {
        match v {
            0 => Ok(ThermalGain::Auto),
            1 => Ok(ThermalGain::Span),
            _ => Err(NotAMode {
                what: "thermal gain",
                value: v,
                top: 1,
            }),
        }
    }
}

impl TryFrom<NameOrCode> for ThermalGain {
    type Error = String;

    fn try_from(v: NameOrCode) -> Result<ThermalGain, String> {
        match v {
            NameOrCode::Code(n) => ThermalGain::try_from(n).map_err(|e| e.to_string()),
            NameOrCode::Name(n) if n.eq_ignore_ascii_case("auto") => Ok(ThermalGain::Auto),
            NameOrCode::Name(n) if n.eq_ignore_ascii_case("span") => Ok(ThermalGain::Span),
            NameOrCode::Name(n) => Err(format!("thermal gain {n:?}: give \"auto\" or \"span\"")),
        }
    }
}

impl Default for ThermalLook {
    /// White-hot under the automatic gain, half blended, unzoomed; a span of 0 to 100 °C.
    fn default() -> Self {
        ThermalLook {
            palette: Palette::WhiteHot,
            gain: ThermalGain::Auto,
            low: 273.15,
            high: 373.15,
            blend: 0.5,
            zoom: 1,
        }
    }
}

impl ThermalLook {
    /// The gain as the colouring takes it.
    pub fn gain_mode(&self) -> GainMode {
        match self.gain {
            ThermalGain::Auto => GainMode::default(),
            ThermalGain::Span => GainMode::Span {
                low_k: self.low,
                high_k: self.high,
            },
        }
    }
}

/// Everything an operator sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub output: Output,
    /// lens_id in lens.cal (0 CIL216, 1 CIL018, 2 LN007).
    pub lens: u8,
    pub cameras: Vec<Camera>,
    pub mount: Angles,
    pub sensor: Sensor,
    pub detection: DetectionSettings,
    pub thermal: ThermalLook,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            output: Output::default(),
            lens: 0,
            cameras: (0..MAX_CAMERAS).map(Camera::numbered).collect(),
            mount: Angles {
                yaw: 0.0,
                pitch: -std::f64::consts::FRAC_PI_2,
                roll: 0.0,
            },
            sensor: Sensor::default(),
            detection: DetectionSettings::default(),
            thermal: ThermalLook::default(),
        }
    }
}

impl Settings {
    /// The sensor's frame size.
    pub fn sensor_size(&self) -> (u32, u32) {
        (self.sensor.width, self.sensor.height)
    }
}
