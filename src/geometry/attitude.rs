//! Vehicle attitude over time: timestamped samples, and the attitude at a frame's capture time
//! by spherical interpolation between the two samples around it (or, for a frame captured
//! after the newest sample that has arrived, turning on as the last two samples did).

use super::rotation::Euler;
use glam::DQuat;
use std::collections::VecDeque;

/// How far past the newest sample the attitude is carried on at the last two samples' rate, µs.
/// An autopilot's samples arrive some milliseconds after they are taken (a link's delay, a
/// busy flight controller), often after a frame captured at the same moment is rendered: held
/// at the newest sample, a vehicle turning 90°/s would be drawn a degree or two behind. Past
/// this, a silent autopilot's last attitude is held rather than guessed.
const EXTRAPOLATION_US: u64 = 50_000;

/// A bounded history of attitude samples, oldest first, timestamps in microseconds.
#[derive(Clone, Debug)]
pub struct AttitudeTrack {
    samples: VecDeque<(u64, DQuat)>,
    capacity: usize,
}

impl AttitudeTrack {
    pub fn new(capacity: usize) -> Self {
        AttitudeTrack {
            samples: VecDeque::with_capacity(capacity),
            capacity: capacity.max(2),
        }
    }

    /// Adds a sample. Samples may arrive out of order; one with the time of an existing sample
    /// replaces it. The oldest is dropped when full.
    pub fn push(&mut self, t_us: u64, attitude: Euler) {
        let q = attitude.quat().normalize();
        match self.samples.binary_search_by_key(&t_us, |s| s.0) {
            Ok(i) => self.samples[i].1 = q,
            Err(i) => self.samples.insert(i, (t_us, q)),
        }
        while self.samples.len() > self.capacity {
            self.samples.pop_front();
        }
    }

    /// The newest sample, whatever its time.
    pub fn latest(&self) -> Option<Euler> {
        self.samples.back().map(|&(_, q)| Euler::from_quat(q))
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The attitude at time `t_us`: slerp between the samples around it; after the newest,
    /// turning on at the rate between the last two for up to [`EXTRAPOLATION_US`]; before
    /// the oldest, the oldest; None with no samples.
    pub fn at(&self, t_us: u64) -> Option<Euler> {
        let i = self.samples.partition_point(|s| s.0 <= t_us);
        let q = match (
            i.checked_sub(1).map(|j| self.samples[j]),
            self.samples.get(i),
        ) {
            (Some((t0, q0)), Some(&(t1, q1))) => {
                let s = (t_us - t0) as f64 / (t1 - t0) as f64;
                // Shortest path: q and -q are the same rotation.
                let q1 = if q0.dot(q1) < 0.0 { -q1 } else { q1 };
                q0.slerp(q1, s)
            }
            (Some((t0, q0)), None) if i >= 2 => {
                let (tp, qp) = self.samples[i - 2];
                let ahead = (t_us - t0).min(EXTRAPOLATION_US) as f64 / (t0 - tp) as f64;
                let qp = if qp.dot(q0) < 0.0 { -qp } else { qp };
                q0 * DQuat::from_scaled_axis((qp.inverse() * q0).to_scaled_axis() * ahead)
            }
            (Some((_, q)), None) | (None, Some(&(_, q))) => q,
            (None, None) => return None,
        };
        Some(Euler::from_quat(q))
    }
}
