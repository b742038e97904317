//! The live state of a running DigiView: the one [`State`] that the renderer snapshots once
//! per frame and the control server (and later MAVLink) changes, plus the run's status and
//! its capture hook.
//!
//! Readers never wait: a snapshot is an `Arc` loaded lock-free. Writers take a short mutex
//! among themselves only, copy the state, change the copy, check it and publish it whole,
//! so a reader sees either the old state or the new one, never half of a change, and a
//! refused change leaves nothing behind.

use crate::lens::{Lens, LensCal, Roi};
use crate::state::State;
use arc_swap::ArcSwap;
use std::sync::atomic::{AtomicU8, Ordering};
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
}

/// What CAPTURE's GET reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaptureStatus {
    pub recording: bool,
    pub images: u16,
    pub videos: u16,
}

/// Where CAPTURE requests go: the video pipeline takes stills and records; without one
/// (`serve --no-video`) there is nothing to capture and the request is refused.
pub trait Capturer: Send + Sync {
    fn still(&self) -> Result<(), String>;
    fn record(&self, on: bool) -> Result<(), String>;
    fn status(&self) -> CaptureStatus;
}

impl<T: Capturer> Capturer for Arc<T> {
    fn still(&self) -> Result<(), String> {
        T::still(self)
    }
    fn record(&self, on: bool) -> Result<(), String> {
        T::record(self, on)
    }
    fn status(&self) -> CaptureStatus {
        T::status(self)
    }
}

/// The capture hook of a control server without video.
pub struct NoVideo;

impl Capturer for NoVideo {
    fn still(&self) -> Result<(), String> {
        Err("there is no video pipeline (serve --no-video) to take a still from".into())
    }
    fn record(&self, on: bool) -> Result<(), String> {
        if on {
            Err("there is no video pipeline (serve --no-video) to record".into())
        } else {
            Ok(())
        }
    }
    fn status(&self) -> CaptureStatus {
        CaptureStatus::default()
    }
}

pub struct Live {
    state: ArcSwap<State>,
    writer: Mutex<()>,
    /// Every lens of lens.cal, by lens_id, at its calibration frame.
    lenses: Vec<(u8, Lens)>,
    status: AtomicU8,
    failure: AtomicU8,
    capture: Box<dyn Capturer>,
}

impl Live {
    /// The initial state must be valid and name a lens of `cal`.
    pub fn new(state: State, cal: &LensCal, capture: Box<dyn Capturer>) -> Result<Live, String> {
        state.validate()?;
        let lenses: Vec<(u8, Lens)> = cal.entries.iter().map(|e| (e.lens_id, e.lens())).collect();
        if !lenses.iter().any(|(id, _)| *id == state.lens) {
            return Err(format!("lens_id {} is not in lens.cal", state.lens));
        }
        Ok(Live {
            state: ArcSwap::from_pointee(state),
            writer: Mutex::new(()),
            lenses,
            status: AtomicU8::new(RunStatus::Idle as u8),
            failure: AtomicU8::new(Failure::None as u8),
            capture,
        })
    }

    /// The state now: what the renderer uses for one frame.
    pub fn snapshot(&self) -> Arc<State> {
        self.state.load_full()
    }

    /// Changes the state: `change` edits a copy, which is published only if `change` succeeds
    /// and the result is valid. Concurrent updates are applied one after another.
    pub fn update<T>(
        &self,
        change: impl FnOnce(&mut State) -> Result<T, String>,
    ) -> Result<T, String> {
        let _one_writer = self.writer.lock().unwrap_or_else(|e| e.into_inner());
        let mut next = State::clone(&self.state.load());
        let out = change(&mut next)?;
        next.validate()?;
        self.state.store(Arc::new(next));
        Ok(out)
    }

    /// The lens model of every lens of lens.cal.
    pub fn lens_models(&self) -> impl Iterator<Item = &crate::lens::Model> {
        self.lenses.iter().map(|(_, lens)| &lens.radial.model)
    }

    pub fn has_lens(&self, id: u8) -> bool {
        self.lenses.iter().any(|(i, _)| *i == id)
    }

    /// The state's lens at the sensor's frame size, after its crop.
    pub fn lens(&self, state: &State) -> Option<Lens> {
        self.lens_for_frame(state, state.sensor.width, state.sensor.height)
    }

    /// The state's lens scaled to a `width` × `height` frame (a source's actual size), after
    /// the sensor crop.
    pub fn lens_for_frame(&self, state: &State, width: u32, height: u32) -> Option<Lens> {
        let (_, lens) = self.lenses.iter().find(|(id, _)| *id == state.lens)?;
        let roi = state.sensor.roi.map(|[x, y, w, h]| Roi {
            x: x as f64,
            y: y as f64,
            width: w as f64,
            height: h as f64,
        });
        Some(lens.for_frame(width, height, roi))
    }

    /// The calibration frame size of the state's lens.
    pub fn calibration_size(&self, state: &State) -> Option<(u32, u32)> {
        let (_, lens) = self.lenses.iter().find(|(id, _)| *id == state.lens)?;
        Some((lens.width, lens.height))
    }

    pub fn status(&self) -> RunStatus {
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

    /// SYSTEM_STATUS's error byte.
    pub fn failure(&self) -> u8 {
        self.failure.load(Ordering::Relaxed)
    }

    pub fn capture(&self) -> &dyn Capturer {
        self.capture.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
            Err::<(), _>("refused".to_string())
        });
        assert_eq!(refused, Err("refused".to_string()));
        let invalid = live.update(|s| {
            s.output.width = 5;
            Ok(())
        });
        assert!(invalid.unwrap_err().contains("output size 5x1080"));
        assert_eq!(*live.snapshot(), *before);
        live.update(|s| {
            s.output.layout = 3;
            Ok(())
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
                    Ok(())
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
}
