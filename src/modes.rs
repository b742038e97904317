//! The modes an operator picks, as the seed numbers them on the wire: a view's control mode
//! (CAM_CONTROL_MODE) and crop mode (CAM_CROP_MODE), the output's layout and detection
//! overlay (VIDEO_OUTPUT), and how a view shows the thermal camera (the camera setting
//! THERMAL); and which GPU backend renders. Shared data at the bottom: the renderer, the
//! layout and every entry path name them by these types; only the wire codecs see their
//! numbers.

use serde::{Deserialize, Serialize};

/// A number that names no mode of its kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{what} {value} is outside 0..={top}")]
pub struct NotAMode {
    pub what: &'static str,
    pub value: u8,
    pub top: u8,
}

/// An enum of modes numbered 0..=N on the wire, read from and written to state files as its
/// number.
macro_rules! numbered {
    ($(#[$meta:meta])* $name:ident, $what:literal { $($(#[$vmeta:meta])* $variant:ident = $n:literal,)+ }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
        #[serde(into = "u8", try_from = "u8")]
        pub enum $name {
            $($(#[$vmeta])* $variant = $n,)+
        }

        impl $name {
            /// Every mode, in wire order.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// Its number on the wire.
            pub const fn code(self) -> u8 {
                self as u8
            }
        }

        impl From<$name> for u8 {
            fn from(m: $name) -> u8 {
                m as u8
            }
        }

        /// Its number, as the seed writes it.
        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}", self.code())
            }
        }

        impl TryFrom<u8> for $name {
            type Error = NotAMode;
            fn try_from(v: u8) -> Result<Self, NotAMode> {
                match v {
                    $($n => Ok($name::$variant),)+
                    _ => Err(NotAMode { what: $what, value: v, top: Self::ALL.len() as u8 - 1 }),
                }
            }
        }
    };
}

numbered!(
    /// How a view is steered (CAM_CONTROL_MODE).
    Control, "control mode" {
        /// The view looks along the vehicle's nose.
        Pilot = 0,
        /// The view's angles, composed with the vehicle's per its lock flags.
        Directional = 1,
        /// The view aims at its geographic target, followed as the vehicle moves.
        Coordinate = 2,
        /// As directional.
        Pass = 3,
    }
);

numbered!(
    /// How the views sit in the output frame (VIDEO_OUTPUT's layout_mode; conventions.md).
    LayoutMode, "output layout" {
        /// One square as tall as the frame.
        One = 0,
        /// Two squares stacked.
        TwoStacked = 1,
        /// Two panoramas stacked.
        TwoPanoramas = 2,
        /// Two squares over a panorama.
        TwoAndPanorama = 3,
        /// Four squares, 2x2.
        Four = 4,
        /// Three squares over a panorama.
        ThreeAndPanorama = 5,
        /// The whole fisheye frame (no camera input).
        Whole = 6,
    }
);

numbered!(
    /// Where the detection tiles go (VIDEO_OUTPUT's detection_overlay_mode).
    OverlayMode, "output overlay" {
        None = 0,
        /// One tile in the top-right corner, over the views.
        OneTile = 1,
        Right = 2,
        Left = 3,
        Top = 4,
        Bottom = 5,
    }
);

numbered!(
    /// How a view shows the thermal camera (`plan::thermal`; the camera setting
    /// THERMAL).
    #[derive(Default)]
    ThermalShow, "thermal display" {
        /// The fisheye alone.
        #[default]
        Off = 0,
        /// The thermal colours over the fisheye view where the thermal camera sees, half of
        /// each pixel (a rectified view; others show none).
        Blend = 1,
        /// The thermal picture in the view's lower right corner, a third of its width.
        Pip = 2,
        /// The thermal picture alone, filling the view (black bars where the aspects differ).
        Thermal = 3,
    }
);

impl ThermalShow {
    /// Its name, as the web API and the command line give it.
    pub fn name(self) -> &'static str {
        match self {
            ThermalShow::Off => "off",
            ThermalShow::Blend => "blend",
            ThermalShow::Pip => "pip",
            ThermalShow::Thermal => "thermal",
        }
    }
}

