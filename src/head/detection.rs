//! The detection stage, beside the frame loop. At the scan rate, the frame loop renders the
//! scan views of the frame it has just rendered (same state, same lens, on a renderer of its
//! own) into one mosaic and hands it over, newest wins, to the detection thread; it never
//! waits for it. There the detector (the built-in motion detector on the scans' luma, or an
//! ONNX model on their colours, each view drawn at the model's input size) and the seed's
//! tracker run, and the tracked objects, those the tiles show first, go into the live state,
//! where the detection tiles and DETECTED_ROI read them. GENERAL_SETTINGS' run_ai turns it
//! on and off.

use super::Head;
use super::config::Detector;
use crate::detect::motion::MOVING;
use crate::detect::onnx::class_name;
use crate::detect::scan::{MOTION_VIEWS, ScanView, model_views, visible};
use crate::detect::{AngularBox, MotionDetector, OnnxDetector, OnnxError, Tracker};
use crate::frame::{Frame, PixelFormat};
use crate::geometry::GeoPoint;
use crate::geometry::ground::to_ned;
use crate::geometry::rotation::yaw_pitch;
use crate::layout::layout;
use crate::lens::Lens;
use crate::render::Filter;
use crate::render::FramePlan;
use crate::render::gpu::{Gpu, GpuError, Renderer};
use crate::state::{Invalid, State, Tracked};
use glam::DVec3;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// One scan, as the detection thread takes it.
pub(super) struct Scan {
    views: Vec<ScanView>,
    plan: FramePlan,
    /// The mosaic: I420 for the motion detector (its luma plane first), RGBA for a model.
    picture: Vec<u8>,
    stride: usize,
    /// The vehicle where the frame was captured, and when (seconds).
    position: crate::geometry::GeoPosition,
    t: f64,
}

/// The hand-over between the frame loop and the detection thread: the newest scan only.
#[derive(Default)]
pub(super) struct ScanSlot {
    scan: Mutex<Option<Scan>>,
    ready: Condvar,
}

/// What the frame loop keeps for the scans.
#[derive(Default)]
pub(super) struct ScanRenderer {
    renderer: Option<Renderer>,
    last: Option<Instant>,
}

impl ScanRenderer {
    /// Forgets the renderer (the GPU was rebuilt).
    pub(super) fn reset_gpu(&mut self) {
        self.renderer = None;
    }
}

/// The loaded ONNX model, and the side of the square pictures it takes (read by the frame
/// loop without waiting for the model).
pub(super) struct Model {
    side: u32,
    detector: Mutex<OnnxDetector>,
}

impl Head {
    /// Loads the ONNX model when the configuration chooses it: a missing model or ONNX
    /// Runtime is an error at start-up, not a silent stage.
    pub fn load_detector(&self) -> Result<(), OnnxError> {
        if self.cfg.detection.detector != Detector::Onnx || self.model.get().is_some() {
            return Ok(());
        }
        let cfg = self.cfg.detection.onnx();
        let detector = OnnxDetector::load(&cfg)?;
        info!(
            "detection: {} ({:?}, {}x{} input)",
            cfg.model.display(),
            cfg.decoder,
            detector.side(),
            detector.side()
        );
        let _ = self.model.set(Model {
            side: detector.side(),
            detector: Mutex::new(detector),
        });
        Ok(())
    }

    /// Whether the detector runs now.
    fn detecting(&self, state: &State) -> bool {
        let ready = match self.cfg.detection.detector {
            Detector::Motion => true,
            Detector::Onnx => self.model.get().is_some(),
            Detector::Off => false,
        };
        ready && state.detection.run_ai
    }

    /// The renderer for the scans: luma for the motion detector, colour for a model.
    fn scan_renderer(&self, gpu: &Gpu) -> Result<Renderer, GpuError> {
        if self.cfg.detection.detector != Detector::Onnx {
            return self.renderer(gpu);
        }
        let mut renderer = Renderer::new(gpu, PixelFormat::Rgba, Filter::Bilinear)?;
        renderer.expect_lens_models(self.live.lenses().models());
        Ok(renderer)
    }

    /// Renders the scan views of `frame` (rendered with `state` and `lens`) when a scan is
    /// due, and hands them to the detection thread.
    pub(super) fn offer_scan(
        &self,
        scans: &mut ScanRenderer,
        gpu: &Gpu,
        frame: &Frame,
        state: &State,
        lens: &Lens,
    ) {
        let period = Duration::from_secs_f64(1.0 / self.cfg.detection.scan_hz);
        if !self.detecting(state) || scans.last.is_some_and(|t| t.elapsed() < period) {
            return;
        }
        scans.last = Some(Instant::now());
        if scans.renderer.is_none() {
            match self.scan_renderer(gpu) {
                Ok(r) => scans.renderer = Some(r),
                Err(e) => return warn!("detection: no renderer for the scan: {e}"),
            }
        }
        let renderer = scans.renderer.as_mut().expect("made above");
        let to_lens = crate::geometry::view::lens_from_world(
            state.vehicle.attitude.euler(),
            state.mount.euler(),
        );
        let shape = self
            .model
            .get()
            .map_or(MOTION_VIEWS, |m| model_views(m.side));
        let (views, plan) = visible(lens, to_lens, shape);
        if views.is_empty() {
            return;
        }
        let t0 = Instant::now();
        let out = match renderer.render(&frame.data, &frame.layout, &plan) {
            Ok(out) => out,
            Err(e) => return warn!("detection: the scan did not render: {e}"),
        };
        self.stats
            .scan_us
            .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
        let scan = Scan {
            views,
            plan,
            stride: out.layout.stride as usize,
            picture: out.data,
            position: state.vehicle.position,
            t: frame.captured_us as f64 * 1e-6,
        };
        let slot = &self.scans;
        *slot.scan.lock().unwrap_or_else(|e| e.into_inner()) = Some(scan);
        slot.ready.notify_one();
    }

