//! A V4L2 camera's exposure controls: which of the controls a device reports carry
//! CAM_SENSOR's exposure, gain and auto exposure ([`Mapping`], from the controls alone, so it
//! is tested against a real camera's list), and the device they are set on ([`Device`]: the
//! camera's node opened a second time beside the GStreamer source, as `v4l2-ctl` does).
//!
//! The kernel's interface is four ioctls on stable structures (`linux/videodev2.h`); they are
//! written out here rather than taken from the `v4l` crate, whose bindings are generated
//! with libclang at build time.

mod device;

pub use device::{Device, DeviceError};

use super::{Limits, Setting, UNITY_GAIN};

pub const CID_GAIN: u32 = 0x0098_0913;
pub const CID_AUTOGAIN: u32 = 0x0098_0912;
pub const CID_EXPOSURE_AUTO: u32 = 0x009a_0901;
pub const CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
pub const CID_EXPOSURE_AUTO_PRIORITY: u32 = 0x009a_0903;

/// V4L2_EXPOSURE_AUTO's menu: the camera decides all, manual, or exposure time automatic
/// with a fixed iris (what UVC cameras call auto).
const AUTO: i64 = 0;
const MANUAL: i64 = 1;
const APERTURE_PRIORITY: i64 = 3;

/// V4L2_CID_EXPOSURE_ABSOLUTE counts hundreds of microseconds.
const ABSOLUTE_UNIT_US: i64 = 100;
/// CAM_SENSOR's gain range, spread over the device's own (its gain has no unit).
const SEED_GAIN: (u32, u32) = (UNITY_GAIN, 50_000);

/// One control as the device reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct Control {
    pub id: u32,
    pub name: String,
    pub min: i64,
    pub max: i64,
    pub step: i64,
    pub default: i64,
    /// For menus, the items the device offers.
    pub menu: Vec<i64>,
}

impl Control {
    fn clamp(&self, v: i64) -> i64 {
        let step = self.step.max(1);
        let v = v.clamp(self.min, self.max);
        self.min + (v - self.min) / step * step
    }
}

/// Which controls carry CAM_SENSOR, for one device.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mapping {
    pub exposure: Option<Control>,
    pub gain: Option<Control>,
    /// The auto exposure menu, with the item that turns it on (None: only manual).
    pub auto: Option<(Control, Option<i64>)>,
    pub autogain: Option<Control>,
    /// Whether the camera may stretch frames for exposure (turned off: the frame rate holds).
    pub auto_priority: Option<Control>,
}

impl Mapping {
    pub fn new(controls: &[Control]) -> Mapping {
        let find = |id| controls.iter().find(|c| c.id == id).cloned();
        let auto = find(CID_EXPOSURE_AUTO).map(|c| {
            let on = [APERTURE_PRIORITY, AUTO]
                .into_iter()
                .find(|v| c.menu.contains(v));
            (c, on)
        });
        Mapping {
            exposure: find(CID_EXPOSURE_ABSOLUTE),
            gain: find(CID_GAIN),
            auto,
            autogain: find(CID_AUTOGAIN),
            auto_priority: find(CID_EXPOSURE_AUTO_PRIORITY),
        }
    }

    /// Whether the camera has an auto exposure of its own.
    pub fn has_auto(&self) -> bool {
        self.auto.as_ref().is_some_and(|(_, on)| on.is_some())
    }

    /// What can be set, in CAM_SENSOR's units, the exposure no longer than `frame_us`.
    pub fn limits(&self, frame_us: u32) -> Limits {
        let exposure_us = self.exposure.as_ref().map_or((1, frame_us), |c| {
            let lo = (c.min.max(1) * ABSOLUTE_UNIT_US) as u32;
            (
                lo,
                ((c.max * ABSOLUTE_UNIT_US) as u32).min(frame_us).max(lo),
            )
        });
        let gain = if self.gain.is_some() {
            SEED_GAIN
        } else {
            (UNITY_GAIN, UNITY_GAIN)
        };
        Limits { exposure_us, gain }
    }

    /// The control values for a manual setting, clamped to the device's ranges.
    pub fn manual(&self, s: Setting) -> Vec<(u32, i64)> {
        let mut out = vec![];
        if let Some((c, _)) = &self.auto
            && c.menu.contains(&MANUAL)
        {
            out.push((c.id, MANUAL));
        }
        if let Some(c) = &self.autogain {
            out.push((c.id, 0));
        }
        if let Some(c) = &self.auto_priority {
            out.push((c.id, 0));
        }
        if let Some(c) = &self.exposure {
            let units = (s.exposure_us as i64 + ABSOLUTE_UNIT_US / 2) / ABSOLUTE_UNIT_US;
            out.push((c.id, c.clamp(units)));
        }
        if let Some(c) = &self.gain {
            out.push((c.id, c.clamp(gain_to_device(c, s.gain))));
        }
        out
    }

    /// The control values that hand exposure to the camera's own auto exposure.
    pub fn camera_auto(&self) -> Vec<(u32, i64)> {
        let mut out = vec![];
        if let Some((c, Some(on))) = &self.auto {
            out.push((c.id, *on));
        }
        if let Some(c) = &self.autogain {
            out.push((c.id, 1));
        }
        if let Some(c) = &self.auto_priority {
            out.push((c.id, 0));
        }
        out
    }

    /// The setting the device's exposure and gain values stand for (what GET reports).
    pub fn setting(&self, exposure: Option<i64>, gain: Option<i64>) -> Option<Setting> {
        let exposure_us = (exposure? * ABSOLUTE_UNIT_US).clamp(1, u32::MAX as i64) as u32;
        let gain = match (&self.gain, gain) {
            (Some(c), Some(v)) => gain_from_device(c, v),
            _ => UNITY_GAIN,
        };
        Some(Setting { exposure_us, gain })
    }
}

