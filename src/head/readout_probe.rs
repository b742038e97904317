//! Measuring the camera's readout on the live head (`POST /api/readout/estimate`): the
//! frame loop hands it frames for the seconds asked for, each frame's luma at no more than
//! [`MAX_WIDTH`] pixels across and, once the autopilot's history covers it, the attitude
//! around its capture; then a thread of its own finds the readout that makes them agree
//! (`render::shutter_fit`) and keeps the answer for `GET /api/readout/estimate`.

use crate::clock::clock_us;
use crate::frame::Frame;
use crate::geometry::Euler;
use crate::geometry::shutter::Readout;
use crate::lens::Lens;
use crate::render::shutter_fit::{ATTITUDE_SPAN_US, Fit, FitError, FitFrame, estimate};
use crate::supervise::Locked;
use crate::telemetry::Telemetry;
use serde::Serialize;
use std::sync::{Arc, Mutex};
use tracing::{info, warn};

/// Why an estimate came to no figure.
#[derive(Debug, thiserror::Error)]
enum NotFitted {
    #[error("no frames with luma")]
    NoLuma,
    #[error(transparent)]
    Fit(FitError),
    #[error("starting the fit: {0}")]
    Thread(std::io::Error),
}

/// Frames are kept at most this wide (area-averaged): 10 s at 30 fps then holds 70 MB.
pub const MAX_WIDTH: u32 = 640;
/// The longest collection asked for, seconds.
pub const MAX_SECONDS: f64 = 60.0;

/// Where an estimate stands, as the API answers it.
#[derive(Clone, Debug, Serialize)]
pub struct ProbeStatus {
    /// idle, collecting, fitting, done or failed.
    pub state: &'static str,
    /// Frames collected (of the frames the head drew within the span, `offered`: each
    /// once), the seconds they span, and the seconds asked for.
    pub frames: usize,
    pub offered: usize,
    pub collected_s: f64,
    pub seconds: f64,
    /// The search's steps done and to do.
    pub steps: (usize, usize),
    pub fit: Option<Fit>,
    pub error: Option<String>,
}

impl Default for ProbeStatus {
    fn default() -> Self {
        ProbeStatus {
            state: "idle",
            frames: 0,
            offered: 0,
            collected_s: 0.0,
            seconds: 0.0,
            steps: (0, 0),
            fit: None,
            error: None,
        }
    }
}

/// What is collected for one estimate.
struct Collecting {
    /// How long, and until when once the first frame has come (µs, the frames' clock).
    span_us: u64,
    until_us: Option<u64>,
    /// Whether a frame past the span has come: nothing more is kept.
    full: bool,
    /// Frames whose attitudes the history does not cover yet: luma and capture time.
    pending: Vec<(image::GrayImage, u64)>,
    done: Vec<FitFrame>,
    /// The lens at the kept frames' size, and the camera's mount.
    lens: Option<Lens>,
    mount: Euler,
    /// The capture time of the last frame kept: the same frame drawn again (a slower source)
    /// is kept once.
    last_us: Option<u64>,
    /// The distinct frames offered within the span.
    offered: usize,
}

/// Why an estimate was not started.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error("seconds {0:?} is outside 1..={MAX_SECONDS}")]
    Seconds(f64),
    #[error("an estimate is already {0}")]
    Busy(&'static str),
}

#[derive(Default)]
pub struct ReadoutProbe {
    status: Mutex<ProbeStatus>,
    collecting: Mutex<Option<Collecting>>,
}

