//! A thermal sensor's pictures as data, below everything that shows them: a radiometric frame
//! of 16-bit counts, the linear calibration that makes counts kelvin, the hottest and coldest
//! point of a frame and the temperature at any point of it (`ThermalFrame`), and how counts
//! become colours: the automatic or fixed gain (`gain`) and the palettes (`palette`). The
//! CPU reference of the colouring is here ([`colourise`]); the GPU's twin is
//! `render::gpu::thermal` (shaders/thermal.wgsl), held to it by the tests.

pub mod gain;
pub mod palette;
pub mod synth;

pub use gain::{GainMode, GainTable};
pub use palette::Palette;

use crate::image_ops::{bilinear_by, neighbours};
use glam::{DVec2, DVec3};
use image::RgbaImage;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ThermalError {
    #[error("a thermal frame of {width}x{height} needs {needed} counts; {given} were given")]
    Size {
        width: u32,
        height: u32,
        needed: usize,
        given: usize,
    },
    #[error("a thermal frame must be at least 2x2 pixels; this one is {0}x{1}")]
    TooSmall(u32, u32),
    #[error(
        "thermal kelvin_per_count must be a number from 0.0001 to 1 K (a radiometric core \
         gives 0.01 or 0.1); {0} was given"
    )]
    Scale(f64),
    #[error("thermal kelvin_offset must be a number from -1000 to 1000 K; {0} was given")]
    Offset(f64),
    #[error(
        "a thermal span must run from a lower to a higher temperature, each from 0 to \
         2000 K; {low} K to {high} K was given"
    )]
    Span { low: f64, high: f64 },
    #[error("the thermal gain's plateau must be from 0.1 to 100 % of the pixels; {0} was given")]
    Plateau(f64),
    #[error("no thermal palette is called {0:?}; the palettes are {1}")]
    Palette(String, String),
    #[error("the point ({x:.1}, {y:.1}) is outside the {width}x{height} thermal frame")]
    Outside {
        x: f64,
        y: f64,
        width: u32,
        height: u32,
    },
}

/// The range of a calibration's kelvin a count (a core's TLinear gives 0.01 or 0.1).
pub const KELVIN_PER_COUNT: (f64, f64) = (0.0001, 1.0);
/// The range of a calibration's offset, kelvin.
pub const KELVIN_OFFSET: (f64, f64) = (-1000.0, 1000.0);

/// How counts become temperatures: kelvin = counts × `kelvin_per_count` + `kelvin_offset`
/// (a radiometric core in its linear mode: FLIR's TLinear gives 0.01 K a count, or 0.1 at
/// high gain's wider range, from 0 K).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    pub kelvin_per_count: f64,
    pub kelvin_offset: f64,
}

impl Default for Calibration {
    fn default() -> Calibration {
        Calibration {
            kelvin_per_count: 0.01,
            kelvin_offset: 0.0,
        }
    }
}

impl Calibration {
    /// The calibration, checked: a scale above 0 up to 1 K, an offset within ±1000 K.
    pub fn new(kelvin_per_count: f64, kelvin_offset: f64) -> Result<Calibration, ThermalError> {
        if !(KELVIN_PER_COUNT.0..=KELVIN_PER_COUNT.1).contains(&kelvin_per_count) {
            return Err(ThermalError::Scale(kelvin_per_count));
        }
        if !(KELVIN_OFFSET.0..=KELVIN_OFFSET.1).contains(&kelvin_offset) {
            return Err(ThermalError::Offset(kelvin_offset));
        }
        Ok(Calibration {
            kelvin_per_count,
            kelvin_offset,
        })
    }

    pub fn kelvin(&self, counts: f64) -> f64 {
        counts * self.kelvin_per_count + self.kelvin_offset
    }

    /// The counts of `kelvin`, clamped to what 16 bits hold.
    pub fn counts(&self, kelvin: f64) -> u16 {
        ((kelvin - self.kelvin_offset) / self.kelvin_per_count)
            .round()
            .clamp(0.0, u16::MAX as f64) as u16
    }
}

/// Pixels this close to the hottest (coldest) are one patch with it.
pub const TIE_K: f64 = 0.1;

/// One frame of a radiometric sensor: `width` × `height` counts, rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalFrame {
    pub width: u32,
    pub height: u32,
    pub counts: Vec<u16>,
}

/// A point of a frame and its temperature.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Spot {
    /// The pixel's centre, in the frame's pixels (x right, y down; the first pixel's centre
    /// is (0.5, 0.5)).
    pub x: f64,
    pub y: f64,
    pub kelvin: f64,
}

/// The hottest and coldest point of a frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Extremes {
    pub hottest: Spot,
    pub coldest: Spot,
}

