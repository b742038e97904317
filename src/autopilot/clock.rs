//! The autopilot's boot clock mapped onto the local monotonic clock that frames' capture times
//! use ([`crate::source::clock_us`]), so an attitude stamped by the autopilot lands at the
//! right place among the frames.
//!
//! Every message stamped `remote` by the autopilot and received at `local` gives an offset
//! `local - remote` = the clocks' true offset + the transport delay, and delays are never
//! negative, so the lowest offsets are the truest. The offsets are kept as the lowest one per
//! half second of the autopilot's time over the last ten seconds; once they span five seconds,
//! the clocks' drift is the slope of a least-squares line through those minima (at most
//! 100 ppm: more is the delays' noise; crystals drift by tens), and the line is then lowered
//! onto the lowest of them. Before that, the lowest offset seen serves. An autopilot whose
//! clock jumps back (it rebooted) starts the mapping afresh.

use std::collections::VecDeque;

/// The span of autopilot time one minimum covers, and how many are kept.
const BUCKET_US: u64 = 500_000;
const BUCKETS: usize = 20;
/// Minima spanning this much estimate the drift.
const DRIFT_SPAN_US: u64 = 5_000_000;
/// The largest drift believed, as a rate (100 ppm).
const MAX_DRIFT: f64 = 100e-6;
/// The autopilot's clock going back by more than this is a reboot.
const REBOOT_US: u64 = 1_000_000;

/// The lowest offset seen in one bucket, and the autopilot time it was seen at.
#[derive(Clone, Copy, Debug)]
struct Minimum {
    bucket: u64,
    remote: u64,
    offset: i64,
}

/// What the mapping knows, for the log and `ctl`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClockState {
    /// Messages observed since the mapping (re)started.
    pub samples: u64,
    /// Local minus autopilot time now, µs.
    pub offset_us: i64,
    /// The autopilot clock's rate against ours, parts per million (0 until estimated).
    pub drift_ppm: f64,
    /// The autopilot time the minima span, µs.
    pub span_us: u64,
    /// Times the autopilot's clock went back (reboots).
    pub resets: u64,
}

#[derive(Debug, Default)]
pub struct BootClock {
    minima: VecDeque<Minimum>,
    last_remote: Option<u64>,
    /// (slope, intercept at remote 0): local = remote + intercept + slope · remote.
    line: Option<(f64, f64)>,
    samples: u64,
    resets: u64,
}

impl BootClock {
    /// A message stamped `remote_us` by the autopilot arrived at `local_us`.
    pub fn observe(&mut self, remote_us: u64, local_us: u64) {
        if self
            .last_remote
            .is_some_and(|last| remote_us + REBOOT_US < last)
        {
            let resets = self.resets + 1;
            *self = BootClock {
                resets,
                ..BootClock::default()
            };
        }
        self.last_remote = Some(self.last_remote.map_or(remote_us, |l| l.max(remote_us)));
        self.samples += 1;
        let offset = local_us as i64 - remote_us as i64;
        let bucket = remote_us / BUCKET_US;
        match self.minima.iter_mut().find(|m| m.bucket == bucket) {
            Some(m) if offset < m.offset => {
                (m.remote, m.offset) = (remote_us, offset);
            }
            Some(_) => return,
            None => {
                let at = self.minima.partition_point(|m| m.bucket < bucket);
                self.minima.insert(
                    at,
                    Minimum {
                        bucket,
                        remote: remote_us,
                        offset,
                    },
                );
                while self.minima.len() > BUCKETS {
                    self.minima.pop_front();
                }
            }
        }
        self.line = self.fit();
    }

    /// The drift line through the minima, lowered onto the lowest; None before they span
    /// [`DRIFT_SPAN_US`].
    fn fit(&self) -> Option<(f64, f64)> {
        let (first, last) = (self.minima.front()?, self.minima.back()?);
        if last.remote - first.remote < DRIFT_SPAN_US || self.minima.len() < 3 {
            return None;
        }
        let n = self.minima.len() as f64;
        let x0 = first.remote as f64;
        let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
        for m in &self.minima {
            let (x, y) = (m.remote as f64 - x0, m.offset as f64);
            (sx, sy, sxx, sxy) = (sx + x, sy + y, sxx + x * x, sxy + x * y);
        }
        // Clocks with crystals drift by tens of ppm: a larger slope is the delays' noise.
        let slope = ((n * sxy - sx * sy) / (n * sxx - sx * sx)).clamp(-MAX_DRIFT, MAX_DRIFT);
        let lowest = self
            .minima
            .iter()
            .map(|m| m.offset as f64 - slope * (m.remote as f64 - x0))
            .fold(f64::INFINITY, f64::min);
        Some((slope, lowest - slope * x0))
    }

