//! The live handle of a running DigiView: the one [`State`] that the frame loop snapshots once
//! per frame and the control server (and later MAVLink and the web page) changes, the lenses
//! of lens.cal it may name, the run's status (with the services that failed), and its
//! capture hook.
//!
//! Readers never wait: a snapshot is an `Arc` loaded lock-free. Writers take a short mutex
//! among themselves only, copy the state, change the copy, check it and publish it whole,
//! so a reader sees either the old state or the new one, never half of a change, and a
//! refused change leaves nothing behind.

use super::capture::Capturer;
use super::services::Services;
use super::{Invalid, State};
use crate::geometry::shutter::ShutterTable;
use crate::lens::{LensCal, Lenses};
use arc_swap::ArcSwap;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

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
}

pub struct Live {
    state: ArcSwap<State>,
    writer: Mutex<()>,
    lenses: Lenses,
    status: AtomicU8,
    failure: AtomicU8,
    /// The autopilot's attitude is stale; reported while nothing worse is.
    attitude_lost: AtomicBool,
    capture: Box<dyn Capturer>,
    /// Why CAM_SENSOR cannot be set, for a source with no exposure to set.
    sensor_refusal: Mutex<Option<String>>,
    /// The supervised services that have failed.
    pub services: Services,
    /// The last frame rendered: what is drawn over it is placed with it.
    rendered: Mutex<Option<RenderedFrame>>,
}

/// What a frame was rendered with: its capture time, the presentation time the composed
/// stream gives it, the vehicle as it saw it (the state's own attitude is not the
/// autopilot's, which only the telemetry follows), and its rolling-shutter table with the
/// frame's size (None: a global shutter).
#[derive(Clone)]
pub struct RenderedFrame {
    pub captured_us: u64,
    pub pts_us: u64,
    pub vehicle: super::Vehicle,
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
        s.vehicle = self.vehicle.clone();
        s.moved_on_to(self.captured_us);
        s
    }
}

impl Live {
    /// The initial state must be valid and name a lens of `cal`.
    pub fn new(state: State, cal: &LensCal, capture: Box<dyn Capturer>) -> Result<Live, Invalid> {
        let lenses = Lenses::new(cal);
        state.validate(&lenses)?;
        Ok(Live {
            state: ArcSwap::from_pointee(state),
            writer: Mutex::new(()),
            lenses,
            status: AtomicU8::new(RunStatus::Idle as u8),
            failure: AtomicU8::new(Failure::None as u8),
            attitude_lost: AtomicBool::new(false),
            capture,
            sensor_refusal: Mutex::new(None),
            services: Services::default(),
            rendered: Mutex::new(None),
        })
    }

    /// The frame last rendered, as one record, so a reader never sees one frame's vehicle
    /// with another's table or time.
    pub fn set_rendered(&self, frame: RenderedFrame) {
        *self.rendered.lock().unwrap_or_else(|e| e.into_inner()) = Some(frame);
    }

