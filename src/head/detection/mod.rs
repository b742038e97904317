//! The detection stage, beside the frame loop. At the scan rate, the frame loop renders the
//! scan views of the frame it has just rendered (same state, same lens, on a renderer of its
//! own) into one mosaic and hands it over, newest wins, to the detection thread; it never
//! waits for it. There the detector (the built-in motion detector on the scans' luma, or an
//! ONNX model on their colours, each view drawn at the model's input size) and the seed's
//! tracker run, and the tracked objects, those the tiles show first, go into what is sensed
//! (`crate::state::Sensed`), where the detection tiles and DETECTED_ROI read them. Between scans, at the crop rate, the
//! ONNX detector's track step looks again for each object in the tiles, in a crop the frame
//! loop renders around where it should be (handed over the same way, the older first).
//! GENERAL_SETTINGS' run_ai turns it on and off.

mod handover;
mod objects;
pub mod score;

pub(super) use handover::ScanSlot;

use super::Head;
use crate::detect::external::{Inbox, listen};
use crate::detect::scan::{MOTION_VIEWS, ScanView, model_views, visible};
use crate::detect::{AngularBox, Detector, MotionDetector, OnnxDetector, OnnxError, Tracker};
use crate::frame::{Frame, PixelFormat};
use crate::geometry::GeoPoint;
use crate::geometry::ground::to_ned;
use crate::plan::{Filter, FramePlan};
use crate::render::gpu::{GpuError, OutputId, Renderer};
use crate::state::State;
use crate::supervise::Locked;
use glam::DVec3;
use handover::Scan;
use objects::crop_plan;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// What the frame loop keeps for the scans and crops: their outputs of its renderer (drawn
/// from the frame's one upload), and when each was last offered.
#[derive(Default)]
pub(super) struct ScanRenderer {
    scan: Option<OutputId>,
    crops: Option<OutputId>,
    last: Option<Instant>,
    last_crops: Option<Instant>,
}

impl ScanRenderer {
    /// Forgets the outputs (the GPU and its renderer were rebuilt).
    pub(super) fn reset_gpu(&mut self) {
        (self.scan, self.crops) = (None, None);
    }
}

