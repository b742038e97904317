//! A view's metadata as one ST 0601 packet: tag 2 (the frame's capture time) first, the
//! platform's pose, the sensor's position and pointing, the view's fields of view, its frame
//! centre and the corners of its footprint, tag 65 (the set's version), the tracked objects
//! (tag 74, ST 0903) and tag 1 (the checksum) last. Every value is mapped linearly onto its integer as the standard says;
//! an item the view does not have (a corner above the horizon) is left out, never made up.

use super::LocalSet;
use super::view::ViewMetadata;

/// The UAS Datalink Local Set's universal key.
pub const UAS_LS_KEY: [u8; 16] = [
    0x06, 0x0e, 0x2b, 0x34, 0x02, 0x0b, 0x01, 0x01, 0x0e, 0x01, 0x03, 0x01, 0x01, 0x00, 0x00, 0x00,
];
/// The ST 0601 revision the packets follow (tag 65).
pub const VERSION: u8 = 19;
/// What tag 12 says of the coordinates.
const COORDINATES: &str = "Geodetic WGS84";

/// `v` in `min..=max` onto an unsigned integer of `n` bytes, 0 to its largest value.
fn unsigned(v: f64, (min, max): (f64, f64), n: usize) -> Vec<u8> {
    let top = (1u64 << (8 * n)) - 1;
    let code = ((v.clamp(min, max) - min) / (max - min) * top as f64).round() as u64;
    code.to_be_bytes()[8 - n..].to_vec()
}

/// `v` in `-range..=range` onto a signed integer of `n` bytes (±its largest value); out of
/// range, or not a number, the standard's error code (the lowest value, `0x80…`).
fn signed(v: f64, range: f64, n: usize) -> Vec<u8> {
    let top = (1i64 << (8 * n - 1)) - 1;
    let code = match v.is_finite() && v.abs() <= range {
        true => (v / range * top as f64).round() as i64,
        false => -top - 1,
    };
    code.to_be_bytes()[8 - n..].to_vec()
}

/// An angle in degrees wrapped onto 0..360.
fn turn(deg: f64) -> f64 {
    deg.rem_euclid(360.0)
}

/// Altitudes (MSL) and elevations: -900 to 19,000 m in two bytes.
fn altitude(m: f64) -> Vec<u8> {
    unsigned(m, (-900.0, 19_000.0), 2)
}

impl ViewMetadata {
    /// The packet, tags in ascending order between tag 2 and tags 65 and 1.
    pub fn packet(&self) -> Vec<u8> {
        let mut set = LocalSet::default();
        set.push(2, &self.time_us.to_be_bytes());
        set.push(5, &unsigned(turn(self.platform.yaw), (0.0, 360.0), 2));
        // Pitch and roll beyond tags 6 and 7's ranges go in the full-range tags 90 and 91
        // instead (below): a reader that knows only 6 and 7 sees them missing, not wrong.
        if self.platform.pitch.abs() <= 20.0 {
            set.push(6, &signed(self.platform.pitch, 20.0, 2));
        }
        if self.platform.roll.abs() <= 50.0 {
            set.push(7, &signed(self.platform.roll, 50.0, 2));
        }
        set.push(11, self.source.as_bytes());
        set.push(12, COORDINATES.as_bytes());
        set.push(13, &signed(self.sensor.lat, 90.0, 4));
        set.push(14, &signed(self.sensor.lon, 180.0, 4));
        set.push(15, &altitude(self.sensor.alt));
        set.push(16, &unsigned(self.fov.0, (0.0, 180.0), 2));
        set.push(17, &unsigned(self.fov.1, (0.0, 180.0), 2));
        set.push(18, &unsigned(turn(self.relative.yaw), (0.0, 360.0), 4));
        set.push(19, &signed(self.relative.pitch, 180.0, 4));
        set.push(20, &unsigned(turn(self.relative.roll), (0.0, 360.0), 4));
        if let Some(centre) = &self.centre {
            set.push(21, &unsigned(centre.range, (0.0, 5e6), 4));
            set.push(23, &signed(centre.point.lat, 90.0, 4));
            set.push(24, &signed(centre.point.lon, 180.0, 4));
            set.push(25, &altitude(centre.point.alt));
        }
        set.push(65, &[VERSION]);
        if let Some(objects) = &self.objects {
            set.push(74, &objects.local_set(self.time_us, &self.source, self.fov));
        }
        // The corners, full range (82 to 89: latitude then longitude, from the top left
        // clockwise): only where all four meet the ground, as readers draw a quadrilateral.
        if let Some(corners) = &self.corners {
            for (k, c) in corners.iter().enumerate() {
                set.push(82 + 2 * k as u32, &signed(c.lat, 90.0, 4));
                set.push(83 + 2 * k as u32, &signed(c.lon, 180.0, 4));
            }
        }
        if self.platform.pitch.abs() > 20.0 {
            set.push(90, &signed(self.platform.pitch, 90.0, 4));
        }
        if self.platform.roll.abs() > 50.0 {
            set.push(91, &signed(self.platform.roll, 90.0, 4));
        }
        set.packet(&UAS_LS_KEY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_map_as_the_standard_says_and_out_of_range_is_the_error_code() {
        assert_eq!(unsigned(360.0, (0.0, 360.0), 2), [0xff, 0xff]);
        assert_eq!(unsigned(180.0, (0.0, 360.0), 2), [0x80, 0x00]);
        assert_eq!(signed(20.0, 20.0, 2), [0x7f, 0xff]);
        assert_eq!(signed(-20.0, 20.0, 2), [0x80, 0x01]);
        assert_eq!(signed(20.5, 20.0, 2), [0x80, 0x00], "out of range");
        assert_eq!(signed(f64::NAN, 90.0, 4), [0x80, 0, 0, 0]);
        assert_eq!(altitude(-900.0), [0, 0]);
        assert_eq!(turn(-90.0), 270.0);
    }
}
