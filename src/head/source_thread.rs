//! The source thread: the built-in demo (a simulated camera and flight, feeding the
//! telemetry as an autopilot would), or a GStreamer source reopened with back-off whenever it
//! fails. Frames go to the head's newest-wins slot.

use super::detection::score::DemoTruth;
use super::{Head, HeadError};
use crate::clock::clock_us;
use crate::exposure::{SensorModel, Setting};
use crate::frame::{Frame, PlaneLayout};
use crate::geometry::Euler;
use crate::scene::GridWorld;
use crate::scene::synth::world_origin;
use crate::source::demo::{DemoCamera, Flight};
use crate::source::{Ended, SourceSpec, backoff};
use crate::state::State;
use crate::supervise::Locked;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

impl Head {
    /// Runs the source until the head stops: the demo, or a GStreamer source reopened with
    /// back-off whenever it fails, its failure kept for the status and the health log.
    pub(super) fn source_thread(&self, spec: SourceSpec) {
        if spec == SourceSpec::Demo {
            if let Err(e) = self.demo_source() {
                error!("demo source: {e}");
                self.set_source_error(Some(e.to_string()));
            }
            return;
        }
        let mut backoff = backoff();
        while !self.stop.load(Ordering::Relaxed) {
            let outcome = crate::source::open(
                &spec,
                self.cfg.source_fps,
                self.cfg.source_loop,
                self.input.slot.clone(),
            )
            .and_then(|s| {
                info!("source: {spec}");
                s.run(&self.stop)
            });
            let e = match outcome {
                Ok(Ended::Stopped) => return,
                Ok(Ended::Eos) => {
                    info!("source {spec} ended");
                    self.set_source_error(Some(format!("source {spec} ended")));
                    return;
                }
                Err(e) => e,
            };
            // A source that delivered a while before failing starts its back-off afresh.
            if self
                .input
                .slot
                .silence()
                .is_some_and(|s| s < Duration::from_secs(5))
            {
                backoff.held();
            }
            let wait = backoff.failed();
            if backoff.worth_logging() {
                error!(
                    "source {spec} failed ({} times): {e}; retrying in {wait:?}",
                    backoff.failures()
                );
            }
            self.set_source_error(Some(format!("camera gone: {e}")));
            self.pause(wait);
        }
    }

    /// Whether a source's frame can be seen through the lens the settings name: a lens
    /// pair's only in the pair's shape (unless a sensor crop says which part). When not, the
    /// source's error says why, for the status, the page and ground stations.
    pub(super) fn frame_fits(&self, frame: &Frame, state: &State) -> bool {
        let s = &state.settings;
        let settings = self.gate.settings();
        let Some(lens) = settings.lenses().get(s.lens) else {
            return true;
        };
        match lens.fits(frame.layout.width, frame.layout.height, s.sensor.roi()) {
            Err(e) => {
                let why = e.to_string();
                if self.source_error().as_deref() != Some(why.as_str()) {
                    warn!("source: {why}");
                    self.set_source_error(Some(why));
                }
                false
            }
            Ok(()) => true,
        }
    }

    /// The simulated camera and flight, paced at the demo's frame rate.
    fn demo_source(&self) -> Result<(), HeadError> {
        let d = &self.cfg.demo;
        let (camera, flight) = self.demo_camera()?;
        let period = Duration::from_secs_f64(1.0 / d.fps as f64);
        let start = Instant::now();
        *self.observers.demo_truth.locked() = Some(DemoTruth {
            movers: camera.world().movers.clone(),
            origin: world_origin(&flight.hover),
            start_us: clock_us(),
        });
        // The flight goes to the frames through the MAVLink link, as a real autopilot's would,
        // where the link listens on this machine; else straight into the telemetry.
        let _autopilot = match (&self.input.demo_autopilot, d.spin) {
            (Some(send), false) => Some(send(&flight, start)),
            _ => None,
        };
        let mut next = start;
        let mut number = 0u64;
        while !self.stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now < next {
                std::thread::sleep(next - now);
            }
            next += period;
            if next < Instant::now() {
                // Fell behind (a busy machine): skip ahead rather than burst.
                next = Instant::now() + period;
            }
            if self.input.slot.pending() {
                // The renderer has not taken the last frame: a simulated camera need not
                // spend the CPU the renderer needs on a frame that would be dropped.
                continue;
            }
            number += 1;
            self.demo_frame(&camera, &flight, start.elapsed().as_secs_f64(), number);
        }
        Ok(())
    }

    /// The demo's camera and flight, as the settings and the vehicle now give them.
    fn demo_camera(&self) -> Result<(DemoCamera, Flight), HeadError> {
        let d = &self.cfg.demo;
        let state = self.state();
        let settings = self.gate.settings();
        let lenses = settings.lenses();
        let (width, height) = lenses
            .get(state.settings.lens)
            .map_or((d.width, d.height), |lens| d.size_for(lens));
        let lens = lenses.for_frame(
            state.settings.lens,
            (width, height),
            state.settings.sensor.roi(),
        )?;
        let layout = PlaneLayout::tight(d.format, width, height)?;
        let camera = DemoCamera::new(&lens, layout, state.settings.mount.euler())
            .with_readout(d.readout_ms)
            .in_world(GridWorld::demo(d.movers));
        let flight = Flight {
            hover: state.vehicle.position,
            // Spinning is about level and north, by the clock alone: never about an attitude
            // an autopilot may already have reported.
            attitude: if d.spin {
                Euler::default()
            } else {
                state.vehicle.attitude.euler()
            },
            motion: d.motion,
            spin: d.spin,
            radius: 30.0,
            lap: 90.0,
        };
        info!(
            "source: demo, {width}x{height} {} at {} fps, {}",
            d.format,
            d.fps,
            match (d.spin, d.motion) {
                (true, _) => "spinning (yaw 90°/s, roll ±20° at 1 Hz)",
                (false, true) => "flying a circle",
                (false, false) => "hovering",
            }
        );
        Ok((camera, flight))
    }

    /// The demo's frame `number`, `t` seconds into its flight, into the slot.
    fn demo_frame(&self, camera: &DemoCamera, flight: &Flight, t: f64, number: u64) {
        let d = &self.cfg.demo;
        let captured_us = clock_us();
        let (attitude, position) = flight.pose_at(t, captured_us as f64 / 1e6);
        self.telemetry.simulated(captured_us, attitude, position);
        let stamp = d.stamp.then_some((captured_us / 1000) as u32);
        // The exposure and gain as they are now, read after the capture time is taken: the
        // auto exposure knows a frame stamped after its change shows it.
        let sensor = &self.settings().sensor;
        let sensor = SensorModel::new(Setting {
            exposure_us: sensor.exposure_us,
            gain: sensor.gain,
        });
        // A rolling shutter's later rows see the flight as it goes on.
        let clock_s = captured_us as f64 / 1e6;
        let at = |dt_us: f64| {
            let dt = dt_us * 1e-6;
            flight.pose_at(t + dt, clock_s + dt).0
        };
        let data = camera.frame(at, &position, t, (sensor, number), stamp);
        self.input.slot.put(Frame {
            data,
            layout: *camera.layout(),
            captured_us,
        });
    }
}
