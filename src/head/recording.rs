//! A recording while it runs, the composed stream's or one view's: fed each access unit by
//! `capture`, it watches its disk. Four times a second the free space is read; when what the
//! muxer holds would take it under what is kept free (`capture.min_free_mb`), the recording is
//! ended cleanly, its last fragment written. A disk that fails under it (full with nothing
//! kept free, a write error) stops it, its file cut back to what plays. Either way the head's report says why (SYSTEM_STATUS error 6,
//! `/api/status`, the page, a STATUSTEXT) and no empty file is left.

use crate::state::Report;
use crate::state::capture::CaptureError;
use crate::stream::encoder::AccessUnit;
use crate::stream::record_file::Left;
use crate::stream::{Recorder, StreamError};
use std::path::Path;
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

/// How often a running recording reads its disk's free space.
const CHECK_EVERY: Duration = Duration::from_millis(250);

const MB: u64 = 1024 * 1024;

/// Where captures go and how much of the disk is kept free.
pub struct Disk<'a> {
    pub dir: &'a Path,
    pub min_free_mb: u64,
}

impl Disk<'_> {
    /// The free space a capture starts with: what is kept free, and at least 1 MB (with
    /// nothing kept free, a full disk would still take an empty file).
    pub fn needed_mb(&self) -> u64 {
        self.min_free_mb.max(1)
    }

    /// The free space, MB, as an unprivileged writer has it.
    pub fn free_mb(&self) -> Result<u64, CaptureError> {
        Ok(self.free()? / MB)
    }

    /// The free space, bytes.
    fn free(&self) -> Result<u64, CaptureError> {
        let stat = rustix::fs::statvfs(self.dir).map_err(|e| CaptureError::Directory {
            dir: self.dir.to_path_buf(),
            source: e.into(),
        })?;
        Ok(stat.f_bavail.saturating_mul(stat.f_frsize))
    }

    /// Whether the disk is (nearly) full, as far as captures go.
    pub fn full(&self) -> bool {
        self.free_mb().is_ok_and(|free| free < self.needed_mb())
    }
}

/// Why a running recording stopped.
enum Stop {
    /// The free space fell under what is kept free.
    Low(u64),
    /// Writing failed.
    Failed(StreamError),
}

pub struct Running {
    recorder: Recorder,
    /// "the recording", "camera 1's recording": as the log and the status say it.
    what: String,
    checked: Instant,
    /// The bytes of video handed to the muxer: what it has not written yet is still to come
    /// out of the free space.
    pushed: u64,
}

impl Running {
    pub fn new(recorder: Recorder, what: String) -> Running {
        Running {
            recorder,
            what,
            checked: Instant::now(),
            pushed: 0,
        }
    }

    pub fn path(&self) -> &Path {
        self.recorder.path()
    }

    fn push(&mut self, au: &AccessUnit, disk: &Disk) -> Result<(), Stop> {
        self.recorder.push_unit(au).map_err(Stop::Failed)?;
        self.pushed += au.buffer.size() as u64;
        if self.checked.elapsed() < CHECK_EVERY {
            return Ok(());
        }
        self.checked = Instant::now();
        let written = std::fs::metadata(self.path()).map_or(0, |m| m.len());
        let to_come = self.pushed.saturating_sub(written);
        match disk.free() {
            Ok(free) if free.saturating_sub(to_come) < disk.min_free_mb * MB => {
                Err(Stop::Low(free / MB))
            }
            _ => Ok(()),
        }
    }

    /// Ends it cleanly (the last fragment written; shutdown, or asked to stop).
    pub fn finish(self) {
        let path = self.path().to_path_buf();
        match self.recorder.finish() {
            Ok(Left::Removed) => info!("{} held no frame: {} removed", self.what, path.display()),
            Ok(_) => info!("{} ended: {}", self.what, path.display()),
            Err(e) => warn!("{e}"),
        }
    }

    /// Ends it after `stop`; what the status says, short and whole.
    fn stopped(self, stop: Stop, disk: &Disk) -> (String, String) {
        let path = self.path().display().to_string();
        let (brief, why, left) = match stop {
            Stop::Low(free) => {
                let left = self.recorder.finish().unwrap_or(Left::Kept { cut: 0 });
                let why = format!(
                    "the disk has {free} MB free, under the {} MB kept free \
                     (capture.min_free_mb)",
                    disk.min_free_mb
                );
                ("disk full", why, left)
            }
            Stop::Failed(e) => {
                let brief = if disk.full() {
                    "disk full"
                } else {
                    "write error"
                };
                (brief, e.to_string(), self.recorder.abandon())
            }
        };
        let kept = match left {
            Left::Removed => format!("{path} held no frame and was removed"),
            Left::Kept { cut: 0 } => format!("{path} is kept"),
            Left::Kept { cut } => format!("{path} is kept, its last {cut} bytes (unfinished) cut"),
        };
        let what = self.what;
        error!("{what} stopped: {why}; {kept}");
        (
            format!("{what} stopped: {brief}"),
            format!("{what} stopped: {why}; {kept}"),
        )
    }
}

/// Feeds the recording in `slot`, if one runs; one that must stop (its disk full or failing)
/// is ended here, and the report says why.
pub fn feed(slot: &mut Option<Running>, au: &AccessUnit, disk: &Disk, report: &Report) {
    let Some(r) = slot.as_mut() else {
        return;
    };
    let Err(stop) = r.push(au, disk) else {
        return;
    };
    if let Some(r) = slot.take() {
        let (brief, why) = r.stopped(stop, disk);
        report.set_capture_failure(Some(crate::state::CaptureFailure { brief, why }));
    }
}
