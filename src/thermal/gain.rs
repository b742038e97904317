//! How a frame's counts become levels 0 to 255 (which the palette then colours): the gain.
//! Both modes fill one table of [`BINS`] levels over a range of counts, so the CPU and the GPU
//! colour a count the same way from the same few kilobytes:
//!
//! - automatic: plateau equalisation, the thermal cores' own automatic gain. The frame's
//!   histogram over its own coldest to hottest count, each bin held to a plateau (a share of
//!   the pixels) so a sky or a field that fills half the picture does not take half the
//!   levels, then each bin's level from the running sum of the held histogram;
//! - a fixed span in kelvin: the levels spread evenly from the lower temperature to the
//!   higher, colder and hotter clamped to the first and last level, so a colour means one
//!   temperature from frame to frame.

use super::{Calibration, ThermalError, ThermalFrame};

/// The bins of a gain table.
pub const BINS: usize = 1024;

/// The two ways of setting the gain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GainMode {
    /// Plateau equalisation, each bin held to `plateau_percent` of the pixels.
    Auto { plateau_percent: f64 },
    /// The levels spread from `low_k` to `high_k` kelvin.
    Span { low_k: f64, high_k: f64 },
}

impl Default for GainMode {
    /// Automatic, with the plateau at 5 % of the pixels.
    fn default() -> GainMode {
        GainMode::Auto {
            plateau_percent: 5.0,
        }
    }
}

impl GainMode {
    /// The mode, checked: a plateau from 0.1 to 100 %, a span from a lower to a higher
    /// temperature within 0 to 2000 K.
    pub fn checked(self) -> Result<GainMode, ThermalError> {
        match self {
            GainMode::Auto { plateau_percent: p } if !(0.1..=100.0).contains(&p) => {
                Err(ThermalError::Plateau(p))
            }
            GainMode::Span { low_k, high_k }
                if !((0.0..=2000.0).contains(&low_k)
                    && (0.0..=2000.0).contains(&high_k)
                    && low_k < high_k) =>
            {
                Err(ThermalError::Span {
                    low: low_k,
                    high: high_k,
                })
            }
            ok => Ok(ok),
        }
    }
}

/// A level for each of [`BINS`] bins spread over `span` counts from `lo`: count `c` is in bin
/// `(c - lo) × BINS / span`, counts below `lo` in the first and above in the last.
#[derive(Clone, Debug, PartialEq)]
pub struct GainTable {
    pub lo: u16,
    /// How many counts the bins cover, 1 to 65536.
    pub span: u32,
    pub levels: Vec<u8>,
}

impl GainTable {
    /// The table `mode` (checked) gives for `frame`.
    pub fn new(
        frame: &ThermalFrame,
        mode: GainMode,
        cal: &Calibration,
    ) -> Result<GainTable, ThermalError> {
        Ok(match mode.checked()? {
            GainMode::Auto { plateau_percent } => plateau(frame, plateau_percent),
            GainMode::Span { low_k, high_k } => span(cal.counts(low_k), cal.counts(high_k)),
        })
    }

    pub fn bin(&self, c: u16) -> usize {
        let d = (c as u32).saturating_sub(self.lo as u32).min(self.span - 1);
        (d as u64 * BINS as u64 / self.span as u64) as usize
    }

    pub fn level(&self, c: u16) -> u8 {
        self.levels[self.bin(c)]
    }
}

/// Plateau equalisation over the frame's own range.
fn plateau(frame: &ThermalFrame, plateau_percent: f64) -> GainTable {
    let lo = *frame.counts.iter().min().expect("a frame has pixels");
    let hi = *frame.counts.iter().max().expect("a frame has pixels");
    let mut table = GainTable {
        lo,
        span: hi as u32 - lo as u32 + 1,
        levels: vec![0; BINS],
    };
    let mut histogram = vec![0u64; BINS];
    for &c in &frame.counts {
        histogram[table.bin(c)] += 1;
    }
    let cap = ((plateau_percent / 100.0 * frame.counts.len() as f64).round() as u64).max(1);
    for h in &mut histogram {
        *h = (*h).min(cap);
    }
    let total: u64 = histogram.iter().sum();
    // Each bin at the middle of its share of the running sum: a frame of one temperature is
    // mid grey, not white.
    let mut before = 0u64;
    for (level, &h) in table.levels.iter_mut().zip(&histogram) {
        *level = (((2 * before + h) * 255 + total) / (2 * total)) as u8;
        before += h;
    }
    table
}

