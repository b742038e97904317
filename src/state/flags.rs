//! The command line's way into the state: `key=value` lists that set a camera, an attitude, a
//! position or a tracked object (`--cam 0:yaw=45deg,fov=90deg`), the same fields a state file
//! names. Each flag changes only what it names; the caller validates the whole state after.

use super::view::Field;
use super::{Angles, State, Tracked};
use crate::modes::NotAMode;
use crate::units::{UnitError, parse_angle};

/// Why a flag was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FlagError {
    #[error("`{0}` is not key=value")]
    NotKeyValue(String),
    #[error("{key}=`{value}` is not a valid number here")]
    NotANumber { key: String, value: String },
    #[error("{key}=`{value}`: give a finite number")]
    NotFinite { key: String, value: String },
    #[error("`{key}` is not {what}")]
    UnknownKey { key: String, what: &'static str },
    #[error("`{flag}`: {why}")]
    Camera { flag: String, why: String },
    #[error(transparent)]
    Angle(#[from] UnitError),
    #[error(transparent)]
    Mode(#[from] NotAMode),
}

impl State {
    /// Applies `--cam 0:yaw=45deg,pitch=-30deg,fov=90deg,crop=1,lock=7`.
    pub fn apply_camera_flag(&mut self, flag: &str) -> Result<(), FlagError> {
        let refused = |why: String| FlagError::Camera {
            flag: flag.to_string(),
            why,
        };
        let (id, pairs) = flag
            .split_once(':')
            .ok_or_else(|| refused("expected N:key=value,...".into()))?;
        let id: usize = id
            .trim()
            .parse()
            .map_err(|_| refused(format!("camera id `{id}` is not a number")))?;
        let cameras = &mut self.settings.cameras;
        let last = cameras.len() - 1;
        let cam = cameras
            .get_mut(id)
            .ok_or_else(|| refused(format!("camera id {id} is outside 0..={last}")))?;
        for (key, value) in key_values(pairs)? {
            let Some(field) = Field::parse(key) else {
                return Err(unknown(
                    key,
                    "a camera field (yaw, pitch, roll, fov, zoom, crop, lock, control)",
                ));
            };
            let v = match field {
                _ if field.angle() => parse_angle(value)?,
                Field::Zoom => number::<i8>(key, value)? as f64,
                _ => number::<u8>(key, value)? as f64,
            };
            cam.put(field, v)?;
        }
        Ok(())
    }

    /// Applies `--attitude yaw=10deg,pitch=5deg,roll=20deg` (or `--mount ...`) to a triple.
    pub fn apply_angles(target: &mut Angles, flag: &str) -> Result<(), FlagError> {
        for (key, value) in key_values(flag)? {
            match key {
                "yaw" => target.yaw = parse_angle(value)?,
                "pitch" => target.pitch = parse_angle(value)?,
                "roll" => target.roll = parse_angle(value)?,
                _ => return Err(unknown(key, "an angle (yaw, pitch, roll)")),
            }
        }
        Ok(())
    }

    /// Applies `--position lat=58.0,lon=15.0,alt=150,rel=50`.
    pub fn apply_position(&mut self, flag: &str) -> Result<(), FlagError> {
        let p = &mut self.vehicle.position;
        for (key, value) in key_values(flag)? {
            match key {
                "lat" => p.lat = finite(key, value)?,
                "lon" => p.lon = finite(key, value)?,
                "alt" => p.alt = finite(key, value)?,
                "rel" | "relative_alt" => p.relative_alt = finite(key, value)?,
                _ => return Err(unknown(key, "a position field (lat, lon, alt, rel)")),
            }
        }
        Ok(())
    }

    /// Applies `--cam-sensor ae=0,target=100,exposure=5000,gain=1000` (CAM_SENSOR's fields:
    /// exposure in microseconds, gain in thousandths).
    pub fn apply_sensor(&mut self, flag: &str) -> Result<(), FlagError> {
        let s = &mut self.settings.sensor;
        for (key, value) in key_values(flag)? {
            match key {
                "ae" => s.ae = number::<u8>(key, value)? != 0,
                "target" | "target_brightness" => s.target_brightness = number(key, value)?,
                "exposure" | "exposure_us" => s.exposure_us = number(key, value)?,
                "gain" => s.gain = number(key, value)?,
                _ => {
                    return Err(unknown(key, "a sensor field (ae, target, exposure, gain)"));
                }
            }
        }
        Ok(())
    }

    /// Adds a tracked object from `--track yaw=10deg,pitch=-40deg,size=3deg,score=90`.
    pub fn add_tracked(&mut self, flag: &str) -> Result<(), FlagError> {
        let mut t = Tracked {
            id: self.tracked.len() as u32,
            ..Tracked::default()
        };
        for (key, value) in key_values(flag)? {
            match key {
                "yaw" => t.yaw = parse_angle(value)?,
                "pitch" => t.pitch = parse_angle(value)?,
                "size" => t.size = parse_angle(value)?,
                "score" => t.score = number(key, value)?,
                "id" => t.id = number(key, value)?,
                _ => {
                    return Err(unknown(
                        key,
                        "a tracked-object field (yaw, pitch, size, score, id)",
                    ));
                }
            }
        }
        self.tracked.push(t);
        Ok(())
    }
}

fn unknown(key: &str, what: &'static str) -> FlagError {
    FlagError::UnknownKey {
        key: key.to_string(),
        what,
    }
}

fn key_values(text: &str) -> Result<Vec<(&str, &str)>, FlagError> {
    text.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|kv| {
            kv.split_once('=')
                .map(|(k, v)| (k.trim(), v.trim()))
                .ok_or_else(|| FlagError::NotKeyValue(kv.to_string()))
        })
        .collect()
}

/// A number that is finite: NaN and the infinities are no place, height or size.
fn finite(key: &str, value: &str) -> Result<f64, FlagError> {
    let v: f64 = number(key, value)?;
    match v.is_finite() {
        true => Ok(v),
        false => Err(FlagError::NotFinite {
            key: key.to_string(),
            value: value.to_string(),
        }),
    }
}

fn number<T: std::str::FromStr>(key: &str, value: &str) -> Result<T, FlagError> {
    value.parse().map_err(|_| FlagError::NotANumber {
        key: key.to_string(),
        value: value.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_override_fields_and_reject_unknown_keys() {
        let mut s = State::default();
        s.apply_camera_flag("1:yaw=10deg,crop=2,lock=3").unwrap();
        let c = &s.settings.cameras[1];
        assert_eq!((c.crop().code(), c.locks().0), (2, 3));
        assert!(
            s.apply_camera_flag("4:yaw=0")
                .unwrap_err()
                .to_string()
                .contains("outside 0..=3")
        );
        assert!(
            s.apply_camera_flag("0:colour=red")
                .unwrap_err()
                .to_string()
                .contains("not a camera field")
        );
        State::apply_angles(&mut s.vehicle.attitude, "roll=20deg,pitch=0.1").unwrap();
        assert_eq!(s.vehicle.attitude.pitch, 0.1);
        s.apply_position("lat=1,lon=2,alt=30,rel=20").unwrap();
        assert_eq!(s.vehicle.position.relative_alt, 20.0);
        s.add_tracked("yaw=5deg,size=2deg").unwrap();
        assert_eq!(s.tracked.len(), 1);
    }

    #[test]
    fn sensor_flags_set_cam_sensors_fields_and_the_state_refuses_what_it_cannot_take() {
        let cal = include_str!("../../lens-cal/lens.cal");
        let cal = crate::lens::LensCal::parse(std::path::Path::new("lens.cal"), cal).unwrap();
        let lenses = crate::lens::Lenses::new(&cal);
        let mut s = State::default();
        s.apply_sensor("ae=0,target=100,exposure=5000,gain=2000")
            .unwrap();
        let sensor = &s.settings.sensor;
        assert_eq!(
            (
                sensor.ae,
                sensor.target_brightness,
                sensor.exposure_us,
                sensor.gain
            ),
            (false, 100, 5000, 2000)
        );
        assert!(s.validate(&lenses).is_ok());
        assert!(s.apply_sensor("iso=100").is_err());
        for (flag, says) in [
            ("exposure=0", "exposure 0"),
            ("exposure=40000", "frame time at 30 fps"),
            ("gain=60000", "gain 60000"),
            ("target=255", "target brightness 255"),
        ] {
            let mut bad = s.clone();
            bad.apply_sensor(flag).unwrap();
            let e = bad.validate(&lenses).unwrap_err().to_string();
            assert!(e.contains(says), "{flag}: {e}");
        }
    }

    #[test]
    fn a_position_that_is_no_number_is_refused_and_the_state_kept() {
        let mut s = State::default();
        for flag in ["alt=nan", "rel=inf", "lat=-inf", "lon=NaN"] {
            let e = s.apply_position(flag).unwrap_err().to_string();
            assert!(e.contains("give a finite number"), "{flag}: {e}");
        }
        assert_eq!(s, State::default());
    }
}
