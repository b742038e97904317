//! The frame loop: paced by [`Pacer`], it takes the newest frame from the slot, renders it
//! with the live state and the vehicle as the telemetry had it at capture time (or streams
//! "no signal" while the source is down), hands stills to the capture, and feeds the
//! encoder. A failed GPU or encoder is rebuilt and the status says so meanwhile.

use super::detection::score::rings;
use super::pacing::Pacer;
use super::supervise::Fault;
use super::views::{Framed, ViewOutputs};
use super::{Head, HeadError, no_signal};
use crate::clock::{Stamps, clock_us, unix_us};
use crate::frame::{Frame, PixelFormat, PlaneLayout};
use crate::geometry::lens_from_world;
use crate::geometry::shutter::ShutterTable;
use crate::head::capture::Still;
use crate::lens::Lens;
use crate::render::gpu::{Gpu, GpuError, Renderer};
use crate::render::{Filter, FramePlan};
use crate::state::{Failure, RenderedFrame, RunStatus, Settings, State, Tracked};
use crate::stream::Encoder;
use crate::stream::encoder::{AccessUnit, Side};
use crate::stream::klv::ViewMetadata;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

/// A source silent for this long is gone: the stream shows "no signal".
const SIGNAL_TIMEOUT: Duration = Duration::from_secs(1);

/// Why a frame was not rendered: the GPU failed (rebuild it), or this frame or state cannot
/// be rendered (skip it, say why).
enum RenderFailure {
    Gpu(String),
    Frame(String),
}

/// A frame rendered: its bytes, the state and lens it was rendered with, its capture time
/// on the UNIX clock (the one every stream's KLV of this frame carries), and its KLV.
struct Rendered {
    data: Vec<u8>,
    layout: PlaneLayout,
    state: State,
    lens: Lens,
    unix_us: u64,
    klv: Option<Arc<[u8]>>,
    shutter: Option<ShutterTable>,
}

/// What the status should say: running while frames flow; error once the source failed or
/// went silent; nothing new (idle) while the first frame is awaited.
fn health(signal: bool, source_failed: bool, had_a_frame: bool) -> Option<bool> {
    match (signal && !source_failed, source_failed || had_a_frame) {
        (true, _) => Some(true),
        (false, true) => Some(false),
        (false, false) => None,
    }
}

impl Head {
    /// The encoder's sink: every access unit to the clients, the page's viewers, the recording
    /// and the relays.
    fn encoder(self: &Arc<Head>, fps: u32) -> Result<Encoder, HeadError> {
        let head = self.clone();
        let encoder = Encoder::new(&self.cfg.encoder, fps, move |au: AccessUnit| {
            head.stats.units.fetch_add(1, Ordering::Relaxed);
            head.rtsp.push(&au.buffer);
            head.preview.push(&au);
            head.capture.on_access_unit(&au);
            for p in &head.publishers {
                if p.push(&au) {
                    head.key_wanted.store(true, Ordering::Relaxed);
                }
            }
            if let Some(s) = au.stamps {
                head.latency.record(Stamps {
                    sent: clock_us(),
                    ..s
                });
            }
            if let Some(t) = au.encode_time {
                head.stats.encoded.fetch_add(1, Ordering::Relaxed);
                head.stats
                    .encode_us
                    .fetch_add(t.as_micros() as u64, Ordering::Relaxed);
            }
        })?;
        Ok(encoder)
    }

    /// The stream's renderer: I420 out, mip filtering, ready from its first frame for a
    /// LENS SET to any lens of lens.cal.
    pub(super) fn renderer(&self, gpu: &Gpu) -> Result<Renderer, GpuError> {
        let mut renderer = Renderer::new(gpu, PixelFormat::I420, Filter::Mip)?;
        renderer.expect_lens_models(self.gate.settings().lenses().models());
        Ok(renderer)
    }

