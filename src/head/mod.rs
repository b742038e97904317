//! The video head: source → upload → GPU render → readback → H.264 → RTSP (and recording),
//! frame after frame. A source thread puts frames in a newest-wins slot; the frame loop takes
//! the newest, renders it with the live state and the attitude at its capture time, and feeds
//! the encoder, whose access units go to the RTSP clients and the recorder. Output size and
//! rate follow the live state's VIDEO_OUTPUT at each frame. A failed source is retried with
//! back-off while a "no signal" frame is streamed; a failed encoder or GPU is rebuilt.

pub mod capture;
pub mod config;
mod no_signal;
pub mod telemetry;

use crate::control::live::{Failure, Live, RunStatus};
use crate::render::gpu::{Gpu, GpuError, Renderer};
use crate::render::{Filter, FramePlan, PixelFormat, PlaneLayout};
use crate::source::demo::{DemoCamera, Flight};
use crate::source::{Ended, Frame, FrameSlot, SourceSpec, backoff, clock_us};
use crate::stream::encoder::AccessUnit;
use crate::stream::{Encoder, Rtsp};
use capture::{Capture, Still};
use config::Config;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use telemetry::Telemetry;
use tracing::{error, info, warn};

/// A source silent for this long is gone: the stream shows "no signal".
const SIGNAL_TIMEOUT: Duration = Duration::from_secs(1);

/// Shared by the head's threads.
pub struct Head {
    pub cfg: Config,
    pub live: Arc<Live>,
    pub capture: Arc<Capture>,
    pub telemetry: Arc<Telemetry>,
    pub rtsp: Arc<Rtsp>,
    pub slot: Arc<FrameSlot>,
    pub stop: Arc<AtomicBool>,
    /// Set by the RTSP server when a client joins: the encoder owes it a key frame.
    pub key_wanted: Arc<AtomicBool>,
    /// Why the source is down, while it is.
    source_error: Mutex<Option<String>>,
    stats: Stats,
}

#[derive(Default)]
struct Stats {
    out: AtomicU64,
    encoder_dropped: AtomicU64,
    render_us: AtomicU64,
    encode_us: AtomicU64,
    encoded: AtomicU64,
}

impl Head {
    pub fn new(
        cfg: Config,
        live: Arc<Live>,
        capture: Arc<Capture>,
        rtsp: Arc<Rtsp>,
        key_wanted: Arc<AtomicBool>,
    ) -> Arc<Head> {
        Arc::new(Head {
            cfg,
            live,
            capture,
            telemetry: Arc::default(),
            rtsp,
            slot: Arc::default(),
            stop: Arc::default(),
            key_wanted,
            source_error: Mutex::new(None),
            stats: Stats::default(),
        })
    }

    /// Runs the source thread, the health log and the frame loop until `stop` is set.
    pub fn run(self: &Arc<Head>) -> Result<(), String> {
        let spec: SourceSpec = self.cfg.source.parse()?;
        let source = {
            let head = self.clone();
            std::thread::Builder::new()
                .name("source".into())
                .spawn(move || head.source_thread(spec))
                .map_err(|e| e.to_string())?
        };
        let health = {
            let head = self.clone();
            std::thread::Builder::new()
                .name("health".into())
                .spawn(move || head.health_thread())
                .map_err(|e| e.to_string())?
        };
        let result = self.frame_loop();
        self.stop.store(true, Ordering::Relaxed);
        self.capture.finish();
        let _ = source.join();
        let _ = health.join();
        result
    }

    fn set_source_error(&self, e: Option<String>) {
        *self.source_error.lock().unwrap_or_else(|e| e.into_inner()) = e;
    }