impl ReadoutProbe {
    /// Starts collecting `seconds` of frames; refused while an estimate runs.
    pub fn start(&self, seconds: f64) -> Result<ProbeStatus, StartError> {
        if !(seconds.is_finite() && (1.0..=MAX_SECONDS).contains(&seconds)) {
            return Err(StartError::Seconds(seconds));
        }
        let mut status = self.status.locked();
        if matches!(status.state, "collecting" | "fitting") {
            return Err(StartError::Busy(status.state));
        }
        *status = ProbeStatus {
            state: "collecting",
            seconds,
            ..ProbeStatus::default()
        };
        *self.collecting.locked() = Some(Collecting {
            span_us: (seconds * 1e6) as u64,
            until_us: None,
            full: false,
            pending: vec![],
            done: vec![],
            lens: None,
            mount: Euler::default(),
            last_us: None,
            offered: 0,
        });
        info!("readout estimate: collecting {seconds} s of frames");
        Ok(status.clone())
    }

    pub fn status(&self) -> ProbeStatus {
        let mut s = self.status.locked().clone();
        if s.state.is_empty() {
            s.state = "idle";
        }
        s
    }

    /// A frame the head rendered, through `lens` (at the frame's size) on `mount`; its
    /// readout is fitted as `like` says (direction, stamped row). Cheap when not collecting.
    pub fn offer(
        self: &Arc<Self>,
        frame: &Frame,
        (lens, mount): (&Lens, Euler),
        like: Readout,
        telemetry: &Arc<Telemetry>,
    ) {
        let mut guard = self.collecting.locked();
        let Some(c) = guard.as_mut() else {
            return;
        };
        let until = *c.until_us.get_or_insert(frame.captured_us + c.span_us);
        c.full |= frame.captured_us > until;
        let again = c.last_us.replace(frame.captured_us) == Some(frame.captured_us);
        if !c.full && !again {
            c.offered += 1;
            let (w, h) = (frame.layout.width, frame.layout.height);
            let k = w.div_ceil(MAX_WIDTH).max(1);
            let size = (w / k, h / k);
            if let Some(luma) = frame.luma() {
                let luma = image::imageops::thumbnail(&luma, size.0, size.1);
                c.lens
                    .get_or_insert_with(|| lens.for_frame(size.0, size.1, None));
                c.mount = mount;
                c.pending.push((luma, frame.captured_us));
            }
        }
        // The history covers a frame's attitudes once its capture is this far behind.
        let covered = clock_us().saturating_sub(2 * ATTITUDE_SPAN_US);
        let ready = c.pending.partition_point(|p| p.1 <= covered);
        for (luma, at) in c.pending.drain(..ready) {
            let attitude = |t: i64| telemetry.at(at.saturating_add_signed(t)).0;
            if let Some(f) = FitFrame::new(luma, attitude) {
                c.done.push(f);
            }
        }
        let mut status = self.status.locked();
        status.frames = c.done.len();
        status.offered = c.offered;
        let first = until - c.span_us;
        status.collected_s = (frame.captured_us.min(until).saturating_sub(first)) as f64 / 1e6;
        if !c.full || !c.pending.is_empty() {
            return;
        }
        let c = guard.take().expect("collecting");
        status.state = "fitting";
        drop(status);
        let probe = self.clone();
        let spawned = std::thread::Builder::new()
            .name("readout-fit".into())
            .spawn(move || probe.fit(c, like));
        if let Err(e) = spawned {
            self.finish(Err(NotFitted::Thread(e)));
        }
    }

    fn fit(&self, c: Collecting, like: Readout) {
        let Some(lens) = c.lens else {
            return self.finish(Err(NotFitted::NoLuma));
        };
        let progress = |done, of| {
            self.status.locked().steps = (done, of);
        };
        let fit = estimate(&c.done, &lens, c.mount, like, progress).map_err(NotFitted::Fit);
        self.finish(fit);
    }

    fn finish(&self, result: Result<Fit, NotFitted>) {
        let mut status = self.status.locked();
        match result {
            Ok(fit) => {
                info!(
                    "readout estimate: {:.1} ms ({} pairs of frames)",
                    fit.readout_ms, fit.pairs
                );
                (status.state, status.fit) = ("done", Some(fit));
            }
            Err(e) => {
                warn!("readout estimate failed: {e}");
                (status.state, status.error) = ("failed", Some(e.to_string()));
            }
        }
    }
}
