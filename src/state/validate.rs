//! The one check every way into the state goes through (state files, flags, the control
//! protocol, and what comes later): every field against the range the protocol allows.

use super::{State, rules};
use crate::geometry::view::{clamp_fov, control, crop, fov_range};
use crate::lens::Lenses;

/// Why a state is refused: the field, its value and the range it must lie in.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Invalid(pub String);

fn invalid<T>(message: String) -> Result<T, Invalid> {
    Err(Invalid(message))
}

impl State {
    /// Rounds an odd output width or height down to even, as every entry does (flags, state
    /// files, the protocol's VIDEO_OUTPUT): 4:2:0 video has no odd sizes.
    pub fn even_output(&mut self) {
        let o = &mut self.output;
        let even = (o.width & !1, o.height & !1);
        if even != (o.width, o.height) {
            tracing::info!(
                "output size {}x{} rounded down to {}x{} (4:2:0 video needs even sizes)",
                o.width,
                o.height,
                even.0,
                even.1
            );
            (o.width, o.height) = even;
        }
    }

    /// The one check of a whole state, whichever way it came in: every field against the
    /// range the protocol allows, and the lens and the sensor crop against lens.cal.
    pub fn validate(&self, lenses: &Lenses) -> Result<(), Invalid> {
        self.validate_fields()?;
        let Some(lens) = lenses.get(self.lens) else {
            return invalid(format!("lens_id {} is not in lens.cal", self.lens));
        };
        if let Some([x, y, w, h]) = self.sensor.roi {
            let (cw, ch) = (lens.width, lens.height);
            let fits = w > 0
                && h > 0
                && x.checked_add(w).is_some_and(|r| r <= cw)
                && y.checked_add(h).is_some_and(|b| b <= ch);
            if !fits {
                return invalid(format!(
                    "sensor crop {w}x{h} at {x},{y} does not fit the lens's {cw}x{ch} \
                     calibration frame"
                ));
            }
        }
        Ok(())
    }

    /// Every field against its rule ([`rules::RULES`], what the protocol takes unchanged),
    /// and the bounds that join fields (what can be checked without lens.cal;
    /// [`State::validate`] checks the rest).
    pub fn validate_fields(&self) -> Result<(), Invalid> {
        for (label, key, v) in self.values() {
            let Some(rule) = rules::of_key(key) else {
                return invalid(format!("{label}: no rule for `{key}` (a bug)"));
            };
            if !rule.holds(v) {
                let also = match rule.also {
                    "" => String::new(),
                    a => format!(", and {a}"),
                };
                return invalid(format!(
                    "{label} {} is outside {}{also}",
                    num(v),
                    rule.range()
                ));
            }
        }
        let o = &self.output;
        if o.width % 2 == 1 || o.height % 2 == 1 {
            return invalid(format!(
                "output size {}x{} is odd; 4:2:0 video needs even sizes",
                o.width, o.height
            ));
        }
        for (i, c) in self.cameras.iter().enumerate() {
            if clamp_fov(c.fov, c.crop) != c.fov && c.crop <= crop::DEBUG {
                let (lo, hi) = fov_range(c.crop);
                return invalid(format!(
                    "camera {i}: fov {:.3} rad is outside {lo}..={hi:.3} for crop mode {}",
                    c.fov, c.crop
                ));
            }
            if c.control == control::COORDINATE && c.target.is_none() {
                return invalid(format!(
                    "camera {i}: control mode 2 needs a target (lat, lon, alt)"
                ));
            }
        }
        let s = &self.sensor;
        let longest = s.longest_exposure_us();
        if s.exposure_us > longest {
            return invalid(format!(
                "sensor exposure {} µs is outside 1..={longest} (the frame time at {} fps)",
                s.exposure_us, s.fps
            ));
        }
        Ok(())
    }