    /// The frame last rendered (None before any).
    pub fn rendered(&self) -> Option<RenderedFrame> {
        self.rendered
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The last frame's rolling-shutter table for a lens planned at `size` pixels (None:
    /// global shutter).
    pub fn rendered_shutter(&self, size: (u32, u32)) -> Option<ShutterTable> {
        self.rendered()?.shutter_for(size)
    }

    /// The state now: what the renderer uses for one frame.
    pub fn snapshot(&self) -> Arc<State> {
        self.state.load_full()
    }

    /// Changes the state: `change` edits a copy, which is published only if `change` succeeds
    /// and the result is valid. Concurrent updates are applied one after another.
    pub fn update<T, E: From<Invalid>>(
        &self,
        change: impl FnOnce(&mut State) -> Result<T, E>,
    ) -> Result<T, E> {
        let _one_writer = self.writer.lock().unwrap_or_else(|e| e.into_inner());
        let mut next = State::clone(&self.state.load());
        let detecting = next.detection.run_ai;
        let out = change(&mut next)?;
        // Detection turned off (run_ai, from any entry) takes its objects with it at once,
        // whether or not the detection thread gets the CPU to say so.
        if detecting && !next.detection.run_ai {
            next.tracked.clear();
            next.drop_lost_followers();
        }
        next.validate(&self.lenses)?;
        self.state.store(Arc::new(next));
        Ok(out)
    }

    /// Every lens of lens.cal, by lens_id.
    pub fn lenses(&self) -> &Lenses {
        &self.lenses
    }

    /// The run's status: error while anything failed, the attitude included.
    pub fn status(&self) -> RunStatus {
        if self.attitude_lost.load(Ordering::Relaxed) {
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

    /// SYSTEM_STATUS's error byte: a failed stage first, else a stale attitude.
    pub fn failure(&self) -> u8 {
        match self.failure.load(Ordering::Relaxed) {
            0 if self.attitude_lost.load(Ordering::Relaxed) => Failure::Attitude as u8,
            f => f,
        }
    }

    /// Whether the autopilot's attitude is stale (the views hold the last one).
    pub fn set_attitude_lost(&self, lost: bool) {
        self.attitude_lost.store(lost, Ordering::Relaxed);
    }

    /// Says CAM_SENSOR SET is refused, and why (the source has no exposure to set), or
    /// allowed again.
    pub fn set_sensor_refusal(&self, why: Option<String>) {
        *self
            .sensor_refusal
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = why;
    }

    pub fn sensor_refusal(&self) -> Option<String> {
        self.sensor_refusal
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    pub fn capture(&self) -> &dyn Capturer {
        self.capture.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::capture::NoVideo;
    use std::sync::mpsc;

    fn live() -> Live {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal");
        let cal = LensCal::load(&path).unwrap();
        Live::new(State::default(), &cal, Box::new(NoVideo)).unwrap()
    }

    #[test]
    fn a_refused_or_invalid_change_leaves_the_state_as_it_was() {
        let live = live();
        let before = live.snapshot();
        let refused = live.update(|s| {
            s.output.layout = 3;
            Err::<(), _>(Invalid("refused".to_string()))
        });
        assert_eq!(refused, Err(Invalid("refused".to_string())));
        let invalid = live.update(|s| {
            s.output.width = 5;
            Ok::<_, Invalid>(())
        });
        assert!(
            invalid
                .unwrap_err()
                .0
                .contains("output width 5 is outside 640..=1920 px")
        );
        assert_eq!(*live.snapshot(), *before);
        live.update(|s| {
            s.output.layout = 3;
            Ok::<_, Invalid>(())
        })
        .unwrap();
        assert_eq!(live.snapshot().output.layout, 3);
        assert_eq!(before.output.layout, 4, "an older snapshot is unchanged");
    }

    #[test]
    fn a_reader_gets_the_old_state_while_a_writer_is_mid_change() {
        let live = live();
        let (go_tx, go_rx) = mpsc::channel();
        let (inside_tx, inside_rx) = mpsc::channel();
        std::thread::scope(|scope| {
            let live = &live;
            scope.spawn(move || {
                live.update(|s| {
                    s.lens = 1;
                    inside_tx.send(()).unwrap();
                    // Finish only after the reader has its snapshot: were snapshots to wait
                    // for writers, this would never return.
                    go_rx.recv().unwrap();
                    Ok::<_, Invalid>(())
                })
                .unwrap()
            });
            inside_rx.recv().unwrap();
            assert_eq!(
                live.snapshot().lens,
                0,
                "the change is not visible half-made"
            );
            go_tx.send(()).unwrap();
        });
        assert_eq!(live.snapshot().lens, 1);
    }

    /// Detection turned off takes its objects with it in the same change; a change that
    /// leaves it on, or turns it on, leaves them.
    #[test]
    fn turning_detection_off_empties_the_tracked_list_at_once() {
        let live = live();
        let set = |on: bool, objects: usize| {
            live.update(|s| {
                s.detection.run_ai = on;
                if objects > 0 {
                    s.tracked = vec![crate::state::Tracked::default(); objects];
                }
                Ok::<_, Invalid>(())
            })
            .unwrap()
        };
        set(true, 2);
        set(true, 0);
        assert_eq!(live.snapshot().tracked.len(), 2);
        set(false, 0);
        assert!(live.snapshot().tracked.is_empty());
        set(false, 1);
        set(true, 0);
        assert_eq!(
            live.snapshot().tracked.len(),
            1,
            "set while off, kept on turning on"
        );
    }
}
