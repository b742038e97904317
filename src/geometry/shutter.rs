//! Rolling shutter: a sensor that reads its rows one after another, so each row of a frame
//! sees the world at its own moment. [`Readout`] is the camera's model of it (how long the
//! readout takes, which way it runs across the frame, and which row the capture timestamp
//! names); [`ShutterTable`] is one frame's small table of rotations, from the lens frame at
//! the frame's middle row to the lens frame at the time each of [`KNOTS`] evenly spaced rows
//! was read. The renderers (CPU and GPU alike) and everything that maps fisheye pixels to
//! rays read a frame through its table; a global shutter (readout 0) has none.
//!
//! Time runs in microseconds from the frame's middle row, the moment the frame is rendered
//! for.

use glam::{DMat3, DQuat, DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// Rows of the frame whose rotation the table holds, evenly spaced from the first row read to
/// the last; between two, the rotation is interpolated (nlerp). 16 bands: at 90°/s and a
/// 25 ms readout, 0.14° a band, where interpolating a steady turn is exact and a 1 Hz
/// vibration of ±20° is off by under 0.001°.
pub const KNOTS: usize = 17;
/// The longest readout taken, milliseconds (a camera slower than a frame at 10 fps).
pub const MAX_READOUT_MS: f64 = 100.0;

/// Which way the sensor's readout runs across the frame as it arrives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ReadoutDirection {
    /// Row 0 first (most sensors, mounted upright).
    #[default]
    TopToBottom,
    /// The last row first (a sensor mounted upside down, or a frame flipped by the driver).
    BottomToTop,
    /// Column 0 first (a sensor mounted on its side).
    LeftToRight,
    RightToLeft,
}

/// Which row's time the capture timestamp gives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StampRow {
    /// The first row read (start of frame).
    #[default]
    Start,
    Middle,
    /// The last row read (end of frame: many V4L2 drivers).
    End,
}

/// The camera's readout (`[readout]` in the serve configuration; `--readout-ms` and friends
/// on `render` and `bench`). Readout 0 is a global shutter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct Readout {
    /// Milliseconds from the first row read to the last, in the sensor mode the camera runs.
    pub time_ms: f64,
    pub direction: ReadoutDirection,
    /// Which row the frames' capture timestamps name.
    pub timestamp: StampRow,
}

/// A readout time that is no number or outside 0..=[`MAX_READOUT_MS`].
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("readout time_ms {0:?} is outside 0..={MAX_READOUT_MS} ms")]
pub struct BadReadout(pub f64);

impl Readout {
    /// A readout of `time_ms` top to bottom, stamped at its start.
    pub fn top_to_bottom(time_ms: f64) -> Readout {
        Readout {
            time_ms,
            ..Readout::default()
        }
    }

    /// Whether every row is read at once (nothing to correct).
    pub fn is_global(&self) -> bool {
        self.time_ms <= 0.0
    }

    /// Refuses a readout that is not a number or is outside 0..=[`MAX_READOUT_MS`].
    pub fn check(&self) -> Result<(), BadReadout> {
        match self.time_ms.is_finite() && (0.0..=MAX_READOUT_MS).contains(&self.time_ms) {
            true => Ok(()),
            false => Err(BadReadout(self.time_ms)),
        }
    }

    /// Microseconds from the capture timestamp to the middle row's reading.
    pub fn middle_after_stamp_us(&self) -> f64 {
        let stamp = match self.timestamp {
            StampRow::Start => 0.0,
            StampRow::Middle => 0.5,
            StampRow::End => 1.0,
        };
        (0.5 - stamp) * self.time_ms.max(0.0) * 1000.0
    }

    /// The knot coordinate of fisheye point q (OpenCV pixels) of a `size` frame, as
    /// `line · (q.x, q.y, 1)`: 0 at the first row read, `KNOTS - 1` at the last.
    pub fn line(&self, (width, height): (u32, u32)) -> DVec3 {
        let bands = (KNOTS - 1) as f64;
        let (w, h) = (width.max(1) as f64, height.max(1) as f64);
        match self.direction {
            ReadoutDirection::TopToBottom => DVec3::new(0.0, bands / h, 0.5 * bands / h),
            ReadoutDirection::BottomToTop => DVec3::new(0.0, -bands / h, bands * (h - 0.5) / h),
            ReadoutDirection::LeftToRight => DVec3::new(bands / w, 0.0, 0.5 * bands / w),
            ReadoutDirection::RightToLeft => DVec3::new(-bands / w, 0.0, bands * (w - 0.5) / w),
        }
    }