impl ThermalFrame {
    pub fn new(width: u32, height: u32, counts: Vec<u16>) -> Result<ThermalFrame, ThermalError> {
        if width < 2 || height < 2 {
            return Err(ThermalError::TooSmall(width, height));
        }
        let needed = width as usize * height as usize;
        if counts.len() != needed {
            return Err(ThermalError::Size {
                width,
                height,
                needed,
                given: counts.len(),
            });
        }
        Ok(ThermalFrame {
            width,
            height,
            counts,
        })
    }

    /// A frame from 16-bit little-endian samples (V4L2's Y16, GStreamer's GRAY16_LE).
    pub fn from_le_bytes(width: u32, height: u32, bytes: &[u8]) -> Result<Self, ThermalError> {
        let counts = bytes
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        ThermalFrame::new(width, height, counts)
    }

    pub fn at(&self, x: u32, y: u32) -> u16 {
        self.counts[(y * self.width + x) as usize]
    }

    /// The hottest and coldest point: each the middle of the patch of pixels around the
    /// first hottest (coldest) one, in reading order, that are within [`TIE_K`] of it (a warm
    /// body the same temperature all over is found at its middle, not at its top edge).
    pub fn extremes(&self, cal: &Calibration) -> Extremes {
        self.extremes_where(cal, |_| true)
            .expect("a frame has pixels")
    }

    /// [`ThermalFrame::extremes`] of the pixels `keep` takes (by index, rows top to bottom),
    /// their patches taking none other; None where it takes none.
    pub fn extremes_where(
        &self,
        cal: &Calibration,
        keep: impl Fn(usize) -> bool,
    ) -> Option<Extremes> {
        let mut kept = (0..self.counts.len()).filter(|&i| keep(i));
        let first = kept.next()?;
        let (mut hot, mut cold) = (first, first);
        for i in kept {
            let c = self.counts[i];
            if c > self.counts[hot] {
                hot = i;
            }
            if c < self.counts[cold] {
                cold = i;
            }
        }
        let tie = (TIE_K / cal.kelvin_per_count).floor() as u32;
        let hot_from = (self.counts[hot] as u32).saturating_sub(tie);
        let cold_to = self.counts[cold] as u32 + tie;
        let counts = &self.counts;
        Some(Extremes {
            hottest: self.patch(hot, |i| keep(i) && counts[i] as u32 >= hot_from, cal),
            coldest: self.patch(cold, |i| keep(i) && counts[i] as u32 <= cold_to, cal),
        })
    }

    /// The middle of the 8-connected patch around pixel `first` of the pixels `within` takes
    /// (by index), at `first`'s temperature.
    fn patch(&self, first: usize, within: impl Fn(usize) -> bool, cal: &Calibration) -> Spot {
        let (w, h) = (self.width as usize, self.height as usize);
        let mut seen = std::collections::HashSet::from([first]);
        let mut todo = vec![first];
        let (mut sx, mut sy) = (0.0, 0.0);
        while let Some(i) = todo.pop() {
            sx += (i % w) as f64 + 0.5;
            sy += (i / w) as f64 + 0.5;
            for n in neighbours(i, w, h) {
                if within(n) && seen.insert(n) {
                    todo.push(n);
                }
            }
        }
        let n = seen.len() as f64;
        Spot {
            x: sx / n,
            y: sy / n,
            kelvin: cal.kelvin(self.counts[first] as f64),
        }
    }

    /// The temperature at (`x`, `y`) in the frame's pixels, interpolated between the four
    /// pixels around it (the edge pixels held beyond their centres).
    pub fn spot(&self, x: f64, y: f64, cal: &Calibration) -> Result<Spot, ThermalError> {
        let (w, h) = (self.width as f64, self.height as f64);
        if !(0.0..=w).contains(&x) || !(0.0..=h).contains(&y) {
            return Err(ThermalError::Outside {
                x,
                y,
                width: self.width,
                height: self.height,
            });
        }
        // Pixel centres at whole numbers for the sampler, edges clamped.
        let (wi, hi) = (self.width as i64, self.height as i64);
        let at = |px: i64, py: i64| {
            let c = self.at(px.clamp(0, wi - 1) as u32, py.clamp(0, hi - 1) as u32);
            DVec3::splat(c as f64)
        };
        let counts = bilinear_by(DVec2::new(x - 0.5, y - 0.5), at).x;
        Ok(Spot {
            x,
            y,
            kelvin: cal.kelvin(counts),
        })
    }
}

/// The CPU reference of the colouring: each pixel's level under `gain`, then its colour in
/// `palette` (opaque).
pub fn colourise(frame: &ThermalFrame, gain: &GainTable, palette: Palette) -> RgbaImage {
    let table = palette.table();
    let mut out = RgbaImage::new(frame.width, frame.height);
    for (px, &c) in out.pixels_mut().zip(&frame.counts) {
        px.0 = table[gain.level(c) as usize];
    }
    out
}
