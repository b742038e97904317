//! The frame loop: paced by [`Pacer`], it takes the newest frame from the slot, renders it
//! with the live state and the vehicle as the telemetry had it at capture time (or streams
//! "no signal" while the source is down), hands stills to the capture, and feeds the
//! encoder. A failed GPU or encoder is rebuilt and the status says so meanwhile.

use super::pacing::Pacer;
use super::views::{Framed, ViewOutputs};
use super::{Head, HeadError, no_signal, parts};
use crate::clock::{Stamps, clock_us, unix_us};
use crate::frame::{Frame, PixelFormat, PlaneLayout};
use crate::geometry::lens_from_world;
use crate::geometry::shutter::ShutterTable;
use crate::head::capture::Still;
use crate::lens::Lens;
use crate::plan::{Filter, FramePlan};
use crate::render::choose;
use crate::render::gpu::{Gpu, GpuError, Renderer};
use crate::state::{Failure, RenderedFrame, RunStatus, Settings, State, Tracked};
use crate::stream::Encoder;
use crate::stream::encoder::{AccessUnit, Side};
use crate::stream::klv::ViewMetadata;
use crate::supervise::{self, Backoff, Fault, Locked};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

/// A source silent for this long is gone: the stream shows "no signal".
const SIGNAL_TIMEOUT: Duration = Duration::from_secs(1);
/// How a failed encoder is built again (`rebuild_encoder`).
const ENCODER_RETRY: Backoff = Backoff::new(Duration::from_millis(500), Duration::from_secs(4));

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

/// What the frame loop keeps from one frame to the next.
struct Looping {
    renderer: Renderer,
    views: ViewOutputs,
    scans: super::detection::ScanRenderer,
    encoder: Encoder,
    start: Instant,
    pacer: Pacer,
    last_frame: Option<Frame>,
    /// The settings and objects of the last frame rendered.
    shown: Option<(Arc<Settings>, Arc<Vec<Tracked>>)>,
    /// The status last reported: None idle, Some(running or not).
    healthy: Option<bool>,
    /// Frames the source replaced in the slot before they were taken, as of the last take.
    replaced_then: u64,
}

/// A frame due out: the state it is drawn with, its presentation time, when the frame loop
/// took it, whether the source is live, and a fresh frame's stamps.
struct Turn {
    state: State,
    pts: Duration,
    taken: Instant,
    signal: bool,
    stamps: Option<Stamps>,
}

