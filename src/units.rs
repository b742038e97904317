//! Human-facing text: angles written as radians or with a `deg` suffix, lengths, `WxH` sizes, and the
//! line a value stands on in a file. Used by lens.cal, state files and the command line alike.

use serde::{Deserialize, Deserializer};

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
    fn sizes_read_as_width_x_height() {
        assert_eq!(parse_size("1920x1080").unwrap(), (1920, 1080));
        assert!(parse_size("1920").is_err());
        assert!(parse_size("0x10").is_err());
    }
}
