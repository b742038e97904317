//! The thermal sensor beside the fisheye (`serve --thermal SOURCE`, `[thermal]`): its thread,
//! which puts each frame in the sensor's newest-wins slot (the demo's thermal camera drawn
//! from the demo world at the demo's time and at the vehicle's attitude at the frame's capture,
//! or a GStreamer source reopened with back-off when it fails), and what a view reads of the
//! newest frame: the hottest and coldest point of what the view shows and the temperature at
//! any of its pixels, in the view's own pixels (its own stream's and stills' size), the view
//! as it is aimed now and the vehicle as it was when the thermal frame was captured; and the
//! newest frame laid over the views that show it (`plan::thermal`).

use super::Head;
use crate::clock::clock_us;
use crate::lens::{Lens, Lenses};
use crate::modes::ThermalShow;
use crate::plan::FramePlan;
use crate::plan::thermal::ThermalLayer;
use crate::scene::GridWorld;
use crate::scene::thermal::{thermal_frame, thermal_in_lens, world_from_thermal};
use crate::source::thermal::{Stamped, ThermalConfig, ThermalSetup, ThermalSlot};
use crate::source::{SourceSpec, backoff};
use crate::state::State;
use crate::supervise::Locked;
use crate::thermal::{GainMode, GainTable, Spot};
use glam::{DMat3, DVec2};
use serde::Serialize;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tracing::{error, info};

/// The thermal sensor as the head runs it.
pub struct Sensor {
    pub setup: ThermalSetup,
    /// Its lens at its calibration frame.
    pub lens: Lens,
    pub slot: Arc<ThermalSlot>,
    /// Why the source is down, while it is.
    error: Mutex<Option<String>>,
    /// The newest frame's gain table, made once for the composed frame and every view's
    /// stream: the frame's capture time and the gain it was made with.
    gain: Mutex<Option<(u64, GainMode, Arc<GainTable>)>>,
}

impl Sensor {
    /// The sensor `[thermal]` describes, as [`Sensor::open`] makes it; None when it is off.
    pub fn configured(cfg: &ThermalConfig, lenses: &Lenses) -> Result<Option<Sensor>, String> {
        match cfg.setup().map_err(|e| e.to_string())? {
            Some(setup) => Sensor::open(setup, lenses).map(Some),
            None => Ok(None),
        }
    }

    /// The sensor `setup` describes, its lens found in `lenses` and its source checked: a
    /// source that can never open is refused now, not retried for ever.
    pub fn open(setup: ThermalSetup, lenses: &Lenses) -> Result<Sensor, String> {
        let Some(lens) = lenses.named(&setup.lens) else {
            let names: Vec<_> = lenses.names().into_iter().map(|(_, n)| n).collect();
            return Err(format!(
                "thermal lens {:?} is not in lens.cal; its lenses are {}",
                setup.lens,
                names.join(", ")
            ));
        };
        crate::source::thermal::check(&setup.spec, setup.fps)
            .map_err(|e| format!("thermal source: {e}"))?;
        Ok(Sensor {
            lens: lens.clone(),
            setup,
            slot: Arc::default(),
            error: Mutex::default(),
            gain: Mutex::default(),
        })
    }

    /// `stamped`'s gain table under `mode`, made on the first asking.
    fn gain(&self, stamped: &Stamped, mode: GainMode) -> Option<Arc<GainTable>> {
        let mut kept = self.gain.locked();
        if let Some((at, m, table)) = kept.as_ref()
            && (*at, *m) == (stamped.captured_us, mode)
        {
            return Some(table.clone());
        }
        let table = Arc::new(GainTable::new(&stamped.frame, mode, &self.setup.cal).ok()?);
        *kept = Some((stamped.captured_us, mode, table.clone()));
        Some(table)
    }

    fn set_error(&self, e: Option<String>) {
        *self.error.locked() = e;
    }

    /// The sensor's figures for `/api/status`: its source, frames so far, the newest frame's
    /// size and why it is down, while it is.
    pub fn status(&self) -> serde_json::Value {
        let newest = self.slot.newest();
        serde_json::json!({
            "source": self.setup.spec.to_string(),
            "lens": self.lens.name,
            "frames": self.slot.received(),
            "size": newest.map(|f| [f.frame.width, f.frame.height]),
            "error": *self.error.locked(),
        })
    }
}

/// What a view reads of the newest thermal frame, in its own pixels (x right, y down from
/// its top-left corner; a pixel's centre at +0.5).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct InView {
    pub camera: usize,
    pub width: u32,
    pub height: u32,
    /// The thermal frame's capture time, µs on the head's clock.
    pub captured_us: u64,
    /// The hottest and coldest point the view shows; None where it shows none of the
    /// thermal camera's field.
    pub hottest: Option<Spot>,
    pub coldest: Option<Spot>,
    /// The temperature at the pixel asked for.
    pub spot: Option<Spot>,
}