    /// Local minus autopilot time at autopilot time `remote_us`; None before any message.
    fn offset_at(&self, remote_us: u64) -> Option<f64> {
        match self.line {
            Some((slope, intercept)) => Some(intercept + slope * remote_us as f64),
            None => self.minima.iter().map(|m| m.offset).min().map(|o| o as f64),
        }
    }

    /// The local time of autopilot time `remote_us`; None before any message.
    pub fn to_local(&self, remote_us: u64) -> Option<u64> {
        let offset = self.offset_at(remote_us)?;
        Some((remote_us as f64 + offset).max(0.0).round() as u64)
    }

    pub fn state(&self) -> ClockState {
        let now = self.last_remote.unwrap_or(0);
        ClockState {
            samples: self.samples,
            offset_us: self.offset_at(now).unwrap_or(0.0).round() as i64,
            drift_ppm: self.line.map_or(0.0, |(slope, _)| slope * 1e6),
            span_us: match (self.minima.front(), self.minima.back()) {
                (Some(a), Some(b)) => b.remote - a.remote,
                _ => 0,
            },
            resets: self.resets,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), so the test needs no crate and repeats.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Messages about every 5 ms (200 Hz) stamped in whole milliseconds, as ATTITUDE's
    /// time_boot_ms, from an autopilot booted 3.7 s before our clock's zero, its clock 80 ppm
    /// fast, through 0 to 20 ms of random delay; the worst mapping error over the last
    /// `check_s` of `run_s`.
    fn worst_error(run_s: f64, check_s: f64, seed: u64) -> f64 {
        let mut rng = Rng(seed);
        let mut clock = BootClock::default();
        let boot_offset = 3_700_000.0;
        let mut worst: f64 = 0.0;
        let steps = (run_s / 0.005) as usize;
        for i in 0..steps {
            // True local time of the message's making (every 5 ms, at any phase of the
            // millisecond), and the autopilot's reading of it.
            let local_true = (1_000_000.0 + i as f64 * 5000.0 + rng.next() * 1000.0).round();
            let remote_ms = ((local_true + boot_offset) * (1.0 + 80e-6) / 1000.0).floor();
            let arrived = local_true + rng.next() * 20_000.0;
            clock.observe(remote_ms as u64 * 1000, arrived as u64);
            if i as f64 * 0.005 >= run_s - check_s {
                let mapped = clock.to_local(remote_ms as u64 * 1000).unwrap() as f64;
                worst = worst.max((mapped - local_true).abs());
            }
        }
        worst
    }

    #[test]
    fn the_mapping_is_within_two_milliseconds_after_two_seconds_of_jittered_messages() {
        for seed in [1, 7, 42, 1234, 99991] {
            let early = worst_error(2.0, 0.05, seed);
            let late = worst_error(30.0, 10.0, seed);
            eprintln!("seed {seed}: worst {early:.0} µs at 2 s, {late:.0} µs over 20..30 s");
            assert!(early < 2000.0, "seed {seed}: {early:.0} µs after 2 s");
            assert!(
                late < 2000.0,
                "seed {seed}: {late:.0} µs over 20..30 s (drift)"
            );
        }
    }

    #[test]
    fn the_drift_is_estimated_and_a_reboot_starts_afresh() {
        let mut c = BootClock::default();
        for i in 0..2000u64 {
            // 60 ppm slow against us, no delay.
            let remote = i * 5000;
            c.observe(remote, 10_000_000 + (remote as f64 * (1.0 + 60e-6)) as u64);
        }
        let s = c.state();
        assert!((s.drift_ppm - 60.0).abs() < 5.0, "{s:?}");
        c.observe(1000, 50_000_000);
        assert_eq!(c.state().resets, 1);
        assert_eq!(c.state().samples, 1);
        assert_eq!(c.to_local(2000), Some(50_001_000));
    }
}
