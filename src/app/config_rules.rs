//! The serve configuration's part of the one table of rules (the state's part is
//! [`crate::state::rules`]): every number the configuration holds, with its range and unit.
//! [`Config::check`] refuses by it, naming the key and the range; a test fails when a number
//! of the configuration has no rule here.

use super::{Config, ConfigError};
use crate::geometry::shutter::MAX_READOUT_MS;
use crate::state::{MAX_CAMERAS, MAX_OUTPUT, MIN_OUTPUT};
use crate::stream::encoder::BITRATE_KBPS;
use crate::thermal::{KELVIN_OFFSET, KELVIN_PER_COUNT};
use crate::units::deg;
use std::f64::consts::{FRAC_PI_2, PI};

/// One number of the configuration: its key (`demo.fps`), range and unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigRule {
    pub key: &'static str,
    pub lo: f64,
    pub hi: f64,
    pub unit: &'static str,
}

const fn rule(key: &'static str, lo: f64, hi: f64, unit: &'static str) -> ConfigRule {
    ConfigRule { key, lo, hi, unit }
}

/// Every number of the serve configuration.
#[rustfmt::skip]
pub const CONFIG_RULES: &[ConfigRule] = &[
    rule("source_fps", 1.0, 240.0, "fps"),
    rule("demo.width", 64.0, 7680.0, "px"),
    rule("demo.height", 64.0, 4320.0, "px"),
    rule("demo.fps", 1.0, 120.0, "fps"),
    rule("demo.readout_ms", 0.0, MAX_READOUT_MS, "ms"),
    // Port 0: the system picks a free one (what the tests use).
    rule("rtsp.port", 0.0, 65535.0, ""),
    rule("encoder.bitrate_kbps", BITRATE_KBPS.0 as f64, BITRATE_KBPS.1 as f64, "kbit/s"),
    rule("encoder.key_interval_s", 0.1, 60.0, "s"),
    rule("capture.min_free_mb", 0.0, 1e12, "MB"),
    rule("mavlink.system_id", 1.0, 255.0, ""),
    rule("mavlink.attitude_hz", 0.1, 500.0, "Hz"),
    rule("mavlink.position_hz", 0.1, 500.0, "Hz"),
    rule("cameras.width", MIN_OUTPUT.0 as f64, MAX_OUTPUT.0 as f64, "px"),
    rule("cameras.height", MIN_OUTPUT.1 as f64, MAX_OUTPUT.1 as f64, "px"),
    rule("detection.scan_hz", 0.5, 30.0, "Hz"),
    rule("detection.crop_hz", 0.0, 30.0, "Hz"),
    rule("detection.threads", 1.0, 16.0, ""),
    rule("klv_camera", 0.0, (MAX_CAMERAS - 1) as f64, ""),
    rule("payload.view", 0.0, (MAX_CAMERAS - 1) as f64, ""),
    rule("health_interval_s", 0.0, 3600.0, "s"),
    rule("readout.time_ms", 0.0, MAX_READOUT_MS, "ms"),
    rule("thermal.fps", 1.0, 240.0, "fps"),
    rule("thermal.kelvin_per_count", KELVIN_PER_COUNT.0, KELVIN_PER_COUNT.1, "K"),
    rule("thermal.kelvin_offset", KELVIN_OFFSET.0, KELVIN_OFFSET.1, "K"),
    rule("thermal.mount.yaw", -PI, PI, "rad"),
    rule("thermal.mount.pitch", -FRAC_PI_2, FRAC_PI_2, "rad"),
    rule("thermal.mount.roll", -PI, PI, "rad"),
];

impl Config {
    /// Every number the configuration holds, under its key in [`CONFIG_RULES`].
    pub fn values(&self) -> Vec<(&'static str, f64)> {
        let mut out = vec![
            ("source_fps", self.source_fps as f64),
            ("demo.width", self.demo.width as f64),
            ("demo.height", self.demo.height as f64),
            ("demo.fps", self.demo.fps as f64),
            ("demo.readout_ms", self.demo.readout_ms),
            ("rtsp.port", self.rtsp.port as f64),
            ("encoder.bitrate_kbps", self.encoder.bitrate_kbps as f64),
            ("encoder.key_interval_s", self.encoder.key_interval_s),
            ("capture.min_free_mb", self.capture.min_free_mb as f64),
            ("mavlink.attitude_hz", self.mavlink.attitude_hz),
            ("mavlink.position_hz", self.mavlink.position_hz),
            ("cameras.width", self.cameras.width as f64),
            ("cameras.height", self.cameras.height as f64),
            ("detection.scan_hz", self.detection.scan_hz),
            ("detection.crop_hz", self.detection.crop_hz),
            ("detection.threads", self.detection.threads as f64),
            ("klv_camera", self.klv_camera as f64),
            ("payload.view", self.payload.view as f64),
            ("health_interval_s", self.health_interval_s),
            ("readout.time_ms", self.readout.time_ms),
            ("thermal.fps", self.thermal.fps as f64),
            ("thermal.kelvin_per_count", self.thermal.kelvin_per_count),
            ("thermal.kelvin_offset", self.thermal.kelvin_offset),
            ("thermal.mount.yaw", self.thermal.mount.yaw.0),
            ("thermal.mount.pitch", self.thermal.mount.pitch.0),
            ("thermal.mount.roll", self.thermal.mount.roll.0),
        ];
        if let Some(id) = self.mavlink.system_id {
            out.push(("mavlink.system_id", id as f64));
        }
        out
    }

    /// Every number against its rule: "demo fps 200 is outside 1..=120 fps"; an angle in
    /// degrees, as people write them ("thermal mount pitch 95.00deg is outside
    /// -90.00deg..=90.00deg").
    pub(super) fn check_ranges(&self) -> Result<(), ConfigError> {
        for (key, v) in self.values() {
            let Some(r) = CONFIG_RULES.iter().find(|r| r.key == key) else {
                return Err(ConfigError::Range(format!("{key}: no rule (a bug)")));
            };
            if !(v >= r.lo && v <= r.hi) {
                let unit = match r.unit {
                    "" => String::new(),
                    u => format!(" {u}"),
                };
                let key = key.replace('.', " ");
                let message = match r.unit {
                    "rad" => format!("{key} {} is outside {}..={}", deg(v), deg(r.lo), deg(r.hi)),
                    _ => format!("{key} {v} is outside {}..={}{unit}", r.lo, r.hi),
                };
                return Err(ConfigError::Range(message));
            }
        }
        Ok(())
    }
}
