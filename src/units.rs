//! Human-facing text: angles written as radians or with a `deg` suffix, lengths, `WxH` sizes, and the
//! line a value stands on in a file. Used by lens.cal, state files and the command line alike.

use serde::{Deserialize, Deserializer};
use std::ops::RangeInclusive;
use std::time::Duration;

/// Why a value written by a person was not understood.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UnitError {
    #[error("`{0}` is not an angle (radians, or degrees with a `deg` suffix)")]
    NotAnAngle(String),
    #[error("`{0}` is not a finite angle")]
    Infinite(String),
    #[error("`{0}` is not a size like 1920x1080")]
    NotASize(String),
    #[error("`{0}`: width and height must be positive")]
    EmptySize(String),
    #[error("`{0}` is not a length (metres, or with a `mm`, `cm` or `m` suffix)")]
    NotALength(String),
    #[error("`{0}` is not a number of seconds")]
    NotATime(String),
    #[error("{0}")]
    TimeOutOfRange(String),
    #[error("give a whole number from {1} to {2}, not `{0}`")]
    NotWhole(String, i64, i64),
}

/// A whole number within `range` (a flag's value): `nan`, `2.5` or `0` for 1..=240 are said
/// so, in those words.
pub fn whole<T: TryFrom<i64>>(text: &str, range: RangeInclusive<i64>) -> Result<T, UnitError> {
    let bad = || UnitError::NotWhole(text.to_string(), *range.start(), *range.end());
    let n: i64 = text.trim().parse().map_err(|_| bad())?;
    if !range.contains(&n) {
        return Err(bad());
    }
    T::try_from(n).map_err(|_| bad())
}

/// Parses `0.5`, `0.5rad` or `30deg` (spaces allowed before the unit) into radians.
pub fn parse_angle(text: &str) -> Result<f64, UnitError> {
    let t = text.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("deg") {
        (n, std::f64::consts::PI / 180.0)
    } else if let Some(n) = t.strip_suffix('°') {
        (n, std::f64::consts::PI / 180.0)
    } else if let Some(n) = t.strip_suffix("rad") {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| UnitError::NotAnAngle(text.to_string()))?;
    if !value.is_finite() {
        return Err(UnitError::Infinite(text.to_string()));
    }
    Ok(value * scale)
}

/// Parses `88mm`, `8.8cm`, `0.088m` or `0.088` into metres: finite and positive.
pub fn parse_length(text: &str) -> Result<f64, UnitError> {
    let t = text.trim();
    let (number, scale) = [("mm", 1e-3), ("cm", 1e-2), ("m", 1.0)]
        .iter()
        .find_map(|(unit, scale)| t.strip_suffix(unit).map(|n| (n, *scale)))
        .unwrap_or((t, 1.0));
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(UnitError::NotALength(text.to_string())),
    }
}

/// Parses `1920x1080`.
pub fn parse_size(text: &str) -> Result<(u32, u32), UnitError> {
    let err = || UnitError::NotASize(text.to_string());
    let (w, h) = text.trim().split_once(['x', 'X']).ok_or_else(err)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| err())?,
        h.trim().parse().map_err(|_| err())?,
    );
    if w == 0 || h == 0 {
        return Err(UnitError::EmptySize(text.to_string()));
    }
    Ok((w, h))
}

/// A time in seconds that its field does not take: not a number, infinite, or outside the
/// field's range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{} s is not a time from {} to {} s", short(*value), short(*range.start()), short(*range.end()))]
pub struct BadSeconds {
    pub value: f64,
    pub range: RangeInclusive<f64>,
}