    fn source_thread(&self, spec: SourceSpec) {
        if spec == SourceSpec::Demo {
            if let Err(e) = self.demo_source() {
                error!("demo source: {e}");
                self.set_source_error(Some(e));
            }
            return;
        }
        let mut attempt = 0;
        while !self.stop.load(Ordering::Relaxed) {
            let outcome = crate::source::open(
                &spec,
                self.cfg.source_fps,
                self.cfg.source_loop,
                self.slot.clone(),
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
                .slot
                .silence()
                .is_some_and(|s| s < Duration::from_secs(5))
            {
                attempt = 0;
            }
            let wait = backoff(attempt);
            attempt += 1;
            error!("source {spec} failed: {e}; retrying in {wait:?}");
            self.set_source_error(Some(format!("camera gone: {e}")));
            let until = Instant::now() + wait;
            while Instant::now() < until && !self.stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }

    fn demo_source(&self) -> Result<(), String> {
        let d = &self.cfg.demo;
        let state = self.live.snapshot();
        let lens = self
            .live
            .lens_for_frame(&state, d.width, d.height)
            .ok_or("the state's lens is not in lens.cal")?;
        let layout = PlaneLayout::tight(d.format, d.width, d.height).map_err(|e| e.to_string())?;
        let camera = DemoCamera::new(&lens, layout, state.mount.euler());
        let flight = Flight {
            hover: state.vehicle.position,
            attitude: state.vehicle.attitude.euler(),
            motion: d.motion,
            radius: 30.0,
            lap: 90.0,
        };
        info!(
            "source: demo, {}x{} {} at {} fps, {}",
            d.width,
            d.height,
            d.format,
            d.fps,
            if d.motion {
                "flying a circle"
            } else {
                "hovering"
            }
        );
        let period = Duration::from_secs_f64(1.0 / d.fps as f64);
        let start = Instant::now();
        let mut next = start;
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
            if self.slot.pending() {
                // The renderer has not taken the last frame: a simulated camera need not
                // spend the CPU the renderer needs on a frame that would be dropped.
                continue;
            }
            let captured_us = clock_us();
            let t = start.elapsed().as_secs_f64();
            let (attitude, position) = flight.pose(t);
            self.telemetry.attitude(captured_us, attitude);
            self.telemetry.position(position);
            let stamp = d.stamp.then_some((captured_us / 1000) as u32);
            let data = camera.frame(attitude, &position, t, stamp);
            self.slot.put(Frame {
                data,
                layout,
                captured_us,
            });
        }
        Ok(())
    }

    fn health_thread(&self) {
        let every = self.cfg.health_interval_s;
        if every <= 0.0 {
            return;
        }
        let every = Duration::from_secs_f64(every);
        let mut last = (Instant::now(), self.slot.stats(), 0u64, 0u64, 0u64, 0u64);
        let mut next = Instant::now() + every;
        while !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
            if Instant::now() < next {
                continue;
            }
            next += every;
            let s = &self.stats;
            let now = (
                Instant::now(),
                self.slot.stats(),
                s.out.load(Ordering::Relaxed),
                s.render_us.load(Ordering::Relaxed),
                s.encoded.load(Ordering::Relaxed),
                s.encode_us.load(Ordering::Relaxed),
            );
            let secs = (now.0 - last.0).as_secs_f64();
            let out = now.2 - last.2;
            let encoded = now.4 - last.4;
            info!(
                "health: in {:.1} fps, out {:.1} fps, dropped {} (renderer behind) + {} \
                 (encoder behind), render {:.1} ms, encode {:.1} ms, {} clients{}",
                (now.1.received - last.1.received) as f64 / secs,
                out as f64 / secs,
                now.1.dropped - last.1.dropped,
                s.encoder_dropped.load(Ordering::Relaxed),
                (now.3 - last.3) as f64 / 1000.0 / out.max(1) as f64,
                (now.5 - last.5) as f64 / 1000.0 / encoded.max(1) as f64,
                self.rtsp.clients(),
                match &*self.source_error.lock().unwrap_or_else(|e| e.into_inner()) {
                    Some(e) => format!(", source down: {e}"),
                    None => String::new(),
                }
            );
            last = now;
        }
    }

    /// The encoder's sink: every access unit to the clients and the recording.
    fn encoder(self: &Arc<Head>, fps: u32) -> Result<Encoder, String> {
        let head = self.clone();
        Encoder::new(&self.cfg.encoder, fps, move |au: AccessUnit| {
            head.rtsp.push(&au.buffer);
            head.capture.on_access_unit(&au);
            if let Some(t) = au.encode_time {
                head.stats.encoded.fetch_add(1, Ordering::Relaxed);
                head.stats
                    .encode_us
                    .fetch_add(t.as_micros() as u64, Ordering::Relaxed);
            }
        })
    }

    /// The stream's renderer: I420 out, mip filtering, ready from its first frame for a
    /// LENS SET to any lens of lens.cal.
    fn renderer(&self, gpu: &Gpu) -> Result<Renderer, GpuError> {
        let mut renderer = Renderer::new(gpu, PixelFormat::I420, Filter::Mip)?;
        renderer.expect_lens_models(self.live.lens_models());
        Ok(renderer)
    }