impl std::str::FromStr for ThermalShow {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("no thermal display {s:?}: off, blend, pip or thermal"))
    }
}

/// How a view is drawn (CAM_CROP_MODE; conventions.md, "Crop modes"). Any number is taken,
/// as the seed says: one that names no mode draws the view black.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u8", from = "u8")]
pub enum Crop {
    /// Deprecated by the seed: an unrectified crop of the fisheye around the view's aim.
    FisheyeCrop,
    Rectilinear,
    Panorama,
    /// Deprecated by the seed: drawn as rectilinear.
    RectifiedCrop,
    /// The whole fisheye frame, downscaled (debug).
    Whole,
    /// A number beyond 4: the view is black.
    Unknown(u8),
}

impl Crop {
    /// The modes that draw something, in wire order.
    pub const KNOWN: &'static [Crop] = &[
        Crop::FisheyeCrop,
        Crop::Rectilinear,
        Crop::Panorama,
        Crop::RectifiedCrop,
        Crop::Whole,
    ];

    /// Its number on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Crop::FisheyeCrop => 0,
            Crop::Rectilinear => 1,
            Crop::Panorama => 2,
            Crop::RectifiedCrop => 3,
            Crop::Whole => 4,
            Crop::Unknown(v) => v,
        }
    }

    /// Whether it draws a pinhole view (rectilinear, or the rectified crop drawn as one).
    pub const fn pinhole(self) -> bool {
        matches!(self, Crop::Rectilinear | Crop::RectifiedCrop)
    }
}

impl From<u8> for Crop {
    fn from(v: u8) -> Crop {
        match v {
            0 => Crop::FisheyeCrop,
            1 => Crop::Rectilinear,
            2 => Crop::Panorama,
            3 => Crop::RectifiedCrop,
            4 => Crop::Whole,
            v => Crop::Unknown(v),
        }
    }
}

impl From<Crop> for u8 {
    fn from(c: Crop) -> u8 {
        c.code()
    }
}

/// Its number, as the seed writes it.
impl std::fmt::Display for Crop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.code())
    }
}

/// Which of wgpu's backends renders (`--backend`, the serve config's `gpu_backend`): `auto`
/// takes the best adapter of any and checks it draws right (`render::choose`), `vulkan` (Metal
/// or DX12 where those are the platform's) and `gl` (OpenGL or OpenGL ES through EGL) only
/// those adapters. Not on the wire: the log, `/api/status` and `doctor` name it.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum GpuBackend {
    /// The best adapter that draws right, Vulkan before GL on the same kind of device.
    #[default]
    Auto,
    /// Vulkan (Metal on macOS, DX12 on Windows).
    Vulkan,
    /// OpenGL or OpenGL ES through EGL, headless.
    Gl,
}

impl GpuBackend {
    pub fn name(self) -> &'static str {
        match self {
            GpuBackend::Auto => "auto",
            GpuBackend::Vulkan => "vulkan",
            GpuBackend::Gl => "gl",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_mode_is_its_wire_number_and_back_and_a_number_past_the_last_is_refused() {
        for &m in Control::ALL {
            assert_eq!(Control::try_from(m.code()), Ok(m));
        }
        assert_eq!(LayoutMode::ALL.len(), 7);
        assert_eq!(OverlayMode::ALL.len(), 6);
        let e = LayoutMode::try_from(7).unwrap_err();
        assert_eq!(e.to_string(), "output layout 7 is outside 0..=6");
        for v in 0..=255u8 {
            assert_eq!(Crop::from(v).code(), v);
        }
        assert_eq!(Crop::from(9), Crop::Unknown(9));
    }

    #[test]
    fn the_thermal_displays_are_named_and_read_back_and_others_refused_in_words() {
        for &m in ThermalShow::ALL {
            assert_eq!(m.name().parse::<ThermalShow>(), Ok(m));
            assert_eq!(ThermalShow::try_from(m.code()), Ok(m));
        }
        let e = "overlay".parse::<ThermalShow>().unwrap_err();
        assert!(e.contains("off, blend, pip or thermal"), "{e}");
        let e = ThermalShow::try_from(4).unwrap_err();
        assert_eq!(e.to_string(), "thermal display 4 is outside 0..=3");
    }
}
