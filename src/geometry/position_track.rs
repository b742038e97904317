//! The vehicle's position over time: GLOBAL_POSITION_INT samples stamped on the frames' clock
//! with the velocity they carry, so a frame (and a still drawn from it) gets the position at
//! its own capture time rather than the newest sample's, which at 10 m/s and 10 Hz is up to
//! a metre behind. Between two samples a frame is placed on the line between them; past the
//! newest it is carried on by that sample's velocity, for at most [`CARRY_US`].

use super::ground::{GeoPosition, from_ned};
use glam::DVec3;
use std::collections::VecDeque;

/// Past the newest sample, its velocity carries the position on for at most this long (µs):
/// a link that stalls leaves the vehicle where it was last seen, not drifting away.
pub const CARRY_US: u64 = 1_000_000;
/// Samples kept: several seconds at the rates autopilots send.
const KEPT: usize = 64;

/// A position measured at `t_us` (the frames' clock), moving at `velocity` (north, east, down,
/// m/s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionSample {
    pub t_us: u64,
    pub position: GeoPosition,
    pub velocity: DVec3,
}

#[derive(Debug, Default)]
pub struct PositionTrack {
    samples: VecDeque<PositionSample>,
}

impl PositionTrack {
    /// A new sample; one older than the newest (a reordered datagram) is dropped.
    pub fn push(&mut self, s: PositionSample) {
        match self.samples.back() {
            Some(last) if s.t_us < last.t_us => return,
            Some(last) if s.t_us == last.t_us => {
                self.samples.pop_back();
            }
            _ => {}
        }
        if self.samples.len() == KEPT {
            self.samples.pop_front();
        }
        self.samples.push_back(s);
    }

    /// The newest sample's position.
    pub fn latest(&self) -> Option<GeoPosition> {
        self.samples.back().map(|s| s.position)
    }

    /// The position at `t_us`: between the samples around it, or carried on from the newest
    /// (or back from the oldest) by its velocity.
    pub fn at(&self, t_us: u64) -> Option<GeoPosition> {
        let after = self.samples.partition_point(|s| s.t_us <= t_us);
        let Some(before) = after.checked_sub(1) else {
            return self.samples.front().map(|s| carried(s, t_us));
        };
        let a = &self.samples[before];
        let Some(b) = self.samples.get(after) else {
            return Some(carried(a, t_us));
        };
        let f = (t_us - a.t_us) as f64 / (b.t_us - a.t_us) as f64;
        let mix = |x: f64, y: f64| x + (y - x) * f;
        let (p, q) = (a.position, b.position);
        Some(GeoPosition {
            lat: mix(p.lat, q.lat),
            lon: mix(p.lon, q.lon),
            alt: mix(p.alt, q.alt),
            relative_alt: mix(p.relative_alt, q.relative_alt),
        })
    }
}

/// `s` carried by its velocity to `t_us`, at most [`CARRY_US`] either way.
fn carried(s: &PositionSample, t_us: u64) -> GeoPosition {
    let dt_us = (t_us as i128 - s.t_us as i128).clamp(-(CARRY_US as i128), CARRY_US as i128);
    let moved = s.velocity * (dt_us as f64 * 1e-6);
    if moved == DVec3::ZERO {
        return s.position;
    }
    let p = from_ned(s.position.point(), moved);
    GeoPosition {
        lat: p.lat,
        lon: p.lon,
        alt: p.alt,
        relative_alt: s.position.relative_alt + (p.alt - s.position.alt),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t_us: u64, lat: f64, alt: f64, velocity: DVec3) -> PositionSample {
        PositionSample {
            t_us,
            position: GeoPosition {
                lat,
                lon: 151.0,
                alt,
                relative_alt: alt - 20.0,
            },
            velocity,
        }
    }

    /// Flying north at 10 m/s and climbing at 1 m/s, sampled at 10 Hz: a frame between two
    /// samples lies on the line between them, one after the newest where the velocity takes
    /// it, and one far past the newest no further than a second's flight.
    #[test]
    fn a_frame_gets_the_position_at_its_own_time() {
        let north = DVec3::new(10.0, 0.0, -1.0);
        // 10 m north is 10 / 111_000-odd degrees of latitude here.
        let step = from_ned(sample(0, -33.0, 100.0, north).position.point(), north * 0.1).lat;
        let mut track = PositionTrack::default();
        track.push(sample(1_000_000, -33.0, 100.0, north));
        track.push(sample(1_100_000, step, 100.1, north));
        let mid = track.at(1_050_000).unwrap();
        assert!((mid.lat - (-33.0 + step) / 2.0).abs() < 1e-12, "{mid:?}");
        assert!((mid.alt - 100.05).abs() < 1e-9 && (mid.relative_alt - 80.05).abs() < 1e-9);
        let ahead = track.at(1_150_000).unwrap();
        let expected = from_ned(track.latest().unwrap().point(), north * 0.05);
        assert!((ahead.lat - expected.lat).abs() < 1e-12, "{ahead:?}");
        assert!((ahead.alt - 100.15).abs() < 1e-6, "{ahead:?}");
        assert!((ahead.relative_alt - 80.15).abs() < 1e-6, "{ahead:?}");
        let far = track.at(60_000_000).unwrap();
        assert_eq!(
            far,
            track.at(2_100_000).unwrap(),
            "carried a second at most"
        );
        assert_eq!(track.latest().unwrap().lat, step);
    }

    #[test]
    fn a_sample_older_than_the_newest_is_dropped_and_one_at_rest_stays_put() {
        let mut track = PositionTrack::default();
        track.push(sample(2_000_000, 10.0, 50.0, DVec3::ZERO));
        track.push(sample(1_000_000, 11.0, 50.0, DVec3::ZERO));
        assert_eq!(track.latest().unwrap().lat, 10.0);
        assert_eq!(track.at(5_000_000).unwrap().lat, 10.0);
        assert_eq!(track.at(0).unwrap().lat, 10.0);
        assert_eq!(PositionTrack::default().at(0), None);
    }
}