/// Why a view's thermal reading was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ThermalAsk {
    #[error("no thermal sensor: start serve with --thermal SOURCE (docs/thermal.md)")]
    NoSensor,
    #[error("the thermal sensor has sent no frame yet")]
    NoFrame,
    #[error("camera {0} is not a view: give 0 to {1}")]
    NoCamera(usize, usize),
    #[error("x {x}, y {y} is not a pixel of camera {camera}'s {width}x{height} picture")]
    NotAPixel {
        camera: usize,
        x: f64,
        y: f64,
        width: u32,
        height: u32,
    },
    #[error("camera {0}'s pixel ({1:.1}, {2:.1}) is outside what the thermal camera sees")]
    NotSeen(usize, f64, f64),
    #[error("camera {0}: {1}")]
    Lens(usize, String),
}

impl Head {
    /// Runs the thermal sensor until the head stops.
    pub(super) fn thermal_thread(&self, sensor: &Sensor) {
        if sensor.setup.spec == SourceSpec::Demo {
            return self.thermal_demo(sensor);
        }
        let spec = &sensor.setup.spec;
        let mut backoff = backoff();
        while !self.stop.load(Ordering::Relaxed) {
            let outcome = crate::source::thermal::open(spec, sensor.setup.fps, sensor.slot.clone())
                .and_then(|s| {
                    info!("thermal source: {spec}");
                    sensor.set_error(None);
                    s.run(&self.stop)
                });
            let e = match outcome {
                Ok(_) => return,
                Err(e) => e,
            };
            let wait = backoff.failed();
            if backoff.worth_logging() {
                error!("thermal source {spec} failed: {e}; retrying in {wait:?}");
            }
            sensor.set_error(Some(format!("thermal camera gone: {e}")));
            self.pause(wait);
        }
    }

    /// The demo's thermal camera: the demo world at the demo's time (the flight's, where the
    /// fisheye is the demo too), at the sensor's rate.
    fn thermal_demo(&self, sensor: &Sensor) {
        let world = GridWorld::demo(self.cfg.demo.movers);
        let period = Duration::from_secs_f64(1.0 / sensor.setup.fps as f64);
        let own_start = clock_us();
        info!(
            "thermal source: demo, {}x{} through {} at {} fps",
            sensor.lens.width, sensor.lens.height, sensor.lens.name, sensor.setup.fps
        );
        let mut next = Instant::now();
        while !self.stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now < next {
                std::thread::sleep(next - now);
            }
            next = (next + period).max(Instant::now());
            let captured_us = clock_us();
            let start_us = self.demo_truth().map_or(own_start, |t| t.start_us);
            let mut state = self.state_at(captured_us);
            state.time = captured_us.saturating_sub(start_us) as f64 / 1e6;
            let (lens, setup) = (&sensor.lens, &sensor.setup);
            let frame = thermal_frame(&world, lens, setup.mount, &state, &setup.cal, 2);
            sensor.slot.put(frame, captured_us);
        }
    }

    /// The state now with the vehicle as it was at `t_us`, as far as the telemetry knows.
    fn state_at(&self, t_us: u64) -> State {
        let mut s = self.state();
        self.vehicle_at(&mut s, t_us);
        s
    }

    /// What view `camera` reads of the newest thermal frame: its hottest and coldest point
    /// and, when asked, the temperature at its pixel `spot`.
    pub fn thermal_in_view(
        &self,
        camera: usize,
        spot: Option<DVec2>,
    ) -> Result<InView, ThermalAsk> {
        let sensor = self.input.thermal.as_ref().ok_or(ThermalAsk::NoSensor)?;
        let stamped = sensor.slot.newest().ok_or(ThermalAsk::NoFrame)?;
        let state = self.state_at(stamped.captured_us);
        let count = state.settings.cameras.len();
        if camera >= count {
            return Err(ThermalAsk::NoCamera(camera, count.saturating_sub(1)));
        }
        let (width, height) = self.cfg.view_size;
        let fisheye = self
            .gate
            .settings()
            .lenses()
            .for_frame(
                state.settings.lens,
                self.frame_size_or_sensor(&state),
                state.settings.sensor.roi(),
            )
            .map_err(|e| ThermalAsk::Lens(camera, e.to_string()))?;
        let plan = FramePlan::single_view(&state, &fisheye, camera, width, height);
        let seen = Seen {
            plan: &plan,
            lens: sensor
                .lens
                .for_frame(stamped.frame.width, stamped.frame.height, None),
            world_from_thermal: world_from_thermal(&state, sensor.setup.mount),
        };
        let (hottest, coldest) = seen.extremes(&stamped, &sensor.setup.cal);
        let spot = match spot {
            None => None,
            Some(p) => Some(seen.spot(&stamped, &sensor.setup.cal, camera, p)?),
        };
        Ok(InView {
            camera,
            width,
            height,
            captured_us: stamped.captured_us,
            hottest,
            coldest,
            spot,
        })
    }
}