/// CAM_SENSOR's 1000..=50000 laid linearly over the device's min..=max.
fn gain_to_device(c: &Control, gain: u32) -> i64 {
    let (lo, hi) = SEED_GAIN;
    let f = (gain.clamp(lo, hi) - lo) as f64 / (hi - lo) as f64;
    c.min + (f * (c.max - c.min) as f64).round() as i64
}

fn gain_from_device(c: &Control, v: i64) -> u32 {
    let (lo, hi) = SEED_GAIN;
    let f = (v - c.min) as f64 / (c.max - c.min).max(1) as f64;
    lo + (f.clamp(0.0, 1.0) * (hi - lo) as f64).round() as u32
}

/// The controls in a `v4l2-ctl --list-ctrls-menus` listing (the form users send and tests
/// keep): one line per control, `name 0xID (type) : min=.. max=.. step=.. default=..`,
/// menu items indented below it.
pub fn parse_listing(text: &str) -> Vec<Control> {
    let mut out: Vec<Control> = vec![];
    for line in text.lines() {
        let t = line.trim();
        if let Some((item, _)) = t.split_once(": ")
            && let Ok(v) = item.parse::<i64>()
        {
            if let Some(c) = out.last_mut() {
                c.menu.push(v);
            }
            continue;
        }
        let mut words = t.split_whitespace();
        let (Some(name), Some(id)) = (words.next(), words.next()) else {
            continue;
        };
        let Some(id) = id
            .strip_prefix("0x")
            .and_then(|h| u32::from_str_radix(h, 16).ok())
        else {
            continue;
        };
        let field = |key: &str| {
            t.split_whitespace()
                .find_map(|w| w.strip_prefix(key)?.strip_prefix('=')?.parse().ok())
        };
        let bool_like = t.contains("(bool)");
        out.push(Control {
            id,
            name: name.to_string(),
            min: field("min").unwrap_or(0),
            max: field("max").unwrap_or(if bool_like { 1 } else { 0 }),
            step: field("step").unwrap_or(1),
            default: field("default").unwrap_or(0),
            menu: vec![],
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const C920: &str = include_str!("../../../tests/data/v4l2/logitech-c920.txt");

    #[test]
    fn a_uvc_cameras_listing_parses_into_its_controls() {
        let controls = parse_listing(C920);
        assert_eq!(controls.len(), 17);
        let auto = controls.iter().find(|c| c.id == CID_EXPOSURE_AUTO).unwrap();
        assert_eq!(
            (auto.name.as_str(), auto.menu.as_slice()),
            ("exposure_auto", &[1, 3][..])
        );
        let exposure = controls
            .iter()
            .find(|c| c.id == CID_EXPOSURE_ABSOLUTE)
            .unwrap();
        assert_eq!(
            (exposure.min, exposure.max, exposure.default),
            (3, 2047, 250)
        );
        let pan = controls.iter().find(|c| c.name == "pan_absolute").unwrap();
        assert_eq!((pan.min, pan.step), (-36000, 3600));
        let priority = controls
            .iter()
            .find(|c| c.id == CID_EXPOSURE_AUTO_PRIORITY)
            .unwrap();
        assert_eq!((priority.min, priority.max), (0, 1));
    }

    #[test]
    fn cam_sensor_maps_onto_a_uvc_cameras_controls() {
        let m = Mapping::new(&parse_listing(C920));
        assert!(
            m.has_auto(),
            "aperture priority is the UVC camera's auto exposure"
        );
        // 30 fps: exposure 300 µs..33.3 ms (the device goes to 204.7 ms), gain over 0..=255.
        assert_eq!(
            m.limits(33_333),
            Limits {
                exposure_us: (300, 33_333),
                gain: (1000, 50_000)
            }
        );
        let set = m.manual(Setting {
            exposure_us: 8_000,
            gain: 25_500,
        });
        assert_eq!(
            set,
            vec![
                (CID_EXPOSURE_AUTO, MANUAL),
                (CID_EXPOSURE_AUTO_PRIORITY, 0),
                (CID_EXPOSURE_ABSOLUTE, 80),
                (CID_GAIN, 128),
            ]
        );
        // Out of the device's range: clamped to it.
        let set = m.manual(Setting {
            exposure_us: 40,
            gain: 50_000,
        });
        assert_eq!(set[2..], [(CID_EXPOSURE_ABSOLUTE, 3), (CID_GAIN, 255)]);
        assert_eq!(
            m.camera_auto(),
            vec![
                (CID_EXPOSURE_AUTO, APERTURE_PRIORITY),
                (CID_EXPOSURE_AUTO_PRIORITY, 0)
            ]
        );
        // Read back: 80 × 100 µs and the middle of the gain range.
        assert_eq!(
            m.setting(Some(80), Some(128)),
            Some(Setting {
                exposure_us: 8000,
                gain: 25_596
            })
        );
    }

    #[test]
    fn a_camera_without_auto_exposure_or_gain_says_so() {
        let only_manual: Vec<Control> = parse_listing(C920)
            .into_iter()
            .filter(|c| c.id != CID_GAIN)
            .map(|mut c| {
                c.menu.retain(|&v| v == MANUAL);
                c
            })
            .collect();
        let m = Mapping::new(&only_manual);
        assert!(!m.has_auto());
        assert_eq!(m.limits(33_333).gain, (1000, 1000));
        assert!(
            m.camera_auto()
                .iter()
                .all(|&(id, _)| id != CID_EXPOSURE_AUTO)
        );
        assert_eq!(Mapping::new(&[]), Mapping::default());
    }
}