    pub(super) fn frame_loop(self: &Arc<Head>) -> Result<(), HeadError> {
        let mut renderer = self.renderer(&Gpu::new()?)?;
        let mut views = ViewOutputs::default();
        let mut scans = super::detection::ScanRenderer::default();
        let mut encoder = self.encoder(self.settings().output.fps)?;
        let start = Instant::now();
        let mut pacer = Pacer::default();
        let mut last_frame: Option<Frame> = None;
        // The settings and objects of the last frame rendered.
        let mut shown: Option<(Arc<Settings>, Arc<Vec<Tracked>>)> = None;
        // The status last reported: None idle, Some(running or not).
        let mut healthy: Option<bool> = None;
        let fault = Fault::for_stage("frames");
        // Frames the source replaced in the slot before they were taken, as of the last take.
        let mut replaced_then = self.slot.stats().dropped;
        while !self.stop.load(Ordering::Relaxed) {
            fault.check("frames");
            let (settings, tracked) = (self.settings(), self.gate.sensed().tracked());
            let state = State::of(&settings, self.gate.sensed().vehicle(), &tracked);
            let period = Duration::from_secs_f64(1.0 / state.settings.output.fps as f64);
            let due = pacer.due();
            if let Some(early) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(early);
            }
            let fresh = self
                .slot
                .take_until(start + pacer.wait_until(start.elapsed(), period));
            let taken = Instant::now();
            let replaced_now = self.slot.stats().dropped;
            let replaced = std::mem::replace(&mut replaced_then, replaced_now) != replaced_now;
            let signal = self.slot.silence().is_some_and(|s| s < SIGNAL_TIMEOUT);
            if fresh.is_some() && self.source_error().is_some() {
                self.set_source_error(None);
                info!("source: frames again");
            }
            let is_fresh = fresh.is_some();
            if let Some((f, _)) = &fresh {
                self.observe_exposure(f, &state);
            }
            // A fresh frame's way out, stamped stage by stage.
            let mut stamps = fresh.as_ref().map(|(f, arrived)| {
                let now = clock_us();
                Stamps {
                    captured: f.captured_us,
                    arrived: now.saturating_sub(arrived.elapsed().as_micros() as u64),
                    taken: now,
                    ..Stamps::default()
                }
            });
            let arrived = fresh.map(|(f, arrived)| {
                last_frame = Some(f);
                arrived.saturating_duration_since(start)
            });
            pacer.taken(due, arrived, replaced, start.elapsed(), period);
            // A view steered, or the objects the tiles follow changed.
            let moved = !shown
                .as_ref()
                .is_some_and(|(s, t)| Arc::ptr_eq(s, &settings) && Arc::ptr_eq(t, &tracked));
            if !pacer.worth_rendering(is_fresh, signal, moved, start.elapsed()) {
                continue;
            }
            shown = Some((settings, tracked));
            let pts = pacer.pts(start.elapsed());
            let t0 = Instant::now();
            // The state and lens the frame was rendered with and its capture time, for the
            // views alone.
            let mut framed = None;
            let mut klv = None;
            let rendered = match (&last_frame, signal) {
                (Some(frame), true) => self.render(&mut renderer, frame, &state, pts).map(|r| {
                    framed = Some(Framed {
                        state: r.state,
                        lens: r.lens,
                        unix_us: r.unix_us,
                        shutter: r.shutter,
                    });
                    klv = r.klv;
                    (r.data, r.layout)
                }),
                _ => {
                    stamps = None;
                    Ok(no_signal::frame(
                        state.settings.output.width,
                        state.settings.output.height,
                    ))
                }
            };
            let (data, layout) = match rendered {
                Ok(r) => r,
                Err(RenderFailure::Frame(e)) => {
                    warn!("frame not rendered: {e}");
                    continue;
                }
                Err(RenderFailure::Gpu(e)) => {
                    // The GPU failed: say so, start a new device and renderer, go on.
                    error!("GPU: {e}; rebuilding the renderer");
                    self.report.set_failure(Failure::Gpu);
                    healthy = Some(false);
                    std::thread::sleep(Duration::from_secs(1));
                    match Gpu::new().and_then(|g| self.renderer(&g)) {
                        Ok(r) => renderer = r,
                        Err(e) => error!("GPU: {e}"),
                    }
                    views.reset_gpu();
                    scans.reset_gpu();
                    continue;
                }
            };
            self.stats
                .render_us
                .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
            self.stats.out.fetch_add(1, Ordering::Relaxed);
            if let Some(s) = &mut stamps {
                s.rendered = clock_us();
            }
            self.offer_still(&data, layout, last_frame.as_ref());
            if self.key_wanted.swap(false, Ordering::Relaxed) | self.capture.take_key_request() {
                encoder.force_key_unit();
            }
            let dropped_before = encoder.dropped;
            let side = Side { stamps, klv };
            if let Err(e) = encoder.push_with(data, &layout, pts, state.settings.output.fps, side) {
                error!("{e}; rebuilding the encoder");
                self.report.set_failure(Failure::Encoder);
                healthy = Some(false);
                drop(encoder);
                encoder = self.rebuild_encoder(state.settings.output.fps)?;
                continue;
            }
            self.stats
                .encoder_dropped
                .fetch_add(encoder.dropped - dropped_before, Ordering::Relaxed);
            let context = framed.as_ref();
            self.render_views(
                &mut views,
                &mut renderer,
                context,
                pts,
                state.settings.output.fps,
            );
            if let (Some(frame), Some(framed)) = (&last_frame, context) {
                self.offer_scan(&mut scans, &mut renderer, frame, framed);
            }
            views.frame_done(taken.elapsed());
            let now_ok = health(signal, self.source_error().is_some(), last_frame.is_some());
            if now_ok != healthy {
                match now_ok {
                    Some(true) => self.report.set_status(RunStatus::Running),
                    Some(false) => self.report.set_failure(Failure::Source),
                    None => {}
                }
                healthy = now_ok;
            }
        }
        drop(encoder);
        self.report.set_status(RunStatus::Finished);
        Ok(())
    }

    /// A new encoder after one failed, tried every half second until one starts or the
    /// head stops.
    fn rebuild_encoder(self: &Arc<Head>, fps: u32) -> Result<Encoder, HeadError> {
        loop {
            std::thread::sleep(Duration::from_millis(500));
            match self.encoder(fps) {
                Ok(e) => return Ok(e),
                Err(e) if !self.stop.load(Ordering::Relaxed) => error!("{e}"),
                Err(e) => return Err(e),
            }
        }
    }

    /// Hands the rendered frame (and the fisheye frame, if the capture wants it) over as a
    /// still when one was asked for.
    fn offer_still(&self, data: &[u8], layout: PlaneLayout, fisheye: Option<&Frame>) {
        if !self.capture.take_still_request() {
            return;
        }
        let raw = match (fisheye, self.capture.wants_raw()) {
            (Some(f), true) => Some((f.data.clone(), f.layout)),
            _ => None,
        };
        self.capture.save_still(Still {
            output: (data.to_vec(), layout),
            raw,
        });
    }

    /// The rolling shutter's table of a frame whose middle row was read at `middle_us`, the
    /// vehicle turning as the telemetry has it (None for a global shutter).
    fn shutter(&self, s: &State, lens: &Lens, middle_us: u64) -> Option<ShutterTable> {
        let (middle, mount) = (s.vehicle.attitude.euler(), s.settings.mount.euler());
        let at = |dt_us: f64| {
            let t = middle_us.saturating_add_signed(dt_us.round() as i64);
            let attitude = self.telemetry.at(t).0.unwrap_or(middle);
            lens_from_world(attitude, mount)
        };
        ShutterTable::new(&self.cfg.readout, (lens.width, lens.height), at)
    }

    /// Renders `frame`, shown at `pts` in the composed stream, with `state`, the vehicle as the
    /// telemetry had it at capture time; also gives that state, the lens at the frame's size
    /// and the KLV packet of the view `klv_camera` in it.
    fn render(
        &self,
        renderer: &mut Renderer,
        frame: &Frame,
        state: &State,
        pts: Duration,
    ) -> Result<Rendered, RenderFailure> {
        let mut s = state.clone();
        // A rolling shutter's frame is drawn as its middle row saw the world.
        let middle_us = self.cfg.readout.middle_after_stamp_us().round() as i64;
        let middle_us = frame.captured_us.saturating_add_signed(middle_us);
        let (attitude, position) = self.telemetry.at(middle_us);
        if let Some(a) = attitude {
            (
                s.vehicle.attitude.yaw,
                s.vehicle.attitude.pitch,
                s.vehicle.attitude.roll,
            ) = (a.yaw, a.pitch, a.roll);
        }
        if let Some(p) = position {
            s.vehicle.position = p;
        }
        // Tiles, and views that follow an object, follow it between scans.
        s.moved_on_to(frame.captured_us);
        let size = (frame.layout.width, frame.layout.height);
        let lens = self
            .gate
            .settings()
            .lenses()
            .for_frame(s.settings.lens, size, s.settings.sensor.roi())
            .map_err(|e| RenderFailure::Frame(e.to_string()))?;
        let shutter = self.shutter(&s, &lens, middle_us);
        // What the web page and the services draw over this frame is placed with these.
        let drawn = shutter.clone().map(|t| (t, (lens.width, lens.height)));
        self.report.set_rendered(RenderedFrame {
            captured_us: frame.captured_us,
            pts_us: pts.as_micros() as u64,
            vehicle: s.vehicle,
            shutter: drawn,
        });
        let plan = FramePlan::new(&s, &lens)
            .map_err(|e| RenderFailure::Frame(e.to_string()))?
            .with_shutter(shutter.clone());
        let camera = (&lens, s.settings.mount.euler());
        self.readout_probe
            .offer(frame, camera, self.cfg.readout, &self.telemetry);
        let truth = self.demo_truth.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(truth) = truth.as_ref() {
            let mut shared = self.demo_score.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(score) = shared.as_mut() {
                rings(&mut score.rings, truth, (&plan, &s), frame.captured_us);
            }
        }
        drop(truth);
        let out = renderer
            .render(&frame.data, &frame.layout, &plan)
            .map_err(|e| match e {
                GpuError::Failed(_) | GpuError::Device { .. } => RenderFailure::Gpu(e.to_string()),
                other => RenderFailure::Frame(other.to_string()),
            })?;
        let cam = self.cfg.klv_camera;
        let time_us = unix_us(frame.captured_us);
        let klv = ViewMetadata::of_camera(&plan, &s, cam, time_us).map(|m| {
            let m = m.with_objects(self.cfg.klv_objects);
            let packet = m.packet().into();
            *self.klv.lock().unwrap_or_else(|e| e.into_inner()) = Some(m);
            packet
        });
        Ok(Rendered {
            data: out.data,
            layout: out.layout,
            state: s,
            lens,
            unix_us: time_us,
            klv,
            shutter,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::health;

    #[test]
    fn the_status_is_running_with_frames_error_once_the_source_fails_and_idle_before_any() {
        assert_eq!(health(true, false, true), Some(true));
        assert_eq!(health(false, false, true), Some(false), "silent");
        assert_eq!(health(true, true, true), Some(false), "failed");
        assert_eq!(health(false, true, false), Some(false), "failed first");
        assert_eq!(
            health(false, false, false),
            None,
            "waiting for the first frame"
        );
    }
}
