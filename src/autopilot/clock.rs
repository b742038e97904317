//! The autopilot's boot clock mapped onto the local monotonic clock that frames' capture times
//! use ([`crate::clock::clock_us`]), so an attitude stamped by the autopilot lands at the
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
//!
//! The lowest offset still holds the link's least delay (a serial line's bytes, the
//! autopilot's own queue). Where the autopilot answers TIMESYNC, the round trips of the same
//! window measure it: each trip's midpoint is the true offset give or take half the trip's
//! asymmetry, so the lowest offset minus the midpoint is the least delay with an error of
//! either sign. Their weighted mean is taken out once it is clearly above zero; until then
//! the stamps stand alone, so TIMESYNC never makes the mapping worse than the stamps. A trip
//! that cannot be on the messages' clock (the delay it implies below minus half its round
//! trip, or above [`MAX_FLOOR_US`]) is left out.

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
/// The most a link's least one-way delay can be: a TIMESYNC answer putting the clocks further
/// apart than the messages do is on another clock.
pub const MAX_FLOOR_US: f64 = 200_000.0;
/// Round trips kept at most (ten a second over the window make a hundred), and the least
/// that measure the link's delay.
const MAX_TRIPS: usize = 128;
const MIN_TRIPS: usize = 10;

/// The lowest offset seen in one bucket, and the autopilot time it was seen at.
#[derive(Clone, Copy, Debug)]
struct Minimum {
    bucket: u64,
    remote: u64,
    offset: i64,
}

/// One TIMESYNC round trip.
#[derive(Clone, Copy, Debug)]
struct RoundTrip {
    /// The autopilot's time in its answer, µs.
    remote: u64,
    /// Local minus autopilot time at the round trip's midpoint, µs.
    offset: f64,
    rtt: u64,
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
    /// Whether the drift is fitted yet.
    pub fitted: bool,
    /// The link's least delay that TIMESYNC measured and the mapping takes out, µs (None:
    /// the mapping stands on the messages' stamps alone).
    pub link_delay_us: Option<f64>,
    /// TIMESYNC round trips in the window.
    pub trips: usize,
}

#[derive(Debug, Default)]
pub struct BootClock {
    minima: VecDeque<Minimum>,
    last_remote: Option<u64>,
    /// (slope, intercept at remote 0): local = remote + intercept + slope · remote.
    line: Option<(f64, f64)>,
    /// TIMESYNC round trips of the last ten seconds, and the least delay they measure.
    trips: VecDeque<RoundTrip>,
    delay: Option<f64>,
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

    /// A TIMESYNC answer: the autopilot's time was `remote_us` when it answered the request
    /// sent at local `sent_us`, whose answer came back at local `back_us`.
    pub fn observe_sync(&mut self, remote_us: u64, sent_us: u64, back_us: u64) {
        let Some(last) = self.last_remote else {
            return;
        };
        let window = BUCKET_US * BUCKETS as u64;
        // Far from the messages' clock: another clock, or a reboot not yet seen in stamps.
        if back_us < sent_us || remote_us.abs_diff(last) > window {
            return;
        }
        let midpoint = sent_us as f64 + (back_us - sent_us) as f64 / 2.0;
        self.trips.push_back(RoundTrip {
            remote: remote_us,
            offset: midpoint - remote_us as f64,
            rtt: back_us - sent_us,
        });
        self.trips.retain(|t| t.remote + window >= last);
        while self.trips.len() > MAX_TRIPS {
            self.trips.pop_front();
        }
        self.delay = self.link_delay();
    }

    /// The link's least delay as the round trips measure it: each trip's midpoint against the
    /// stamps' lowest offset, weighted by 1/rtt² (a short trip says more), kept when at least
    /// [`MIN_TRIPS`] of them put it above twice its standard error (else the stamps are left
    /// as they are). Trips that cannot be on the stamps' clock are left out.
    fn link_delay(&self) -> Option<f64> {
        let (mut w_sum, mut w2_sum, mut m_sum, mut n) = (0.0, 0.0, 0.0, 0);
        let mut floors = vec![];
        for t in &self.trips {
            let floor = self.stamp_offset_at(t.remote)? - t.offset;
            // Stamps in whole milliseconds: a millisecond of slack below.
            if floor < -(t.rtt as f64) / 2.0 - 1000.0 || floor > MAX_FLOOR_US {
                continue;
            }
            let w = 1.0 / (t.rtt.max(1) as f64).powi(2);
            (w_sum, w2_sum, m_sum, n) = (w_sum + w, w2_sum + w * w, m_sum + w * floor, n + 1);
            floors.push((floor, w));
        }
        if n < MIN_TRIPS {
            return None;
        }
        let mean = m_sum / w_sum;
        let var = floors
            .iter()
            .map(|(f, w)| w * (f - mean).powi(2))
            .sum::<f64>()
            / w_sum;
        let effective = w_sum * w_sum / w2_sum;
        let error = (var / effective).sqrt();
        (mean > 2.0 * error).then_some(mean)
    }