/// A number as people read it: `1e30`, not thirty-one digits.
fn short(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-3..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Seconds as a [`Duration`], checked against the range the field takes. Every number that
/// comes from outside (a flag, a file, a protocol, MAVLink, HTTP) and becomes a time goes
/// through here: `Duration::from_secs_f64` panics on NaN, on negatives and past 2^64 s.
pub fn seconds(value: f64, range: RangeInclusive<f64>) -> Result<Duration, BadSeconds> {
    let bad = || BadSeconds {
        value,
        range: range.clone(),
    };
    if !range.contains(&value) {
        return Err(bad());
    }
    Duration::try_from_secs_f64(value.max(0.0)).map_err(|_| bad())
}

/// Parses a number of seconds within `range`, for a flag: `--timeout 2.5`.
pub fn parse_seconds(text: &str, range: RangeInclusive<f64>) -> Result<Duration, UnitError> {
    let value: f64 = text
        .trim()
        .trim_end_matches('s')
        .trim()
        .parse()
        .map_err(|_| UnitError::NotATime(text.to_string()))?;
    seconds(value, range).map_err(|e| UnitError::TimeOutOfRange(e.to_string()))
}

/// The 1-based line of byte `offset` in `text`, for `file:line` messages.
pub fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Formats radians for people: degrees with two decimals.
pub fn deg(radians: f64) -> String {
    format!("{:.2}deg", radians.to_degrees())
}

/// An angle in radians that deserializes from a number (radians) or a string (`"30deg"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
#[serde(transparent)]
pub struct Angle(pub f64);

impl<'de> Deserialize<'de> for Angle {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Int(i64),
            Text(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(v) => Ok(Angle(v)),
            Raw::Int(v) => Ok(Angle(v as f64)),
            Raw::Text(t) => parse_angle(&t).map(Angle).map_err(serde::de::Error::custom),
        }
    }
}

/// `deserialize_with` for an f64 angle written as radians or `"30deg"`.
pub fn de_angle<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Angle::deserialize(d).map(|a| a.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_read_as_radians_or_degrees() {
        assert_eq!(parse_angle("0.5").unwrap(), 0.5);
        assert_eq!(parse_angle("0.5rad").unwrap(), 0.5);
        assert!((parse_angle("90deg").unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert!((parse_angle("-30 deg").unwrap() + 30f64.to_radians()).abs() < 1e-15);
        assert!(parse_angle("ninety").is_err());
        assert!(parse_angle("nan").is_err());
    }

    #[test]
    fn a_whole_number_in_its_range_or_what_was_wrong_in_words() {
        assert_eq!(whole::<u32>(" 30 ", 1..=240), Ok(30));
        for bad in ["nan", "2.5", "0", "241", "-1", ""] {
            let e = whole::<u32>(bad, 1..=240).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("give a whole number from 1 to 240, not `{bad}`")
            );
        }
    }

    #[test]
    fn seconds_outside_their_range_are_refused_never_a_panic() {
        let hostile = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1.0,
            -f64::MIN_POSITIVE,
            1e30,
            f64::MAX,
            1e300,
            18446744073709551616.0,
        ];
        for range in [0.0..=3600.0, 0.1..=86_400.0, 1e-3..=1e9] {
            for v in hostile {
                assert!(seconds(v, range.clone()).is_err(), "{v} in {range:?}");
            }
            let (lo, hi) = (*range.start(), *range.end());
            assert_eq!(seconds(lo, range.clone()).unwrap().as_secs_f64(), lo);
            assert!((seconds(hi, range.clone()).unwrap().as_secs_f64() - hi).abs() < 1e-6);
        }
        // Zero, negative zero and a subnormal are times where 0 is in the range.
        for v in [0.0, -0.0, f64::from_bits(1)] {
            assert!(seconds(v, 0.0..=1.0).unwrap() < Duration::from_nanos(1));
        }
        assert_eq!(
            parse_seconds("2.5", 0.0..=10.0).unwrap(),
            Duration::from_millis(2500)
        );
        assert_eq!(
            parse_seconds("3 s", 0.0..=10.0).unwrap(),
            Duration::from_secs(3)
        );
        for t in ["1e30", "inf", "nan", "-1", "soon", ""] {
            let e = parse_seconds(t, 0.0..=10.0).unwrap_err().to_string();
            let said = e.to_lowercase().contains(t) || e.contains("seconds");
            assert!(said, "{t}: {e}");
        }
    }

    #[test]
    fn sizes_read_as_width_x_height() {
        assert_eq!(parse_size("1920x1080").unwrap(), (1920, 1080));
        assert!(parse_size("1920").is_err());
        assert!(parse_size("0x10").is_err());
    }
}