    /// Microseconds from the middle row's reading to knot `k`'s.
    pub fn knot_us(&self, k: usize) -> f64 {
        (k as f64 / (KNOTS - 1) as f64 - 0.5) * self.time_ms * 1000.0
    }

    /// Microseconds from the middle row's reading to the reading of fisheye point q.
    pub fn point_us(&self, q: DVec2, size: (u32, u32)) -> f64 {
        let k = self.line(size).dot(q.extend(1.0));
        (k / (KNOTS - 1) as f64 - 0.5) * self.time_ms * 1000.0
    }
}

/// One frame's rolling shutter: where each fisheye point was read, and the rotation from the
/// lens frame at the middle row's time to the lens frame when that row was read.
#[derive(Clone, Debug, PartialEq)]
pub struct ShutterTable {
    /// Fisheye point q → knot coordinate `line · (q.x, q.y, 1)` (clamped to the knots).
    pub line: DVec3,
    /// Unit quaternions, knot by knot: lens frame at the middle row → lens frame at the knot.
    pub knots: [DQuat; KNOTS],
}

impl ShutterTable {
    /// The table of a frame `size` pixels read out as `readout` says, where
    /// `lens_from_world(dt_us)` is the lens's orientation `dt_us` after the middle row was
    /// read. None for a global shutter.
    pub fn new(
        readout: &Readout,
        size: (u32, u32),
        lens_from_world: impl Fn(f64) -> DMat3,
    ) -> Option<ShutterTable> {
        if readout.is_global() {
            return None;
        }
        let middle = DQuat::from_mat3(&lens_from_world(0.0)).normalize();
        let mut knots = [DQuat::IDENTITY; KNOTS];
        let mut previous = DQuat::IDENTITY;
        for (k, knot) in knots.iter_mut().enumerate() {
            let at = DQuat::from_mat3(&lens_from_world(readout.knot_us(k))).normalize();
            let q = (at * middle.conjugate()).normalize();
            // Neighbours on the same side of the sphere, so interpolation takes the short way.
            *knot = if q.dot(previous) < 0.0 { -q } else { q };
            previous = *knot;
        }
        Some(ShutterTable {
            line: readout.line(size),
            knots,
        })
    }

    /// The rotation at fisheye point q: normalised linear interpolation between the knots
    /// around it (shaders/views.wgsl's `shutter_at`).
    pub fn at(&self, q: DVec2) -> DQuat {
        let k = self.line.dot(q.extend(1.0)).clamp(0.0, (KNOTS - 1) as f64);
        let i = (k.floor() as usize).min(KNOTS - 2);
        let f = k - i as f64;
        (self.knots[i] * (1.0 - f) + self.knots[i + 1] * f).normalize()
    }

    /// The same table for the frame scaled from `from` to `to` pixels (a lens planned at the
    /// sensor's size for a frame that arrived smaller): the same rows, their pixel
    /// coordinates scaled as `Lens::for_frame` scales them (q' + ½ = (q + ½) · s).
    pub fn resized(&self, from: (u32, u32), to: (u32, u32)) -> ShutterTable {
        let s = DVec2::new(
            to.0.max(1) as f64 / from.0.max(1) as f64,
            to.1.max(1) as f64 / from.1.max(1) as f64,
        );
        let l = self.line;
        let half = 0.5 / s - 0.5;
        ShutterTable {
            line: DVec3::new(l.x / s.x, l.y / s.y, l.z + l.x * half.x + l.y * half.y),
            knots: self.knots,
        }
    }

    /// Where a ray in the lens frame (as the lens was at the middle row) lands, `project`
    /// being the lens's projection: projected, then projected again [`STEPS`] times with
    /// the rotation of the row it landed on. None where any projection is.
    pub fn project(&self, ray: DVec3, project: impl Fn(DVec3) -> Option<DVec2>) -> Option<DVec2> {
        let mut q = project(ray)?;
        for _ in 0..STEPS {
            q = project(self.at(q) * ray)?;
        }
        Some(q)
    }
}

