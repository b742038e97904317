//! DigiView's own auto exposure, for cameras without one (the demo) and for V4L2 cameras in
//! software mode: from the brightness of frames taken with the current setting, the next
//! exposure and gain towards CAM_SENSOR's target_brightness.
//!
//! The loop is a damped step in the logarithm of the light gathered, so it closes most of the
//! gap each time without overshooting; it waits until frames show the last change before it
//! measures again; and it only starts to move when the picture is off by more than 8%, then
//! settles within 3%, so flicker and small scene changes do not make it hunt.

use super::{Limits, Setting};

/// Frames averaged for each step.
const FRAMES_PER_STEP: u32 = 2;
/// How much of the gap (in the logarithm) one step closes.
const GAIN: f64 = 0.8;
/// Start moving when off by more than this factor; stop once within the second.
const START: f64 = 1.08;
const SETTLE: f64 = 1.03;
/// The largest change one step makes, either way.
const MAX_STEP: f64 = 4.0;
/// Frames that differ by more than this factor are still changing (a camera slower to show
/// a new setting than it was thought to be): measure again.
const STEADY: f64 = 1.15;

#[derive(Clone, Debug, Default)]
pub struct AutoExposure {
    /// Frames captured before this time (capture clock, µs) may show an older setting.
    settled_from_us: u64,
    sum: f64,
    frames: u32,
    /// The darkest and brightest frame of those summed.
    range: (f64, f64),
    adjusting: bool,
}

impl AutoExposure {
    /// A frame captured at `captured_us` measured `luma` (full-range mean in the image
    /// circle) while `current` was set. Returns the next setting when it should change; then
    /// frames captured before `now_us + settle_us` are not measured (how long the camera
    /// takes to show a new setting).
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        captured_us: u64,
        luma: f64,
        target: u8,
        current: Setting,
        limits: &Limits,
        now_us: u64,
        settle_us: u64,
    ) -> Option<Setting> {
        if captured_us < self.settled_from_us {
            return None;
        }
        self.sum += luma;
        self.frames += 1;
        self.range = match self.frames {
            1 => (luma, luma),
            _ => (self.range.0.min(luma), self.range.1.max(luma)),
        };
        if self.frames < FRAMES_PER_STEP {
            return None;
        }
        let mean = std::mem::take(&mut self.sum) / std::mem::take(&mut self.frames) as f64;
        if self.range.1 > STEADY * self.range.0.max(0.5) {
            // Still changing: this frame starts the next measure.
            (self.sum, self.frames, self.range) = (luma, 1, (luma, luma));
            return None;
        }
        let off = target.max(1) as f64 / mean.max(0.5);
        let band = if self.adjusting { SETTLE } else { START };
        if off.max(1.0 / off) < band {
            self.adjusting = false;
            return None;
        }
        self.adjusting = true;
        let step = off.powf(GAIN).clamp(1.0 / MAX_STEP, MAX_STEP);
        let next = Setting::for_brightness(current.brightness() * step, limits);
        if next == current {
            // At a limit: nothing more to do until the scene changes.
            return None;
        }
        self.settled_from_us = now_us + settle_us;
        Some(next)
    }

    /// Forgets the measures so far (auto exposure was turned off, or the camera changed).
    pub fn reset(&mut self) {
        *self = AutoExposure::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits {
        exposure_us: (10, 33_333),
        gain: (1000, 50_000),
    };

    /// A camera whose picture is `scene` times the light gathered, clipped at white, showing
    /// a new setting in the frame `lag` frames after the one it was chosen on, while the loop
    /// is told `settle` frames; returns the luma of each frame.
    fn run(scene: f64, start: Setting, target: u8, (lag, settle): (usize, u64)) -> Vec<f64> {
        let mut ae = AutoExposure::default();
        let mut set = start;
        // What the camera shows: settings made, oldest first.
        let mut queue = vec![start; lag];
        let mut lumas = vec![];
        for i in 0..90 {
            let t = i as u64 * 33_333;
            let shown = queue.remove(0);
            let luma = (scene * shown.brightness()).min(255.0);
            lumas.push(luma);
            if let Some(next) = ae.observe(t, luma, target, set, &LIMITS, t, settle * 33_333) {
                set = next;
            }
            queue.push(set);
        }
        lumas
    }

    #[test]
    fn it_settles_within_ten_percent_quickly_from_dark_and_from_bright_without_overshoot() {
        for (scene, start) in [
            (
                100.0,
                Setting {
                    exposure_us: 1000,
                    gain: 1000,
                },
            ), // 10: far too dark
            (
                100.0,
                Setting {
                    exposure_us: 33_333,
                    gain: 4000,
                },
            ), // clipped white
            (
                3.0,
                Setting {
                    exposure_us: 10_000,
                    gain: 1000,
                },
            ), // needs gain
        ] {
            // Told right, and a camera a frame slower than the loop was told.
            for lag in [(1, 1), (3, 3), (2, 1), (4, 3)] {
                let lumas = run(scene, start, 100, lag);
                let settled = lumas
                    .iter()
                    .position(|l| (l - 100.0).abs() <= 10.0)
                    .unwrap_or_else(|| panic!("never settled: {lumas:?}"));
                assert!(settled < 30, "{settled} frames at 30 fps: {lumas:?}");
                assert!(
                    lumas[settled..].iter().all(|l| (l - 100.0).abs() <= 10.0),
                    "left the band again: {lumas:?}"
                );
                let (lo, hi) = (lumas[0].min(100.0), lumas[0].max(100.0));
                assert!(
                    lumas.iter().all(|&l| l >= lo * 0.8 && l <= hi * 1.2),
                    "overshoot: {lumas:?}"
                );
            }
        }
    }

    #[test]
    fn flicker_within_the_band_does_not_make_it_hunt() {
        let mut ae = AutoExposure::default();
        let set = Setting {
            exposure_us: 10_000,
            gain: 1000,
        };
        for i in 0..300u64 {
            // ±6% at 50 Hz beating against 30 fps.
            let luma = 100.0 * (1.0 + 0.06 * (i as f64 * 2.0 * std::f64::consts::PI / 3.0).sin());
            let t = i * 33_333;
            assert_eq!(
                ae.observe(t, luma, 100, set, &LIMITS, t, 0),
                None,
                "frame {i}"
            );
        }
    }

    #[test]
    fn at_its_limits_it_stays_put() {
        let mut ae = AutoExposure::default();
        let longest = Setting {
            exposure_us: 33_333,
            gain: 50_000,
        };
        for i in 0..10u64 {
            assert_eq!(ae.observe(i, 5.0, 200, longest, &LIMITS, i, 0), None);
        }
    }
}