    fn frame_loop(self: &Arc<Head>) -> Result<(), String> {
        let gpu = Gpu::new().map_err(|e| e.to_string())?;
        let mut renderer = self.renderer(&gpu).map_err(|e| e.to_string())?;
        let mut encoder = self.encoder(self.live.snapshot().output.fps)?;
        let start = Instant::now();
        let mut last_frame: Option<Frame> = None;
        let mut next_due = Instant::now();
        let mut last_pts = Duration::ZERO;
        // The state of the last frame rendered.
        let mut shown: Option<Arc<crate::state::State>> = None;
        // The status last reported: None idle, Some(running or not).
        let mut healthy: Option<bool> = None;
        while !self.stop.load(Ordering::Relaxed) {
            let state = self.live.snapshot();
            let period = Duration::from_secs_f64(1.0 / state.output.fps as f64);
            // Pacing: frames go out a period apart. A frame that was waiting when its turn came
            // keeps that steady beat; one that came in late sets the beat from its arrival, so
            // the loop locks onto a source of the same rate and frames wait little. With no
            // new frame by half a period past due, the last one is shown again (views may have
            // moved), or "no signal" once the source has been silent for a second.
            let due = next_due;
            let now = Instant::now();
            if now < due {
                std::thread::sleep(due - now);
            }
            let fresh = self.slot.take_until(due.max(Instant::now()) + period / 2);
            let signal = self.slot.silence().is_some_and(|s| s < SIGNAL_TIMEOUT);
            let recovered = fresh.is_some()
                && self
                    .source_error
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .take()
                    .is_some();
            if recovered {
                info!("source: frames again");
            }
            let now = Instant::now();
            let is_fresh = fresh.is_some();
            next_due = match fresh {
                Some((f, arrived)) => {
                    last_frame = Some(f);
                    if arrived <= due {
                        due + period
                    } else {
                        arrived + period * 9 / 10
                    }
                }
                None => now + period / 2,
            }
            // Never more than a period behind: a slow frame does not cause a burst.
            .max(now - period.min(now - start));
            // Showing the last frame again is worth its render only when the views moved (or
            // once a second, to keep decoders fed): otherwise it would only delay the next
            // fresh frame.
            let repeat = !is_fresh && signal;
            let moved = !shown.as_ref().is_some_and(|s| Arc::ptr_eq(s, &state));
            if repeat && !moved && last_pts + Duration::from_secs(1) > start.elapsed() {
                continue;
            }
            shown = Some(state.clone());
            let pts = start.elapsed().max(last_pts + Duration::from_millis(1));
            last_pts = pts;
            let t0 = Instant::now();
            let rendered = match (&last_frame, signal) {
                (Some(frame), true) => self.render(&mut renderer, frame, &state),
                _ => Ok(no_signal::frame(state.output.width, state.output.height)),
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
                    self.live.set_failure(Failure::Gpu);
                    healthy = Some(false);
                    std::thread::sleep(Duration::from_secs(1));
                    match Gpu::new().and_then(|g| self.renderer(&g)) {
                        Ok(r) => renderer = r,
                        Err(e) => error!("GPU: {e}"),
                    }
                    continue;
                }
            };
            self.stats
                .render_us
                .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
            self.stats.out.fetch_add(1, Ordering::Relaxed);
            if self.capture.take_still_request() {
                let raw = match (&last_frame, self.capture.wants_raw()) {
                    (Some(f), true) => Some((f.data.clone(), f.layout)),
                    _ => None,
                };
                self.capture.save_still(Still {
                    output: (data.clone(), layout),
                    raw,
                });
            }
            if self.key_wanted.swap(false, Ordering::Relaxed) | self.capture.take_key_request() {
                encoder.force_key_unit();
            }
            let dropped_before = encoder.dropped;
            if let Err(e) = encoder.push(data, &layout, pts, state.output.fps) {
                error!("{e}; rebuilding the encoder");
                self.live.set_failure(Failure::Encoder);
                healthy = Some(false);
                drop(encoder);
                encoder = loop {
                    std::thread::sleep(Duration::from_millis(500));
                    match self.encoder(state.output.fps) {
                        Ok(e) => break e,
                        Err(e) if !self.stop.load(Ordering::Relaxed) => error!("{e}"),
                        Err(e) => return Err(e),
                    }
                };
                continue;
            }
            self.stats
                .encoder_dropped
                .fetch_add(encoder.dropped - dropped_before, Ordering::Relaxed);
            // Running with frames; error once the source failed or went silent; idle while
            // the first frame is awaited.
            let failed = self
                .source_error
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .is_some();
            let now_ok = match (signal && !failed, failed || last_frame.is_some()) {
                (true, _) => Some(true),
                (false, true) => Some(false),
                (false, false) => None,
            };
            if now_ok != healthy {
                match now_ok {
                    Some(true) => self.live.set_status(RunStatus::Running),
                    Some(false) => self.live.set_failure(Failure::Source),
                    None => {}
                }
                healthy = now_ok;
            }
        }
        drop(encoder);
        self.live.set_status(RunStatus::Finished);
        Ok(())
    }

    /// Renders `frame` with `state`, the vehicle as the telemetry had it at capture time.
    fn render(
        &self,
        renderer: &mut Renderer,
        frame: &Frame,
        state: &crate::state::State,
    ) -> Result<(Vec<u8>, PlaneLayout), RenderFailure> {
        let mut s = state.clone();
        let (attitude, position) = self.telemetry.at(frame.captured_us);
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
        let lens = self
            .live
            .lens_for_frame(&s, frame.layout.width, frame.layout.height)
            .ok_or_else(|| RenderFailure::Frame("the state's lens is not in lens.cal".into()))?;
        let plan = FramePlan::new(&s, &lens).map_err(|e| RenderFailure::Frame(e.to_string()))?;
        let out = renderer
            .render(&frame.data, &frame.layout, &plan)
            .map_err(|e| match e {
                GpuError::Failed(_) | GpuError::Device { .. } => RenderFailure::Gpu(e.to_string()),
                other => RenderFailure::Frame(other.to_string()),
            })?;
        Ok((out.data, out.layout))
    }
}

/// Why a frame was not rendered: the GPU failed (rebuild it), or this frame or state cannot
/// be rendered (skip it, say why).
enum RenderFailure {
    Gpu(String),
    Frame(String),
}