/// A picture drawn: its bytes, what it was drawn with (for the views alone), its KLV.
type Drawn = (Vec<u8>, PlaneLayout, Option<Framed>, Option<Arc<[u8]>>);

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
            head.meters.stats.units.fetch_add(1, Ordering::Relaxed);
            head.outputs.clients.push(&au.buffer);
            head.outputs.preview.push(&au);
            head.outputs.capture.on_access_unit(&au);
            for p in &head.outputs.publishers {
                if p.push(&au) {
                    head.outputs.key_wanted.store(true, Ordering::Relaxed);
                }
            }
            if let Some(s) = au.stamps {
                head.meters.latency.record(Stamps {
                    sent: clock_us(),
                    ..s
                });
            }
            if let Some(t) = au.encode_time {
                head.meters.stats.encoded.fetch_add(1, Ordering::Relaxed);
                head.meters
                    .stats
                    .encode_us
                    .fetch_add(t.as_micros() as u64, Ordering::Relaxed);
            }
        })?;
        Ok(encoder)
    }

    /// Opens the adapter the configured backend chooses (`render::choose`) and says which,
    /// and why, in the health figures.
    fn open_gpu(&self) -> Result<Gpu, GpuError> {
        let chosen = choose::open(self.cfg.gpu_backend)?;
        *self.meters.gpu.locked() = Some(chosen.choice);
        Ok(chosen.gpu)
    }

    /// The stream's renderer: I420 out, mip filtering, ready from its first frame for a LENS
    /// SET to any lens of lens.cal of the source's kind (single or pair; not the other's).
    pub(super) fn renderer(&self, gpu: &Gpu) -> Result<Renderer, GpuError> {
        let mut renderer = Renderer::new(gpu, PixelFormat::I420, Filter::Mip)?;
        let lenses = self.gate.settings().lenses();
        let pair = lenses
            .get(self.settings().lens)
            .is_some_and(|l| l.pair.is_some());
        renderer.expect_lenses(lenses.all().filter(|l| l.pair.is_some() == pair));
        Ok(renderer)
    }

    pub(super) fn frame_loop(self: &Arc<Head>) -> Result<(), HeadError> {
        let mut l = Looping {
            renderer: self.renderer(&self.open_gpu()?)?,
            views: ViewOutputs::default(),
            scans: super::detection::ScanRenderer::default(),
            encoder: self.encoder(self.settings().output.fps)?,
            start: Instant::now(),
            pacer: Pacer::default(),
            last_frame: None,
            shown: None,
            healthy: None,
            replaced_then: self.input.slot.stats().dropped,
        };
        let fault = Fault::at_every_start("frames");
        while !self.stop.load(Ordering::Relaxed) {
            fault.check("frames");
            if let Some(turn) = self.next_turn(&mut l) {
                self.draw_turn(&mut l, turn)?;
            }
        }
        drop(l.encoder);
        self.report.set_status(RunStatus::Finished);
        Ok(())
    }

    /// Waits for the next beat and takes the newest frame: the turn to draw, or None when
    /// drawing the last frame again would show nothing new.
    fn next_turn(&self, l: &mut Looping) -> Option<Turn> {
        let sensed = self.gate.sensed();
        let (settings, tracked) = (self.settings(), sensed.tracked());
        let state = State::of(&settings, sensed.vehicle(), &tracked);
        let period = Duration::from_secs_f64(1.0 / state.settings.output.fps as f64);
        let due = l.pacer.due();
        if let Some(early) = due.checked_sub(l.start.elapsed()) {
            std::thread::sleep(early);
        }
        let fresh = self
            .input
            .slot
            .take_until(l.start + l.pacer.wait_until(l.start.elapsed(), period));
        // A frame the lens cannot see is no signal, and the last one goes with it.
        let fresh = match fresh {
            Some((f, _)) if !self.frame_fits(&f, &state) => {
                l.last_frame = None;
                None
            }
            fresh => fresh,
        };
        let taken = Instant::now();
        let replaced_now = self.input.slot.stats().dropped;
        let replaced = std::mem::replace(&mut l.replaced_then, replaced_now) != replaced_now;
        // A frame just taken is signal, however long ago it was put (a loop a second late
        // drew "no signal" over a live camera's frame); the slot's silence starts at a take.
        let signal = fresh.is_some()
            || self
                .input
                .slot
                .silence()
                .is_some_and(|s| s < SIGNAL_TIMEOUT);
        if fresh.is_some() && self.source_error().is_some() {
            self.set_source_error(None);
            info!("source: frames again");
        }
        let is_fresh = fresh.is_some();
        if let Some((f, _)) = &fresh {
            self.observe_exposure(f, &state);
        }
        // A fresh frame's way out, stamped stage by stage.
        let stamps = fresh.as_ref().map(|(f, arrived)| {
            let now = clock_us();
            Stamps {
                captured: f.captured_us,
                arrived: now.saturating_sub(arrived.elapsed().as_micros() as u64),
                taken: now,
                ..Stamps::default()
            }
        });
        let arrived = fresh.map(|(f, arrived)| {
            l.last_frame = Some(f);
            arrived.saturating_duration_since(l.start)
        });
        l.pacer
            .taken(due, arrived, replaced, l.start.elapsed(), period);
        // A view steered, or the objects the tiles follow changed.
        let moved = !l
            .shown
            .as_ref()
            .is_some_and(|(s, t)| Arc::ptr_eq(s, &settings) && Arc::ptr_eq(t, &tracked));
        if !l
            .pacer
            .worth_rendering(is_fresh, signal, moved, l.start.elapsed())
        {
            return None;
        }
        l.shown = Some((settings, tracked));
        let pts = l.pacer.pts(l.start.elapsed());
        Some(Turn {
            state,
            pts,
            taken,
            signal,
            stamps,
        })
    }

    /// Draws a turn's frame (or "no signal"), hands it to the encoder, then draws the views
    /// and the scans from it and says how the head fares.
    fn draw_turn(self: &Arc<Head>, l: &mut Looping, mut turn: Turn) -> Result<(), HeadError> {
        let t0 = Instant::now();
        let Some((data, layout, framed, klv)) = self.drawn(l, &mut turn) else {
            return Ok(());
        };
        self.meters
            .stats
            .render_us
            .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
        self.meters.stats.out.fetch_add(1, Ordering::Relaxed);
        if let Some(s) = &mut turn.stamps {
            s.rendered = clock_us();
        }
        self.offer_still(&data, layout, l.last_frame.as_ref());
        let fps = turn.state.settings.output.fps;
        if !self.encode(
            l,
            (data, layout),
            turn.pts,
            fps,
            Side {
                stamps: turn.stamps,
                klv,
            },
        )? {
            return Ok(());
        }
        let context = framed.as_ref();
        self.render_views(&mut l.views, &mut l.renderer, context, turn.pts, fps);
        if let (Some(frame), Some(framed)) = (&l.last_frame, context) {
            self.offer_scan(&mut l.scans, &mut l.renderer, frame, framed);
        }
        l.views.frame_done(turn.taken.elapsed());
        let now_ok = health(
            turn.signal,
            self.source_error().is_some(),
            l.last_frame.is_some(),
        );
        if now_ok != l.healthy {
            match now_ok {
                Some(true) => self.report.set_status(RunStatus::Running),
                Some(false) => self.report.set_failure(Failure::Source),
                None => {}
            }
            l.healthy = now_ok;
        }
        Ok(())
    }

    /// The turn's picture: the last frame rendered, or "no signal" while the source is
    /// silent; with what it was drawn with and its KLV. None when nothing was drawn (a frame
    /// that cannot be, or a GPU that failed and is being rebuilt).
    fn drawn(&self, l: &mut Looping, turn: &mut Turn) -> Option<Drawn> {
        let rendered = match (&l.last_frame, turn.signal) {
            (Some(frame), true) => self.render(&mut l.renderer, frame, &turn.state, turn.pts),
            _ => {
                turn.stamps = None;
                let out = &turn.state.settings.output;
                let (data, layout) = no_signal::frame(out.width, out.height);
                return Some((data, layout, None, None));
            }
        };
        match rendered {
            Ok(r) => {
                let framed = Framed {
                    state: r.state,
                    lens: r.lens,
                    unix_us: r.unix_us,
                    shutter: r.shutter,
                };
                Some((r.data, r.layout, Some(framed), r.klv))
            }
            Err(RenderFailure::Frame(e)) => {
                warn!("frame not rendered: {e}");
                None
            }
            Err(RenderFailure::Gpu(e)) => {
                // The GPU failed: say so, start a new device and renderer, go on.
                error!("GPU: {e}; rebuilding the renderer");
                self.report.set_failure(Failure::Gpu);
                l.healthy = Some(false);
                std::thread::sleep(Duration::from_secs(1));
                match self.open_gpu().and_then(|g| self.renderer(&g)) {
                    Ok(r) => l.renderer = r,
                    Err(e) => error!("GPU: {e}"),
                }
                l.views.reset_gpu();
                l.scans.reset_gpu();
                None
            }
        }
    }

    /// Hands a picture to the encoder; false when the encoder failed and was rebuilt (the
    /// picture is lost, the status says so meanwhile).
    fn encode(
        self: &Arc<Head>,
        l: &mut Looping,
        (data, layout): (Vec<u8>, PlaneLayout),
        pts: Duration,
        fps: u32,
        side: Side,
    ) -> Result<bool, HeadError> {
        if self.outputs.key_wanted.swap(false, Ordering::Relaxed)
            | self.outputs.capture.take_key_request()
        {
            l.encoder.force_key_unit();
        }
        let dropped_before = l.encoder.dropped;
        if let Err(e) = l.encoder.push_with(data, &layout, pts, fps, side) {
            error!("{e}; rebuilding the encoder");
            self.report.set_failure(Failure::Encoder);
            l.healthy = Some(false);
            l.encoder = self.rebuild_encoder(fps)?;
            return Ok(false);
        }
        self.meters
            .stats
            .encoder_dropped
            .fetch_add(l.encoder.dropped - dropped_before, Ordering::Relaxed);
        Ok(true)
    }

    /// A new encoder after one failed, tried by the one back-off (half a second, doubling to
    /// 4 s) until one starts or the head stops: its wait ends when the head stops, and an
    /// encoder that keeps failing is logged three times, then once a minute or so.
    fn rebuild_encoder(self: &Arc<Head>, fps: u32) -> Result<Encoder, HeadError> {
        let mut backoff = ENCODER_RETRY;
        loop {
            supervise::sleep_unless(&self.stop, backoff.failed());
            match self.encoder(fps) {
                Ok(e) => return Ok(e),
                Err(e) if self.stop.load(Ordering::Relaxed) => return Err(e),
                Err(e) if backoff.worth_logging() => error!("{e}"),
                Err(_) => {}
            }
        }
    }

    /// Hands the rendered frame (and the fisheye frame, if the capture wants it) over as a
    /// still when one was asked for.
    fn offer_still(&self, data: &[u8], layout: PlaneLayout, fisheye: Option<&Frame>) {
        if !self.outputs.capture.take_still_request() {
            return;
        }
        let raw = match (fisheye, self.outputs.capture.wants_raw()) {
            (Some(f), true) => Some((f.data.clone(), f.layout)),
            _ => None,
        };
        self.outputs.capture.save_still(Still {
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
        self.vehicle_at(&mut s, middle_us);
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
        let cameras = (0..plan.layout.views.len()).filter(|&i| plan.shows_camera(i));
        let layer = self.thermal_layer(&s, &plan, cameras.map(|i| (i, i)));
        let plan = plan.with_thermal(layer);
        let seen = parts::Seen {
            frame,
            plan: &plan,
            state: &s,
            lens: &lens,
        };
        self.observers
            .frame_planned(&seen, self.cfg.readout, &self.telemetry);
        let out = renderer
            .render(&frame.data, &frame.layout, &plan)
            .map_err(|e| match e {
                GpuError::Failed(_) | GpuError::Device { .. } => RenderFailure::Gpu(e.to_string()),
                other => RenderFailure::Frame(other.to_string()),
            })?;
        *self.meters.lenses.locked() = renderer.lenses_matched();
        let cam = self.cfg.klv_camera;
        let time_us = unix_us(frame.captured_us);
        let klv = ViewMetadata::of_camera(&plan, &s, cam, time_us).map(|m| {
            let m = m.with_objects(self.cfg.klv_objects);
            let packet = m.packet().into();
            *self.observers.klv.locked() = Some(m);
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
mod tests;
