//! The one check every way into the state goes through (state files, flags, the control
//! protocol, and what comes later): every field against the range the protocol allows.

use super::detection::BOX_LIMITS;
use super::{FPS_RANGE, MAX_GAIN, MAX_OUTPUT, MAX_SENSOR, MIN_OUTPUT, RATIO_RANGE, State};
use crate::geometry::view::{LockFlags, clamp_fov, control, crop, fov_range};
use crate::layout::{LAYOUT_MODES, OVERLAY_MODES};
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

    /// Every field against the range the protocol allows (what can be checked without
    /// lens.cal; [`State::validate`] checks the rest).
    pub fn validate_fields(&self) -> Result<(), Invalid> {
        let o = &self.output;
        let (lo, hi) = (MIN_OUTPUT, MAX_OUTPUT);
        if !(lo.0..=hi.0).contains(&o.width) || !(lo.1..=hi.1).contains(&o.height) {
            return invalid(format!(
                "output size {}x{} is outside {}x{}..={}x{}",
                o.width, o.height, lo.0, lo.1, hi.0, hi.1
            ));
        }
        if o.width % 2 == 1 || o.height % 2 == 1 {
            return invalid(format!(
                "output size {}x{} is odd; 4:2:0 video needs even sizes",
                o.width, o.height
            ));
        }
        if !(FPS_RANGE.0..=FPS_RANGE.1).contains(&o.fps) {
            return invalid(format!(
                "output fps {} is outside {}..={}",
                o.fps, FPS_RANGE.0, FPS_RANGE.1
            ));
        }
        if o.layout >= LAYOUT_MODES {
            return invalid(format!(
                "layout {} does not exist (0..={})",
                o.layout,
                LAYOUT_MODES - 1
            ));
        }
        if o.overlay >= OVERLAY_MODES {
            return invalid(format!(
                "overlay {} does not exist (0..={})",
                o.overlay,
                OVERLAY_MODES - 1
            ));
        }
        for (i, c) in self.cameras.iter().enumerate() {
            if c.lock > LockFlags::ALL.0 {
                return invalid(format!(
                    "camera {i}: lock flags {} are outside 0..=7",
                    c.lock
                ));
            }
            if c.control > control::PASS {
                return invalid(format!(
                    "camera {i}: control mode {} is outside 0..={}",
                    c.control,
                    control::PASS
                ));
            }
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
        if !(1..=MAX_SENSOR).contains(&s.width) || !(1..=MAX_SENSOR).contains(&s.height) {
            return invalid(format!(
                "sensor size {}x{} is outside 1x1..={MAX_SENSOR}x{MAX_SENSOR}",
                s.width, s.height
            ));
        }
        if !(1..=240).contains(&s.fps) {
            return invalid(format!("sensor fps {} is outside 1..=240", s.fps));
        }
        let longest = s.longest_exposure_us();
        if !(1..=longest).contains(&s.exposure_us) {
            return invalid(format!(
                "sensor exposure {} µs is outside 1..={longest} (the frame time at {} fps)",
                s.exposure_us, s.fps
            ));
        }
        if !(1..=MAX_GAIN).contains(&s.gain) {
            return invalid(format!("sensor gain {} is outside 1..={MAX_GAIN}", s.gain));
        }
        if !(1..=254).contains(&s.target_brightness) {
            return invalid(format!(
                "sensor target brightness {} is outside 1..=254",
                s.target_brightness
            ));
        }
        let angles = self
            .cameras
            .iter()
            .flat_map(|c| [c.yaw, c.pitch, c.roll, c.fov]);
        let vehicle = &self.vehicle.attitude;
        let frames = [
            vehicle.yaw,
            vehicle.pitch,
            vehicle.roll,
            self.mount.yaw,
            self.mount.pitch,
        ];
        if !angles
            .chain(frames)
            .chain([self.mount.roll, self.time])
            .all(f64::is_finite)
        {
            return invalid("angles and the scene time must be finite numbers".into());
        }
        let d = &self.detection;
        for (name, v) in [
            ("crop_confidence_threshold", d.crop_confidence_threshold),
            ("var_confidence_threshold", d.var_confidence_threshold),
            ("crop_box_overlap", d.crop_box_overlap),
            ("var_box_overlap", d.var_box_overlap),
        ] {
            if !RATIO_RANGE.contains(&v) {
                return invalid(format!("detection {name} {v} is outside [0, 0.99)"));
            }
        }
        for (name, v) in [
            ("crop_box_limit", d.crop_box_limit),
            ("var_box_limit", d.var_box_limit),
        ] {
            // What DETECTION clamps them to, refused from every other path.
            if !(BOX_LIMITS.0..=BOX_LIMITS.1).contains(&v) {
                return invalid(format!(
                    "detection {name} {v} is outside {}..={}",
                    BOX_LIMITS.0, BOX_LIMITS.1
                ));
            }
        }
        if d.sorting_mode > 2 {
            return invalid(format!(
                "detection sorting_mode {} is outside 0..=2",
                d.sorting_mode
            ));
        }
        let p = &self.vehicle.position;
        if !(-90.0..=90.0).contains(&p.lat) || !(-180.0..=180.0).contains(&p.lon) {
            return invalid(format!(
                "vehicle position {}, {} is not a latitude, longitude",
                p.lat, p.lon
            ));
        }
        for (name, m) in [("altitude", p.alt), ("height above home", p.relative_alt)] {
            if !HEIGHTS.contains(&m) {
                return invalid(format!(
                    "vehicle {name} {} m is outside {}..={} m",
                    num(m),
                    HEIGHTS.start(),
                    HEIGHTS.end()
                ));
            }
        }
        self.validate_frames()
    }

    /// The attitude, the mount, the cameras' targets and the tracked objects: angles within
    /// what they can be, places on the globe.
    fn validate_frames(&self) -> Result<(), Invalid> {
        use std::f64::consts::{FRAC_PI_2, PI};
        // The protocol carries angles in milliradians: -π/2 arrives as -1.571.
        let slack = 1e-3;
        let a = &self.vehicle.attitude;
        let m = &self.mount;
        for (what, e) in [
            ("vehicle attitude", (a.yaw, a.pitch, a.roll)),
            ("mount", (m.yaw, m.pitch, m.roll)),
        ] {
            let (yaw, pitch, roll) = e;
            if yaw.abs() > 2.0 * PI + slack
                || pitch.abs() > FRAC_PI_2 + slack
                || roll.abs() > PI + slack
            {
                return invalid(format!(
                    "{what} yaw {}, pitch {}, roll {} rad is outside ±2π, ±π/2, ±π",
                    num(yaw),
                    num(pitch),
                    num(roll)
                ));
            }
        }
        for (i, c) in self.cameras.iter().enumerate() {
            // As CAM_ORIENTATION takes them: yaw and pitch wrap (one turn either way is
            // taken), roll is clamped to ±π/2 (so more is refused, not changed).
            if c.yaw.abs() > 2.0 * PI + slack
                || c.pitch.abs() > 2.0 * PI + slack
                || c.roll.abs() > FRAC_PI_2 + slack
            {
                return invalid(format!(
                    "camera {i}: yaw {}, pitch {}, roll {} rad is outside ±2π, ±2π, ±π/2",
                    num(c.yaw),
                    num(c.pitch),
                    num(c.roll)
                ));
            }
            if let Some(t) = &c.target
                && (!(-90.0..=90.0).contains(&t.lat)
                    || !(-180.0..=180.0).contains(&t.lon)
                    || !HEIGHTS.contains(&t.alt))
            {
                return invalid(format!(
                    "camera {i}: target {}, {}, {} m is not a latitude, longitude and altitude \
                     ({}..={} m)",
                    num(t.lat),
                    num(t.lon),
                    num(t.alt),
                    HEIGHTS.start(),
                    HEIGHTS.end()
                ));
            }
        }
        for o in &self.tracked {
            let sound = o.size > 0.0 && o.size <= PI && o.yaw.is_finite() && o.pitch.is_finite();
            if !sound {
                return invalid(format!(
                    "tracked object {}: size {} rad is outside (0, π], or its direction is no \
                     number",
                    o.id, o.size
                ));
            }
        }
        Ok(())
    }
}

/// `v` as a reader takes it in: as it is, or in scientific notation when huge.
fn num(v: f64) -> String {
    match v.abs() < 1e6 {
        true => format!("{v}"),
        false => format!("{v:e}"),
    }
}

/// Altitudes and heights, metres: from below the Dead Sea to above any drone's ceiling.
const HEIGHTS: std::ops::RangeInclusive<f64> = -1000.0..=20_000.0;