/// How often a rolling-shutter frame's ray is projected again with the rotation of the row it
/// landed on ([`ShutterTable::project`]; SHUTTER_STEPS in shaders/views.wgsl). One step (as
/// Gyroflow) leaves a point that moved across rows during the readout up to a quarter pixel
/// off at 90°/s and a 25 ms readout at 4K (0.265 px); two leave 0.005 px
/// (tests/it/rolling_shutter.rs).
pub const STEPS: usize = 2;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Euler;

    #[test]
    fn each_direction_reads_its_first_row_at_knot_0_and_its_last_at_the_end() {
        let size = (640, 480);
        let last = (KNOTS - 1) as f64;
        let k = |d, q: DVec2| {
            let r = Readout {
                direction: d,
                ..Readout::top_to_bottom(20.0)
            };
            r.line(size).dot(q.extend(1.0))
        };
        use ReadoutDirection::*;
        // Pixel centres of the first and last rows (columns) lie half a row inside the ends.
        let half = 0.5 * last / 480.0;
        assert!((k(TopToBottom, DVec2::new(9.0, 0.0)) - half).abs() < 1e-12);
        assert!((k(TopToBottom, DVec2::new(9.0, 479.0)) - (last - half)).abs() < 1e-12);
        assert!((k(BottomToTop, DVec2::new(9.0, 479.0)) - half).abs() < 1e-12);
        let half = 0.5 * last / 640.0;
        assert!((k(LeftToRight, DVec2::new(0.0, 7.0)) - half).abs() < 1e-12);
        assert!((k(RightToLeft, DVec2::new(0.0, 7.0)) - (last - half)).abs() < 1e-12);
    }

    #[test]
    fn a_table_resized_reads_the_same_rows_at_the_scaled_points() {
        let yaw = |dt: f64| Euler::new(1.5 * dt * 1e-6, 0.0, 0.0).matrix().transpose();
        for direction in [ReadoutDirection::TopToBottom, ReadoutDirection::RightToLeft] {
            let readout = Readout {
                direction,
                ..Readout::top_to_bottom(25.0)
            };
            let small = ShutterTable::new(&readout, (640, 360), yaw).unwrap();
            let big = small.resized((640, 360), (3840, 2160));
            let made = ShutterTable::new(&readout, (3840, 2160), yaw).unwrap();
            assert!(big.line.abs_diff_eq(made.line, 1e-15) && big.knots == made.knots);
            let q = DVec2::new(100.25, 200.75);
            let scaled = (q + 0.5) * 6.0 - 0.5;
            assert!(small.at(q).angle_between(big.at(scaled)) < 1e-12);
        }
    }

    #[test]
    fn the_timestamp_row_moves_the_middle_row_by_half_a_readout_either_way() {
        let r = |timestamp| Readout {
            timestamp,
            ..Readout::top_to_bottom(30.0)
        };
        assert_eq!(r(StampRow::Start).middle_after_stamp_us(), 15_000.0);
        assert_eq!(r(StampRow::Middle).middle_after_stamp_us(), 0.0);
        assert_eq!(r(StampRow::End).middle_after_stamp_us(), -15_000.0);
        assert_eq!(Readout::default().middle_after_stamp_us(), 0.0);
    }

    #[test]
    fn a_readout_that_is_not_a_number_of_milliseconds_in_range_is_refused() {
        for bad in [-1.0, 100.5, f64::NAN, f64::INFINITY, 1e300] {
            let e = Readout::top_to_bottom(bad).check().unwrap_err().to_string();
            assert!(e.contains("time_ms") && e.contains("0..=100"), "{e}");
        }
        for good in [0.0, 25.0, 100.0] {
            assert!(Readout::top_to_bottom(good).check().is_ok());
        }
    }

    #[test]
    fn a_steady_turn_gives_knots_turning_evenly_and_a_global_shutter_none() {
        let yaw = |dt: f64| {
            Euler::new(0.3 + 1.5 * dt * 1e-6, 0.1, 0.0)
                .matrix()
                .transpose()
        };
        assert!(ShutterTable::new(&Readout::default(), (640, 480), yaw).is_none());
        let t = ShutterTable::new(&Readout::top_to_bottom(25.0), (640, 480), yaw).unwrap();
        // 1.5 rad/s over 25 ms: 37.5 mrad from the first knot to the last, identity midway.
        let angle = |q: DQuat| q.to_axis_angle().1;
        assert!((angle(t.knots[0]) - 0.01875).abs() < 1e-9);
        assert!(angle(t.knots[KNOTS / 2]) < 1e-9);
        assert!((angle(t.at(DVec2::new(5.0, 479.5))) - 0.01875).abs() < 1e-9);
        // Between knots, the interpolated rotation is the turn at that row.
        let q = t.at(DVec2::new(100.0, 300.0));
        let want = 1.5 * Readout::top_to_bottom(25.0).point_us(DVec2::new(0.0, 300.0), (640, 480));
        assert!(
            (angle(q) - want.abs() * 1e-6).abs() < 1e-8,
            "{} vs {want}",
            angle(q)
        );
    }
}