    /// Every number the state holds: what it is to a reader, its key in [`rules::RULES`],
    /// its value.
    pub fn values(&self) -> Vec<(String, &'static str, f64)> {
        let mut out: Vec<(String, &'static str, f64)> = vec![];
        let mut put = |label: String, key: &'static str, v: f64| out.push((label, key, v));
        let o = &self.output;
        put("output width".into(), "output.width", o.width as f64);
        put("output height".into(), "output.height", o.height as f64);
        put("output fps".into(), "output.fps", o.fps as f64);
        put("output layout".into(), "output.layout", o.layout as f64);
        put("output overlay".into(), "output.overlay", o.overlay as f64);
        put("lens_id".into(), "lens", self.lens as f64);
        for (i, c) in self.cameras.iter().enumerate() {
            let cam = |f: &str| format!("camera {i} {f}");
            put(cam("yaw"), "camera.yaw", c.yaw);
            put(cam("pitch"), "camera.pitch", c.pitch);
            put(cam("roll"), "camera.roll", c.roll);
            put(cam("fov"), "camera.fov", c.fov);
            put(cam("zoom"), "camera.zoom", c.zoom as f64);
            put(cam("crop mode"), "camera.crop", c.crop as f64);
            put(cam("lock flags"), "camera.lock", c.lock as f64);
            put(cam("control mode"), "camera.control", c.control as f64);
            if let Some(t) = &c.target {
                put(cam("target latitude"), "camera.target.lat", t.lat);
                put(cam("target longitude"), "camera.target.lon", t.lon);
                put(cam("target altitude"), "camera.target.alt", t.alt);
            }
        }
        let a = &self.vehicle.attitude;
        put("vehicle attitude yaw".into(), "vehicle.attitude.yaw", a.yaw);
        put(
            "vehicle attitude pitch".into(),
            "vehicle.attitude.pitch",
            a.pitch,
        );
        put(
            "vehicle attitude roll".into(),
            "vehicle.attitude.roll",
            a.roll,
        );
        let p = &self.vehicle.position;
        put("vehicle latitude".into(), "vehicle.position.lat", p.lat);
        put("vehicle longitude".into(), "vehicle.position.lon", p.lon);
        put("vehicle altitude".into(), "vehicle.position.alt", p.alt);
        put(
            "vehicle height above home".into(),
            "vehicle.position.relative_alt",
            p.relative_alt,
        );
        put("mount yaw".into(), "mount.yaw", self.mount.yaw);
        put("mount pitch".into(), "mount.pitch", self.mount.pitch);
        put("mount roll".into(), "mount.roll", self.mount.roll);
        let s = &self.sensor;
        put("sensor width".into(), "sensor.width", s.width as f64);
        put("sensor height".into(), "sensor.height", s.height as f64);
        put("sensor fps".into(), "sensor.fps", s.fps as f64);
        for (name, v) in ["x", "y", "width", "height"]
            .iter()
            .zip(s.roi.unwrap_or_default())
        {
            put(format!("sensor crop {name}"), "sensor.roi", v as f64);
        }
        put("sensor ae".into(), "sensor.ae", s.ae as u8 as f64);
        put(
            "sensor target brightness".into(),
            "sensor.target_brightness",
            s.target_brightness as f64,
        );
        put(
            "sensor exposure".into(),
            "sensor.exposure_us",
            s.exposure_us as f64,
        );
        put("sensor gain".into(), "sensor.gain", s.gain as f64);
        let d = &self.detection;
        for (key, v) in [
            ("detection.run_ai", d.run_ai as u8 as f64),
            ("detection.mode", d.mode as f64),
            ("detection.sorting_mode", d.sorting_mode as f64),
            (
                "detection.crop_confidence_threshold",
                d.crop_confidence_threshold,
            ),
            (
                "detection.var_confidence_threshold",
                d.var_confidence_threshold,
            ),
            ("detection.crop_box_limit", d.crop_box_limit as f64),
            ("detection.var_box_limit", d.var_box_limit as f64),
            ("detection.crop_box_overlap", d.crop_box_overlap),
            ("detection.var_box_overlap", d.var_box_overlap),
            (
                "detection.creation_score_scale",
                d.creation_score_scale as f64,
            ),
            (
                "detection.bonus_detection_scale",
                d.bonus_detection_scale as f64,
            ),
            (
                "detection.bonus_redetection_scale",
                d.bonus_redetection_scale as f64,
            ),
            (
                "detection.missed_detection_penalty",
                d.missed_detection_penalty as f64,
            ),
            (
                "detection.missed_redetection_penalty",
                d.missed_redetection_penalty as f64,
            ),
        ] {
            put(key.replacen('.', " ", 1), key, v);
        }
        for t in &self.tracked {
            let obj = |f: &str| format!("tracked object {} {f}", t.id);
            put(obj("id"), "tracked.id", t.id as f64);
            put(obj("yaw"), "tracked.yaw", t.yaw);
            put(obj("pitch"), "tracked.pitch", t.pitch);
            put(obj("size"), "tracked.size", t.size);
            put(obj("score"), "tracked.score", t.score as f64);
            for v in t.velocity {
                put(obj("velocity"), "tracked.velocity", v);
            }
            put(obj("sighting time"), "tracked.seen_us", t.seen_us as f64);
        }
        put("scene time".into(), "time", self.time);
        out
    }
}

/// `v` as a reader takes it in: as it is, or in scientific notation when huge.
fn num(v: f64) -> String {
    match v.abs() < 1e6 {
        true => format!("{v}"),
        false => format!("{v:e}"),
    }
}