    /// Local minus autopilot time at `remote_us` by the stamps alone.
    fn stamp_offset_at(&self, remote_us: u64) -> Option<f64> {
        match self.line {
            Some((slope, intercept)) => Some(intercept + slope * remote_us as f64),
            None => self.minima.iter().map(|m| m.offset).min().map(|o| o as f64),
        }
    }

    /// Local minus autopilot time at autopilot time `remote_us`; None before any message.
    fn offset_at(&self, remote_us: u64) -> Option<f64> {
        Some(self.stamp_offset_at(remote_us)? - self.delay.unwrap_or(0.0))
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
            fitted: self.line.is_some(),
            link_delay_us: self.delay,
            trips: self.trips.len(),
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

    /// As [`worst_error`] over 10 s, every delay `floor_us` plus 0 to `jitter_us` (a slow
    /// link's least delay and its spread) and, when `timesync`, a TIMESYNC round trip ten
    /// times a second through the same delays each way: the worst mapping error over the
    /// last `check_s`.
    fn worst_error_on_a_link(
        (floor_us, jitter_us): (f64, f64),
        timesync: bool,
        check_s: f64,
        seed: u64,
    ) -> f64 {
        let mut rng = Rng(seed);
        let mut clock = BootClock::default();
        let boot_offset = 3_700_000.0;
        let remote_at = |local: f64| (local + boot_offset) * (1.0 + 80e-6);
        let mut delay = || floor_us + rng.next() * jitter_us;
        let mut worst: f64 = 0.0;
        for i in 0..2000 {
            let local_true = 1_000_000.0 + i as f64 * 5000.0;
            let remote_ms = (remote_at(local_true) / 1000.0).floor();
            let arrived = local_true + delay();
            clock.observe(remote_ms as u64 * 1000, arrived as u64);
            if timesync && i % 20 == 0 {
                let answered = local_true + delay();
                let back = answered + delay();
                clock.observe_sync(remote_at(answered) as u64, local_true as u64, back as u64);
            }
            if i as f64 * 0.005 >= 10.0 - check_s {
                let mapped = clock.to_local(remote_ms as u64 * 1000).unwrap() as f64;
                worst = worst.max((mapped - local_true).abs());
            }
        }
        worst
    }

    #[test]
    fn timesync_takes_out_the_links_least_delay_and_never_makes_it_worse() {
        for seed in [1, 7, 42] {
            // A serial link: 4 ms least delay, 3 ms of spread.
            let serial = (4000.0, 3000.0);
            let stamps = worst_error_on_a_link(serial, false, 5.0, seed);
            let synced = worst_error_on_a_link(serial, true, 5.0, seed);
            // The tests' link: no least delay, 20 ms of spread.
            let jittery = (0.0, 20_000.0);
            let j_stamps = worst_error_on_a_link(jittery, false, 8.0, seed);
            let j_synced = worst_error_on_a_link(jittery, true, 8.0, seed);
            eprintln!(
                "seed {seed}: 4 + 0..3 ms: stamps {stamps:.0} µs, with TIMESYNC {synced:.0} µs; \
                 0..20 ms: stamps {j_stamps:.0} µs, with TIMESYNC {j_synced:.0} µs"
            );
            assert!(stamps > 3000.0, "the stamps alone carry the least delay");
            assert!(synced < 1200.0, "seed {seed}: {synced:.0} µs with TIMESYNC");
            assert!(
                j_synced < 2000.0,
                "seed {seed}: {j_synced:.0} µs with TIMESYNC"
            );
        }
    }

    #[test]
    fn a_timesync_answer_on_another_clock_is_not_used() {
        let mut c = BootClock::default();
        for i in 0..400u64 {
            c.observe(i * 5000, 10_000_000 + i * 5000 + 2000);
        }
        let trip = |c: &mut BootClock, remote: u64| {
            for _ in 0..12 {
                c.observe_sync(remote, 11_000_000, 11_002_000);
            }
        };
        // Answered in Unix time, not boot time: not used.
        trip(&mut c, 1_700_000_000_000_000);
        assert_eq!(c.state().link_delay_us, None);
        assert_eq!(c.to_local(1_000_000), Some(11_002_000));
        // Answered on a clock 300 ms behind: not used either.
        trip(&mut c, 700_000);
        assert_eq!(c.state().link_delay_us, None);
        // On the boot clock, 1 ms each way: 1 ms of the stamps' 2 ms is the link's.
        trip(&mut c, 1_000_000);
        assert_eq!(c.state().link_delay_us.map(f64::round), Some(1000.0));
        assert_eq!(c.to_local(1_000_000), Some(11_001_000));
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
