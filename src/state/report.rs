//! What the head reports: the run's status and what failed (SYSTEM_STATUS), the supervised
//! services' failures, why CAM_SENSOR cannot be set, and the last frame rendered, with what
//! it was rendered with (what the page and the services place on it). The services write it,
//! the control paths read it; no operator changes it.

use super::State;
use super::sensed::Vehicle;
use super::services::Services;
use crate::geometry::shutter::ShutterTable;
use crate::supervise::Locked;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

/// SYSTEM_STATUS values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum RunStatus {
    Idle = 0,
    Running = 1,
    Finished = 2,
    Error = 3,
}

/// SYSTEM_STATUS's error byte: what failed while the status is error (docs/protocol.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Failure {
    None = 0,
    /// The camera is gone or the source ended or failed; it is being retried.
    Source = 1,
    /// The H.264 encoder failed; it is being rebuilt.
    Encoder = 2,
    /// The GPU device was lost or a render failed; it is being rebuilt.
    Gpu = 3,
    /// The autopilot's attitude stopped coming (none for 0.5 s): the views hold the last.
    Attitude = 4,
    /// A stage of the head failed unexpectedly (a panic): it is started again, and given up
    /// (the process exits) when it keeps failing.
    Internal = 5,
    /// A recording stopped or a still was not written (a full or failing disk); reported
    /// until a recording starts or a still is written again.
    Capture = 6,
}

/// Why a recording stopped or a still was not written: in a few words (a ground station's
/// STATUSTEXT: "the recording stopped: disk full"), and whole (the status, the page, the log).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct CaptureFailure {
    pub brief: String,
    pub why: String,
}

/// What a frame was rendered with: its capture time, the presentation time the composed
/// stream gives it, the vehicle as it saw it (the live vehicle is the link's latest; only the
/// telemetry has it at capture times), and its rolling-shutter table with the frame's size
/// (None: a global shutter).
#[derive(Clone)]
pub struct RenderedFrame {
    pub captured_us: u64,
    pub pts_us: u64,
    pub vehicle: Vehicle,
    pub shutter: Option<(ShutterTable, (u32, u32))>,
}

impl RenderedFrame {
    /// The frame's rolling-shutter table for a lens planned at `size` pixels, so what a
    /// service places on a view maps pixels as the frame was drawn (None: global shutter).
    pub fn shutter_for(&self, size: (u32, u32)) -> Option<ShutterTable> {
        let (table, from) = self.shutter.as_ref()?;
        Some(table.resized(*from, size))
    }

    /// `state` as this frame showed it: the vehicle as it was then, the tracked objects moved
    /// on to the frame's capture time, the following views aimed.
    pub fn shown(&self, state: &State) -> State {
        let mut s = state.clone();
        s.vehicle = self.vehicle;
        s.moved_on_to(self.captured_us);
        s
    }
}

#[derive(Default)]
pub struct Report {
    status: AtomicU8,
    failure: AtomicU8,
    /// The autopilot's attitude is stale; reported while nothing worse is.
    attitude_lost: AtomicBool,
    /// Why the last recording or still failed, until one works again.
    capture: Mutex<Option<CaptureFailure>>,
    /// Why CAM_SENSOR cannot be set, for a source with no exposure to set.
    sensor_refusal: Mutex<Option<String>>,
    /// The supervised services that have failed.
    pub services: Services,
    /// The last frame rendered: what is drawn over it is placed with it.
    rendered: Mutex<Option<RenderedFrame>>,
}

impl Report {
    /// The frame last rendered, as one record, so a reader never sees one frame's vehicle
    /// with another's table or time.
    pub fn set_rendered(&self, frame: RenderedFrame) {
        *self.rendered.locked() = Some(frame);
    }

    /// The frame last rendered (None before any).
    pub fn rendered(&self) -> Option<RenderedFrame> {
        self.rendered.locked().clone()
    }

    /// The last frame's rolling-shutter table for a lens planned at `size` pixels (None:
    /// global shutter).
    pub fn rendered_shutter(&self, size: (u32, u32)) -> Option<ShutterTable> {
        self.rendered()?.shutter_for(size)
    }

    /// The run's status: error while anything failed, the attitude and captures included.
    pub fn status(&self) -> RunStatus {
        if self.attitude_lost.load(Ordering::Relaxed) || self.capture_failure().is_some() {
            return RunStatus::Error;
        }
        match self.status.load(Ordering::Relaxed) {
            0 => RunStatus::Idle,
            1 => RunStatus::Running,
            2 => RunStatus::Finished,
            _ => RunStatus::Error,
        }
    }

    /// Sets the status; any status but error clears the failure.
    pub fn set_status(&self, status: RunStatus) {
        if status != RunStatus::Error {
            self.failure.store(Failure::None as u8, Ordering::Relaxed);
        }
        self.status.store(status as u8, Ordering::Relaxed);
    }

    /// Status error, saying what failed.
    pub fn set_failure(&self, failure: Failure) {
        self.failure.store(failure as u8, Ordering::Relaxed);
        self.status.store(RunStatus::Error as u8, Ordering::Relaxed);
    }

    /// SYSTEM_STATUS's error byte: a failed stage first, then a failed capture, then a stale
    /// attitude.
    pub fn failure(&self) -> u8 {
        match self.failure.load(Ordering::Relaxed) {
            0 if self.capture_failure().is_some() => Failure::Capture as u8,
            0 if self.attitude_lost.load(Ordering::Relaxed) => Failure::Attitude as u8,
            f => f,
        }
    }

    /// What failed, in a few words for a ground station's STATUSTEXT (40 characters at
    /// most); None while nothing has.
    pub fn brief(&self) -> Option<String> {
        let text = match self.failure() {
            1 => "camera signal lost; retrying",
            2 => "encoder failed; rebuilding it",
            3 => "GPU failed; rebuilding it",
            4 => "attitude stale; views hold the last",
            5 => "a stage failed; started again",
            6 => return self.capture_failure().map(|c| c.brief),
            _ => return None,
        };
        Some(text.into())
    }

    /// A recording stopped or a still failed, and why (`Some`); or one worked again (`None`).
    pub fn set_capture_failure(&self, why: Option<CaptureFailure>) {
        *self.capture.locked() = why;
    }

    /// Why the last recording or still failed, while none has worked since.
    pub fn capture_failure(&self) -> Option<CaptureFailure> {
        self.capture.locked().clone()
    }

    /// Whether the autopilot's attitude is stale (the views hold the last one).
    pub fn set_attitude_lost(&self, lost: bool) {
        self.attitude_lost.store(lost, Ordering::Relaxed);
    }

    /// Says CAM_SENSOR SET is refused, and why (the source has no exposure to set), or
    /// allowed again.
    pub fn set_sensor_refusal(&self, why: Option<String>) {
        *self.sensor_refusal.locked() = why;
    }

    pub fn sensor_refusal(&self) -> Option<String> {
        self.sensor_refusal.locked().clone()
    }
}