    /// The detection thread: takes each scan, detects, tracks, and publishes the objects.
    pub(super) fn detection_thread(self: &Arc<Head>) {
        if self.cfg.detection.detector == Detector::Off {
            return;
        }
        yield_to_video();
        let mut detector = MotionDetector::new();
        let mut tracker = Tracker::new();
        // The ground under the first position is the world's origin for the detector.
        let mut origin: Option<GeoPoint> = None;
        let mut owns_list = false;
        while !self.stop.load(Ordering::Relaxed) {
            let state = self.live.snapshot();
            if !self.detecting(&state) {
                if owns_list {
                    info!("detection: off (run_ai); its objects are dropped");
                    (detector, tracker, owns_list) = (MotionDetector::new(), Tracker::new(), false);
                    self.publish(vec![]);
                }
                std::thread::sleep(Duration::from_millis(100));
                continue;
            }
            let Some(scan) = self.next_scan() else {
                continue;
            };
            let t0 = Instant::now();
            let home = *origin.get_or_insert(GeoPoint {
                alt: scan.position.home_alt(),
                ..scan.position.point()
            });
            let eye: DVec3 = to_ned(home, scan.position.point());
            let found = match self.model.get() {
                Some(model) => {
                    let threshold = state.detection.var_confidence_threshold as f32;
                    let mut model = model.detector.lock().unwrap_or_else(|e| e.into_inner());
                    match model.scan(
                        &scan.views,
                        &scan.plan,
                        &scan.picture,
                        scan.stride,
                        threshold,
                    ) {
                        Ok(found) => found,
                        Err(e) => {
                            warn!("detection: {e}");
                            continue;
                        }
                    }
                }
                None => detector.detect(&scan.views, &scan.plan, &scan.picture, scan.stride, eye),
            };
            let covered = |b: &AngularBox| {
                scan.plan
                    .views
                    .iter()
                    .any(|v| scan.plan.view_point(v, b.centre).is_some())
            };
            tracker.scan(&state.detection, scan.t, found, covered);
            let o = &state.output;
            let shown = layout(o.width, o.height, o.layout, o.overlay).map_or(0, |l| l.tiles.len());
            let tiles = tracker.tiles(state.detection.sorting_mode, shown);
            self.publish(tracked(&tracker, &tiles, self.cfg.detection.detector));
            owns_list = true;
            self.stats
                .detect_us
                .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
            self.stats.scans.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The newest scan, waiting up to a tenth of a second for one.
    fn next_scan(&self) -> Option<Scan> {
        let slot = &self.scans;
        let guard = slot.scan.lock().unwrap_or_else(|e| e.into_inner());
        let (mut guard, _) = slot
            .ready
            .wait_timeout_while(guard, Duration::from_millis(100), |s| s.is_none())
            .unwrap_or_else(|e| e.into_inner());
        guard.take()
    }

    /// Puts the objects in the live state.
    fn publish(&self, list: Vec<Tracked>) {
        let result = self.live.update(|s| {
            s.tracked = list;
            Ok::<_, Invalid>(())
        });
        if let Err(e) = result {
            warn!("detection: the objects were not taken: {e}");
        }
    }
}

/// The tracker's objects as the state lists them: those in the tiles first, in tile order,
/// then the others by score.
fn tracked(tracker: &Tracker, tiles: &[Option<u32>], detector: Detector) -> Vec<Tracked> {
    let mut ids: Vec<u32> = tiles.iter().flatten().copied().collect();
    let mut rest: Vec<_> = tracker
        .objects()
        .iter()
        .filter(|o| !ids.contains(&o.id))
        .collect();
    rest.sort_by_key(|o| std::cmp::Reverse(o.score));
    ids.extend(rest.iter().map(|o| o.id));
    ids.iter()
        .filter_map(|&id| tracker.get(id))
        .map(|o| {
            let (yaw, pitch) = yaw_pitch(o.bbox.centre);
            Tracked {
                id: o.id,
                yaw,
                pitch,
                size: o.bbox.size(),
                score: o.score,
                label: label(o.class, detector),
            }
        })
        .collect()
}

/// What an object is called: "moving" for the motion detector, the class's name for a model.
fn label(class: u16, detector: Detector) -> String {
    match detector {
        Detector::Motion if class == MOVING => "moving".into(),
        _ => class_name(class),
    }
}

/// Lowers this thread's priority to the least (nice 19): the detector takes what the video
/// path leaves of the CPU, never the frames' time. A model run on the CPU keeps a core busy
/// for a second a scan on a small board; with it at the same priority the output fell from
/// 26 to 15 fps at 1920x1080 on a 2-core host.
fn yield_to_video() {
    // SAFETY: gettid and setpriority on the calling thread (Linux keeps a nice value per
    // thread); neither touches memory.
    let done = unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
        libc::setpriority(libc::PRIO_PROCESS, tid, 19)
    };
    if done != 0 {
        warn!(
            "detection: cannot lower its priority: {}",
            std::io::Error::last_os_error()
        );
    }
}