/// Why the configured detector cannot start.
#[derive(Debug, thiserror::Error)]
pub enum DetectorError {
    #[error(transparent)]
    Onnx(#[from] OnnxError),
    #[error("detections socket {path}: {source}")]
    Socket {
        path: String,
        source: std::io::Error,
    },
}

/// What the detection stage keeps between the frame loop and its thread.
#[derive(Default)]
pub(super) struct DetectionParts {
    /// The newest scan and the newest crops for the detection thread.
    pub scans: ScanSlot,
    /// The ONNX detector, once loaded.
    pub model: std::sync::OnceLock<Model>,
    /// What the external detector sends, once its socket listens.
    pub external: std::sync::OnceLock<Arc<Inbox>>,
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
    pub fn load_detector(self: &Arc<Head>) -> Result<(), DetectorError> {
        if self.cfg.detection.detector == Detector::External
            && self.detection.external.get().is_none()
        {
            let path = &self.cfg.detection.socket;
            let inbox = Arc::new(Inbox::default());
            listen(path, inbox.clone(), self.stop.clone()).map_err(|e| DetectorError::Socket {
                path: path.display().to_string(),
                source: e,
            })?;
            info!("detection: external, JSON lines on {}", path.display());
            let _ = self.detection.external.set(inbox);
        }
        if self.cfg.detection.detector != Detector::Onnx || self.detection.model.get().is_some() {
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
        let _ = self.detection.model.set(Model {
            side: detector.side(),
            detector: Mutex::new(detector),
        });
        Ok(())
    }

    /// Whether the detector runs now.
    fn detecting(&self, state: &State) -> bool {
        let ready = match self.cfg.detection.detector {
            Detector::Motion => true,
            Detector::Onnx => self.detection.model.get().is_some(),
            Detector::External => self.detection.external.get().is_some(),
            Detector::Off => false,
        };
        ready && state.settings.detection.run_ai
    }

    /// An output of the frame loop's renderer for the scans or crops: I420 for the motion
    /// detector (as the composed frame), colour (RGBA, bilinear) for a model.
    fn scan_output(&self, renderer: &mut Renderer) -> Result<OutputId, GpuError> {
        match self.cfg.detection.detector {
            Detector::Onnx => renderer.add_output(PixelFormat::Rgba, Filter::Bilinear),
            _ => renderer.add_output(PixelFormat::I420, Filter::Mip),
        }
    }

    /// Draws the scan views of `frame` (just rendered by `renderer` with `state` and `lens`)
    /// from its upload when a scan is due, else the crops of a track step when one is, and
    /// hands them to the detection thread.
    pub(super) fn offer_scan(
        &self,
        scans: &mut ScanRenderer,
        renderer: &mut Renderer,
        frame: &Frame,
        framed: &super::views::Framed,
    ) {
        let size = (frame.layout.width as u64) << 32 | frame.layout.height as u64;
        self.input.frame_size.store(size, Ordering::Relaxed);
        if !self.detecting(&framed.state) {
            return;
        }
        let Some((views, crops, plan)) = self.due_scan(scans, framed, frame.captured_us) else {
            return;
        };
        // Drawn as the frame was: a rolling shutter's rows each with their own attitude.
        let plan = plan.with_shutter(framed.shutter.clone());
        let output = if crops.is_empty() {
            &mut scans.scan
        } else {
            &mut scans.crops
        };
        let output = match *output {
            Some(id) => id,
            None => match self.scan_output(renderer) {
                Ok(id) => *output.insert(id),
                Err(e) => return warn!("detection: no output for the scan: {e}"),
            },
        };
        let t0 = Instant::now();
        let out = match renderer.redraw(&[(output, &plan)]) {
            Ok(mut out) => out.remove(0),
            Err(e) => return warn!("detection: the scan did not render: {e}"),
        };
        if crops.is_empty() {
            self.meters
                .stats
                .scan_us
                .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
        }
        self.detection.scans.put(Scan {
            views,
            plan,
            stride: out.layout.stride as usize,
            picture: out.data,
            position: framed.state.vehicle.position,
            t: frame.captured_us as f64 * 1e-6,
            crops,
        });
    }

    /// What to draw of a frame captured at `captured_us` for the detection thread, if
    /// anything is due: the scan views, or the crops of a track step (with their objects'
    /// ids), and the mosaic that draws them.
    fn due_scan(
        &self,
        scans: &mut ScanRenderer,
        framed: &super::views::Framed,
        captured_us: u64,
    ) -> Option<(Vec<ScanView>, Vec<u32>, FramePlan)> {
        let (state, lens) = (&framed.state, &framed.lens);
        // How many periods ago each was last offered; None if it has no rate.
        let late = |last: Option<Instant>, hz: f64| {
            (hz > 0.0).then(|| last.map_or(f64::INFINITY, |t| t.elapsed().as_secs_f64() * hz))
        };
        let cfg = &self.cfg.detection;
        let to_lens = crate::geometry::view::lens_from_world(
            state.vehicle.attitude.euler(),
            state.settings.mount.euler(),
        );
        // What the detection thread would not take within a period is not drawn yet (nor
        // again while one waits): a model slower than the rate sets the pace, the frame loop's
        // time goes to what is used, and what is used is at most a period old when taken.
        let (scan_free, crops_free) = self.detection.scans.free(cfg.scan_hz, cfg.crop_hz);
        let scanned = matches!(cfg.detector, Detector::Motion | Detector::Onnx);
        let model = self.detection.model.get();
        let scan_late = late(scans.last, cfg.scan_hz).filter(|&l| scanned && scan_free && l >= 1.0);
        let crops_late = late(scans.last_crops, cfg.crop_hz)
            .filter(|&l| model.is_some() && crops_free && !state.tracked.is_empty() && l >= 1.0);
        // Of the two that are due, the later by its own period.
        let take_scan = match (scan_late, crops_late) {
            (Some(s), Some(c)) => s >= c,
            (s, _) => s.is_some(),
        };
        let (views, crops, plan) = if take_scan {
            scans.last = Some(Instant::now());
            let shape = model.map_or(MOTION_VIEWS, |m| model_views(m.side));
            let (views, plan) = visible(lens, to_lens, shape);
            (views, vec![], plan)
        } else {
            let model = model.filter(|_| crops_late.is_some())?;
            scans.last_crops = Some(Instant::now());
            crop_plan(state, lens, to_lens, model.side, captured_us)
        };
        (!views.is_empty()).then_some((views, crops, plan))
    }

    /// The detection thread: takes each scan, detects, tracks, and publishes the objects.
    pub(super) fn detection_thread(self: &Arc<Head>) {
        if self.cfg.detection.detector == Detector::Off {
            return;
        }
        yield_to_video();
        let mut d = Detecting::default();
        let fault = crate::supervise::Fault::for_service("detection");
        while !self.stop.load(Ordering::Relaxed) {
            fault.check("detection");
            let state = self.state();
            if !self.detecting(&state) {
                if d.owns_list {
                    // Turning run_ai off emptied the list in the same change (`Gate::change`).
                    info!("detection: off (run_ai); its objects are dropped");
                    (d.detector, d.tracker, d.owns_list) =
                        (MotionDetector::new(), Tracker::new(), false);
                    d.adopted.clear();
                }
                std::thread::sleep(Duration::from_millis(100));
                continue;
            }
            self.adopt_clicks(&mut d.tracker, &state, &mut d.adopted);
            let Some(found) = self.next_found(&mut d, &state) else {
                continue;
            };
            self.track(&mut d, &state, found);
        }
    }

    /// The next boxes to track: the external detector's next line, or a scan's detections.
    /// None when nothing came, or what came was a track step (done here).
    fn next_found(&self, d: &mut Detecting, state: &State) -> Option<Found> {
        if let Some(inbox) = self.detection.external.get() {
            let (batch, arrived) = inbox.take(Duration::from_millis(100))?;
            if batch
                .t
                .is_some_and(|t| d.last_sent.is_some_and(|last| t <= last))
            {
                return None;
            }
            d.last_sent = batch.t.or(d.last_sent);
            let t0 = Instant::now();
            let (found, plan) = self.external_boxes(state, &batch, &mut d.labels)?;
            // On the sources' clock, as a scan's frames are.
            let t = crate::clock::clock_us() as f64 * 1e-6 - arrived.elapsed().as_secs_f64();
            return Some((t, found, plan, t0, None));
        }
        let scan = self.detection.scans.take()?;
        let t0 = Instant::now();
        if !scan.crops.is_empty() {
            self.track_step(&mut d.tracker, state, &scan);
            self.show(&mut d.tracker, state, &d.labels, (&mut d.adopted, scan.t));
            d.owns_list = true;
            self.detection.scans.took(true, t0);
            return None;
        }
        let home = *d.origin.get_or_insert(GeoPoint {
            alt: scan.position.home_alt(),
            ..scan.position.point()
        });
        let eye: DVec3 = to_ned(home, scan.position.point());
        let (v, p) = (&scan.views, &scan.plan);
        let found = match self.detection.model.get() {
            Some(model) => {
                let threshold = state.settings.detection.var_confidence_threshold as f32;
                let mut model = model.detector.locked();
                match model.scan(v, p, &scan.picture, scan.stride, threshold) {
                    Ok(found) => found,
                    Err(e) => {
                        warn!("detection: {e}");
                        return None;
                    }
                }
            }
            None => d
                .detector
                .detect(v, p, &scan.picture, scan.stride, eye, scan.t),
        };
        Some((scan.t, found, scan.plan, t0, Some(scan.position)))
    }

    /// Tracks what a scan (or the external detector) found, publishes the objects, and
    /// scores them against the demo's movers.
    fn track(&self, d: &mut Detecting, state: &State, (t, found, plan, t0, position): Found) {
        let sees = |ray| plan.views.iter().any(|v| plan.view_point(v, ray).is_some());
        let covered = |b: &AngularBox| sees(b.centre);
        d.tracker.scan(&state.settings.detection, t, found, covered);
        let (list, tiled) = self.show(&mut d.tracker, state, &d.labels, (&mut d.adopted, t));
        d.owns_list = true;
        if d.scorer.is_none() {
            d.scorer = self.demo_truth().map(score::Scorer::new);
        }
        if let (Some(position), Some(scorer)) = (position, d.scorer.as_mut()) {
            scorer.scan((t, &position), &list, tiled, sees);
            let mut shared = self.observers.demo_score.locked();
            let rings = shared.take().map(|s| s.rings).unwrap_or_default();
            *shared = Some(score::Score {
                rings,
                ..scorer.score().clone()
            });
        }
        self.detection.scans.took(false, t0);
        self.meters
            .stats
            .detect_us
            .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
        self.meters.stats.scans.fetch_add(1, Ordering::Relaxed);
    }

    /// The track step: the model on each crop, each object found again or missed in its own
    /// (at `crop_confidence_threshold`). A model that fails stops the step where it is.
    fn track_step(&self, tracker: &mut Tracker, state: &State, crops: &Scan) {
        let Some(model) = self.detection.model.get() else {
            return;
        };
        let threshold = state.settings.detection.crop_confidence_threshold as f32;
        let mut model = model.detector.locked();
        for ((view, planned), &id) in crops.views.iter().zip(&crops.plan.views).zip(&crops.crops) {
            match model.crop(view, planned, &crops.picture, crops.stride, threshold) {
                Ok(found) => {
                    tracker.track(&state.settings.detection, crops.t, id, found);
                }
                Err(e) => return warn!("detection: {e}"),
            }
            self.meters.stats.crops.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// What the detection thread keeps from one scan to the next.
#[derive(Default)]
struct Detecting {
    detector: MotionDetector,
    tracker: Tracker,
    /// The ground under the first position: the world's origin for the detector.
    origin: Option<GeoPoint>,
    /// Whether the objects published are this thread's.
    owns_list: bool,
    /// The external detector's class names, by the number the tracker knows them by; the
    /// time its last line gave (its lines are placed in time by their arrival).
    labels: Vec<String>,
    last_sent: Option<f64>,
    adopted: objects::Adopted,
    scorer: Option<score::Scorer>,
}

/// Boxes to track: when they were seen, the boxes, the mosaic they were found in, when
/// their detection started, and (a scan's) where the vehicle was.
type Found = (
    f64,
    Vec<crate::detect::angular::Detection>,
    FramePlan,
    Instant,
    Option<crate::geometry::GeoPosition>,
);

/// Lowers this thread's priority to the least: SCHED_IDLE, which runs only when nothing else
/// wants the CPU and yields at once when a video thread wakes (nice 19 where that is not
/// allowed). The detector takes what the video path leaves of the CPU, never the frames'
/// time. A model run on the CPU keeps a core busy for a second a scan on a small board; with
/// it at the same priority the output fell from 26 to 15 fps at 1920x1080 on a 2-core host.
fn yield_to_video() {
    // SAFETY: gettid, sched_setscheduler and setpriority on the calling thread (Linux keeps
    // a policy and a nice value per thread); the parameter lives across the call.
    let done = unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::pid_t;
        let param = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(tid, libc::SCHED_IDLE, &param) == 0
            || libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, 19) == 0
    };
    if !done {
        warn!(
            "detection: cannot lower its priority: {}",
            std::io::Error::last_os_error()
        );
    }
}