/// Levels spread evenly over the counts from `lo` to `hi`: each bin the level of the first
/// count in it.
fn span(lo: u16, hi: u16) -> GainTable {
    let span = (hi as u32).saturating_sub(lo as u32) + 1;
    let levels = (0..BINS as u64)
        .map(|b| {
            let first = (b * span as u64).div_ceil(BINS as u64);
            match span {
                1 => 255,
                _ => {
                    ((first * 255 * 2 + (span as u64 - 1)) / (2 * (span as u64 - 1))).min(255) as u8
                }
            }
        })
        .collect();
    GainTable { lo, span, levels }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(counts: Vec<u16>) -> ThermalFrame {
        let n = counts.len() as u32;
        ThermalFrame::new(n / 2, 2, counts).unwrap()
    }

    #[test]
    fn a_span_puts_its_ends_on_the_first_and_last_level_and_clamps_beyond() {
        let cal = Calibration::default();
        let mode = GainMode::Span {
            low_k: 280.0,
            high_k: 320.0,
        };
        let f = frame(vec![0, 28_000, 30_000, 32_000, 40_000, 65_535]);
        let t = GainTable::new(&f, mode, &cal).unwrap();
        let levels: Vec<u8> = f.counts.iter().map(|&c| t.level(c)).collect();
        assert_eq!(levels[..2], [0, 0]);
        assert!((127..=128).contains(&levels[2]), "{levels:?}");
        assert_eq!(levels[3..], [255, 255, 255]);
    }

    #[test]
    fn the_plateau_keeps_a_large_uniform_area_from_taking_the_levels() {
        // Nine tenths of the frame at one temperature, the rest spread over a wide range.
        let mut counts = vec![30_000u16; 900];
        counts.extend((0..100).map(|i| 29_000 + i * 20));
        let f = frame(counts);
        let cal = Calibration::default();
        let level_of = |plateau_percent: f64| {
            let t = GainTable::new(&f, GainMode::Auto { plateau_percent }, &cal).unwrap();
            (t.level(29_000), t.level(30_000), t.level(30_980))
        };
        // Without a plateau the uniform area sits at the middle of most of the levels and
        // the spread is squeezed to the ends; held at 1 %, the spread takes the levels.
        let (cold, mid, hot) = level_of(100.0);
        assert!(
            cold <= 1 && hot >= 253 && (120..=135).contains(&mid),
            "{cold} {mid} {hot}"
        );
        let (cold, _, hot) = level_of(1.0);
        assert!(cold <= 3 && hot >= 252, "{cold} {hot}");
        let t = GainTable::new(
            &f,
            GainMode::Auto {
                plateau_percent: 1.0,
            },
            &cal,
        )
        .unwrap();
        let just_below = t.level(29_960);
        assert!(just_below >= 100, "the spread squeezed: {just_below}");
        // The levels never go down as counts go up.
        assert!(t.levels.windows(2).all(|w| w[0] <= w[1]));
    }

    #[test]
    fn one_temperature_everywhere_is_mid_grey() {
        let f = frame(vec![12_345; 8]);
        let t = GainTable::new(&f, GainMode::default(), &Calibration::default()).unwrap();
        assert_eq!(t.level(12_345), 128);
    }

    #[test]
    fn bad_modes_are_refused_in_words() {
        let e = GainMode::Span {
            low_k: 320.0,
            high_k: 280.0,
        }
        .checked()
        .unwrap_err();
        assert!(e.to_string().contains("from a lower to a higher"), "{e}");
        let e = GainMode::Auto {
            plateau_percent: f64::NAN,
        }
        .checked()
        .unwrap_err();
        assert!(e.to_string().contains("plateau"), "{e}");
    }
}