impl Head {
    /// The newest thermal frame over `plan`'s views as their cameras ask (`views`: each
    /// view's index in the plan and its camera's), coloured as the settings say
    /// (`ThermalLook`). None without a sensor, before its first frame, or where no view
    /// shows it.
    pub(super) fn thermal_layer(
        &self,
        state: &State,
        plan: &FramePlan,
        views: impl Iterator<Item = (usize, usize)>,
    ) -> Option<Arc<ThermalLayer>> {
        let sensor = self.input.thermal.as_ref()?;
        let shown: Vec<(usize, ThermalShow)> = views
            .filter_map(|(v, cam)| Some((v, state.settings.cameras.get(cam)?.thermal())))
            .filter(|&(_, show)| show != ThermalShow::Off)
            .collect();
        if shown.is_empty() {
            return None;
        }
        let stamped = sensor.slot.newest()?;
        let look = &state.settings.thermal;
        let gain = sensor.gain(&stamped, look.gain_mode())?;
        let frame = stamped.frame.clone();
        let lens = sensor.lens.for_frame(frame.width, frame.height, None);
        let mut layer = ThermalLayer::new(frame, gain, look.palette, lens);
        (layer.blend, layer.zoom) = (look.blend, look.zoom as f64);
        let mount = thermal_in_lens(sensor.setup.mount);
        for (v, show) in shown {
            layer.add(plan, &plan.views[v], show, mount);
        }
        (!layer.entries.is_empty()).then(|| Arc::new(layer))
    }
}

/// A thermal frame as one view sees it.
struct Seen<'a> {
    /// The view alone, at its own size.
    plan: &'a FramePlan,
    /// The thermal lens at the frame's size.
    lens: Lens,
    world_from_thermal: DMat3,
}

impl Seen<'_> {
    /// Where thermal pixel point `q` (a pixel's centre at +0.5) shows in the view.
    fn in_view(&self, q: DVec2) -> Option<DVec2> {
        let ray = self.lens.unproject(q - DVec2::splat(0.5))?;
        self.plan
            .view_point(&self.plan.views[0], self.world_from_thermal * ray)
    }

    /// The hottest and coldest point among the thermal pixels the view shows, in its pixels.
    fn extremes(
        &self,
        stamped: &Stamped,
        cal: &crate::thermal::Calibration,
    ) -> (Option<Spot>, Option<Spot>) {
        let f = &stamped.frame;
        let w = f.width as usize;
        let shown: Vec<bool> = (0..f.counts.len())
            .map(|i| {
                let q = DVec2::new((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
                self.in_view(q).is_some()
            })
            .collect();
        let Some(e) = f.extremes_where(cal, |i| shown[i]) else {
            return (None, None);
        };
        let place = |s: Spot| {
            let p = self.in_view(DVec2::new(s.x, s.y))?;
            Some(Spot {
                x: p.x,
                y: p.y,
                kelvin: s.kelvin,
            })
        };
        (place(e.hottest), place(e.coldest))
    }

    /// The temperature at view pixel point `p`.
    fn spot(
        &self,
        stamped: &Stamped,
        cal: &crate::thermal::Calibration,
        camera: usize,
        p: DVec2,
    ) -> Result<Spot, ThermalAsk> {
        let view = &self.plan.views[0];
        let (width, height) = (view.rect.w, view.rect.h);
        let inside = p.x >= 0.0 && p.y >= 0.0 && p.x <= width as f64 && p.y <= height as f64;
        if !inside {
            let (x, y) = (p.x, p.y);
            return Err(ThermalAsk::NotAPixel {
                camera,
                x,
                y,
                width,
                height,
            });
        }
        let not_seen = ThermalAsk::NotSeen(camera, p.x, p.y);
        let ray = self.plan.view_ray(view, p).ok_or(not_seen.clone())?;
        let q = self
            .lens
            .project(self.world_from_thermal.transpose() * ray)
            .ok_or(not_seen.clone())?
            + DVec2::splat(0.5);
        let at = stamped.frame.spot(q.x, q.y, cal).map_err(|_| not_seen)?;
        Ok(Spot {
            x: p.x,
            y: p.y,
            kelvin: at.kelvin,
        })
    }
}
