//! The hand-over between the frame loop and the detection thread: the newest scan and the
//! newest crops only, each drawn only when the thread will take it within a period (from how
//! long the last one took it), and taken the older first.

use crate::detect::scan::ScanView;
use crate::plan::FramePlan;
use crate::supervise::Locked;
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// One scan, or the crops of one track step, as the detection thread takes it.
pub(super) struct Scan {
    pub(super) views: Vec<ScanView>,
    /// For a track step, the object each view is a crop around (empty for a scan).
    pub(super) crops: Vec<u32>,
    pub(super) plan: FramePlan,
    /// The mosaic: I420 for the motion detector (its luma plane first), RGBA for a model.
    pub(super) picture: Vec<u8>,
    pub(super) stride: usize,
    /// The vehicle where the frame was captured, and when (seconds).
    pub(super) position: crate::geometry::GeoPosition,
    pub(super) t: f64,
}

/// The newest scan and the newest crops, waiting for the detection thread.
#[derive(Default)]
pub(in crate::head) struct ScanSlot {
    pending: Mutex<Pending>,
    ready: Condvar,
}

#[derive(Default)]
struct Pending {
    scan: Option<Scan>,
    crops: Option<Scan>,
    /// When the detection thread should be done with what it took last, from how long the
    /// last scan and the last crops took it.
    busy_until: Option<Instant>,
    scan_took: Duration,
    crops_took: Duration,
}

impl ScanSlot {
    fn pending(&self) -> std::sync::MutexGuard<'_, Pending> {
        self.pending.locked()
    }

    /// Whether a scan (at `scan_hz`) and crops (at `crop_hz`) may be drawn now: none waits,
    /// and the detection thread will take one within its period.
    pub(super) fn free(&self, scan_hz: f64, crop_hz: f64) -> (bool, bool) {
        let pending = self.pending();
        let soon = |hz: f64| {
            let period = Duration::from_secs_f64(1.0 / hz.max(0.1));
            pending
                .busy_until
                .is_none_or(|b| Instant::now() + period >= b)
        };
        (
            pending.scan.is_none() && soon(scan_hz),
            pending.crops.is_none() && soon(crop_hz),
        )
    }

    /// Hands over a scan, or the crops of a track step, in place of any waiting.
    pub(super) fn put(&self, scan: Scan) {
        let mut pending = self.pending();
        match scan.crops.is_empty() {
            true => pending.scan = Some(scan),
            false => pending.crops = Some(scan),
        }
        self.ready.notify_one();
    }

    /// The newest scan or the newest crops, the older first, waiting up to a tenth of a
    /// second for one.
    pub(super) fn take(&self) -> Option<Scan> {
        let (mut guard, _) = self
            .ready
            .wait_timeout_while(self.pending(), Duration::from_millis(100), |p| {
                p.scan.is_none() && p.crops.is_none()
            })
            .unwrap_or_else(|e| e.into_inner());
        // The older first: crops taken after a newer scan would put objects back where they
        // were before it, and a scan always pending would starve the crops.
        let crops_first = match (&guard.scan, &guard.crops) {
            (Some(scan), Some(crops)) => crops.t < scan.t,
            (scan, _) => scan.is_none(),
        };
        let (taken, took) = match crops_first {
            true => (guard.crops.take(), guard.crops_took),
            false => (guard.scan.take(), guard.scan_took),
        };
        if taken.is_some() {
            guard.busy_until = Some(Instant::now() + took);
        }
        taken
    }

    /// Notes how long the crops (or a scan) took the detection thread, since `t0`.
    pub(super) fn took(&self, crops: bool, t0: Instant) {
        let mut pending = self.pending();
        match crops {
            true => pending.crops_took = t0.elapsed(),
            false => pending.scan_took = t0.elapsed(),
        }
    }
}
