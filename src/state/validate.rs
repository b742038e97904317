//! The one check every way into the settings and the state goes through (state files, flags,
//! the serve configuration, the control paths): every field the one table of rules reads
//! (`rules::RULES`, each through where it says the field is held) against its range, and the
//! bounds that join fields.

use super::State;
use super::rules::{Of, RULES, Rule};
use super::settings::{Output, Settings};
use crate::geometry::view::{clamp_fov, fov_range};
use crate::lens::Lenses;
use crate::modes::Control;
use std::ops::ControlFlow;

/// Why settings or a state are refused: the field, its value and the range it must lie in.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Invalid(pub String);

fn invalid<T>(message: String) -> Result<T, Invalid> {
    Err(Invalid(message))
}

/// Which one of a field's values: of a camera, of a tracked object, a part of the sensor
/// crop; said only when a value is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    Only,
    Camera(usize),
    Object(u32),
    Part(usize),
}

impl Place {
    /// What a reader calls the value: `camera 2 fov`, `tracked object 7 size`.
    pub fn label(self, rule: &Rule) -> String {
        match self {
            Place::Only => rule.label.to_string(),
            Place::Camera(i) => format!("camera {i} {}", rule.label),
            Place::Object(id) => format!("tracked object {id} {}", rule.label),
            Place::Part(k) => {
                let part = ["x", "y", "width", "height"][k.min(3)];
                format!("{} {part}", rule.label)
            }
        }
    }
}

/// A value the one check reads: its rule, which one, the number.
pub type Value = (&'static Rule, Place, f64);

impl Output {
    /// Rounds an odd width or height down to even, as every entry does (flags, state files,
    /// the protocol's VIDEO_OUTPUT): 4:2:0 video has no odd sizes.
    pub fn even(&mut self) {
        let even = (self.width & !1, self.height & !1);
        if even != (self.width, self.height) {
            tracing::info!(
                "output size {}x{} rounded down to {}x{} (4:2:0 video needs even sizes)",
                self.width,
                self.height,
                even.0,
                even.1
            );
            (self.width, self.height) = even;
        }
    }
}

impl Settings {
    /// The one check of whole settings, whichever way they came in: every field against the
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
        let (w, h) = (self.sensor.width, self.sensor.height);
        match lens.fits(w, h, self.sensor.roi()) {
            Err(e) => invalid(format!("{e} (the sensor's size)")),
            Ok(()) => Ok(()),
        }
    }

    /// Every field against its rule (what the protocol takes unchanged), and the bounds that
    /// join fields (what can be checked without lens.cal; [`Settings::validate`] checks the
    /// rest).
    pub fn validate_fields(&self) -> Result<(), Invalid> {
        if let ControlFlow::Break(e) = self.each_value(&mut refuse_outside) {
            return Err(e);
        }
        let o = &self.output;
        if o.width % 2 == 1 || o.height % 2 == 1 {
            return invalid(format!(
                "output size {}x{} is odd; 4:2:0 video needs even sizes",
                o.width, o.height
            ));
        }
        for (i, c) in self.cameras.iter().enumerate() {
            if c.crop().code() <= 4 && clamp_fov(c.fov(), c.crop()) != c.fov() {
                let (lo, hi) = fov_range(c.crop());
                return invalid(format!(
                    "camera {i}: fov {:.3} rad is outside {lo}..={hi:.3} for crop mode {}",
                    c.fov(),
                    c.crop().code()
                ));
            }
            if c.control() == Control::Coordinate && c.target().is_none() {
                return invalid(format!(
                    "camera {i}: control mode 2 needs a target (lat, lon, alt)"
                ));
            }
        }
        let t = &self.thermal;
        if t.low >= t.high {
            return invalid(format!(
                "thermal span low {} K is not below its high {} K",
                t.low, t.high
            ));
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

    /// Calls `f` with every number the settings hold, through the rules that read them.
    pub fn each_value<B>(&self, f: &mut dyn FnMut(Value) -> ControlFlow<B>) -> ControlFlow<B> {
        for rule in RULES {
            match rule.of {
                Of::Output(get) => f((rule, Place::Only, get(&self.output)))?,
                Of::Lens => f((rule, Place::Only, self.lens as f64))?,
                Of::Mount(get) => f((rule, Place::Only, get(&self.mount)))?,
                Of::Sensor(get) => f((rule, Place::Only, get(&self.sensor)))?,
                Of::Detection(get) => f((rule, Place::Only, get(&self.detection)))?,
                Of::Thermal(get) => f((rule, Place::Only, get(&self.thermal)))?,
                Of::SensorCrop => {
                    for (k, v) in self.sensor.roi.unwrap_or_default().into_iter().enumerate() {
                        f((rule, Place::Part(k), v as f64))?;
                    }
                }
                Of::Camera(get) => {
                    for (i, c) in self.cameras.iter().enumerate() {
                        if let Some(v) = get(c) {
                            f((rule, Place::Camera(i), v))?;
                        }
                    }
                }
                _ => {}
            }
        }
        ControlFlow::Continue(())
    }
}

/// Breaks with the refusal of a value outside its rule's range.
fn refuse_outside((rule, place, v): Value) -> ControlFlow<Invalid> {
    if rule.holds(v) {
        return ControlFlow::Continue(());
    }
    let also = match rule.also {
        "" => String::new(),
        a => format!(", and {a}"),
    };
    ControlFlow::Break(Invalid(format!(
        "{} {} is outside {}{also}",
        place.label(rule),
        rule.shown(v),
        rule.range()
    )))
}

impl State {
    /// The one check of a whole state (a file's, the flags'): the settings, and the vehicle,
    /// the tracked objects and the scene's time against their rules.
    pub fn validate(&self, lenses: &Lenses) -> Result<(), Invalid> {
        self.validate_fields()?;
        self.settings.validate(lenses)
    }

    /// [`State::validate`] of what can be checked without lens.cal.
    pub fn validate_fields(&self) -> Result<(), Invalid> {
        if let ControlFlow::Break(e) = self.each_value(&mut refuse_outside) {
            return Err(e);
        }
        self.settings.validate_fields()
    }

    /// Calls `f` with every number the state holds beyond its settings.
    pub fn each_value<B>(&self, f: &mut dyn FnMut(Value) -> ControlFlow<B>) -> ControlFlow<B> {
        for rule in RULES {
            match rule.of {
                Of::Vehicle(get) => f((rule, Place::Only, get(&self.vehicle)))?,
                Of::Time => f((rule, Place::Only, self.time))?,
                Of::Tracked(get) => {
                    for t in &self.tracked {
                        f((rule, Place::Object(t.id), get(t)))?;
                    }
                }
                Of::TrackedVelocity => {
                    for t in &self.tracked {
                        for v in t.velocity {
                            f((rule, Place::Object(t.id), v))?;
                        }
                    }
                }
                _ => {}
            }
        }
        ControlFlow::Continue(())
    }

    /// Every number the state holds, the settings' first: its rule, which one, its value.
    pub fn values(&self) -> Vec<Value> {
        let mut out = vec![];
        let mut put = |v: Value| {
            out.push(v);
            ControlFlow::<()>::Continue(())
        };
        let _ = self.settings.each_value(&mut put);
        let _ = self.each_value(&mut put);
        out
    }
}
