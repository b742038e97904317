//! No thread of the head fails silently. Each runs under [`Head::supervised`]: a panic is
//! caught, logged with its message, reported as SYSTEM_STATUS error 5 (and under its name
//! in `/api/status`'s `services`, as `crate::supervise` reports a service), and the stage is
//! started again after a second; a stage that panics [`MAX_RESTARTS`] times within
//! [`WINDOW`] is given up, the head stops, and `serve` exits non-zero saying why.
//!
//! For tests of this very path, `DIGIVIEW_FAULT=frames` makes the frame loop panic once it
//! has run half a second ([`Fault`]).

use super::{Head, HeadError};
use crate::supervise::{FailureLog, panic_message};
use std::collections::VecDeque;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::error;

/// Panics within this long count together.
const WINDOW: Duration = Duration::from_secs(60);
/// This many panics within the window and the stage is given up.
pub const MAX_RESTARTS: usize = 3;
/// The pause before a stage is started again.
const PAUSE: Duration = Duration::from_secs(1);

impl Head {
    /// Runs `work` until it returns, starting it again after each panic, at most
    /// [`MAX_RESTARTS`] times in [`WINDOW`].
    pub(super) fn supervised<T>(
        &self,
        stage: &'static str,
        mut work: impl FnMut() -> Result<T, HeadError>,
    ) -> Result<T, HeadError> {
        let mut panics: VecDeque<Instant> = VecDeque::new();
        loop {
            let why = match catch_unwind(AssertUnwindSafe(&mut work)) {
                Ok(done) => return done,
                Err(panic) => panic_message(panic.as_ref()),
            };
            panics.push_back(Instant::now());
            panics.retain(|t| t.elapsed() < WINDOW);
            let give_up = panics.len() >= MAX_RESTARTS || self.stop.load(Ordering::Relaxed);
            // SYSTEM_STATUS error 5, and /api/status's `services` name the stage.
            self.report.failed(stage, &why, give_up);
            if give_up {
                error!(
                    "the {stage} stage failed ({why}) {} times within {} s: stopping",
                    panics.len(),
                    WINDOW.as_secs()
                );
                self.stop.store(true, Ordering::Relaxed);
                return Err(HeadError::Panicked(stage, why));
            }
            error!(
                "the {stage} stage failed ({why}); starting it again in {} s",
                PAUSE.as_secs()
            );
            let until = Instant::now() + PAUSE;
            while Instant::now() < until {
                if self.stop.load(Ordering::Relaxed) {
                    return Err(HeadError::Panicked(stage, why));
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            self.report.restarted(stage);
        }
    }
}

/// A fault injected into a stage for tests (`DIGIVIEW_FAULT=frames`).
pub(super) struct Fault {
    armed: bool,
    after: Instant,
}

impl Fault {
    /// The fault for `stage`, armed when the environment names it.
    pub(super) fn for_stage(stage: &str) -> Fault {
        Fault {
            armed: std::env::var("DIGIVIEW_FAULT").is_ok_and(|s| s == stage),
            after: Instant::now() + Duration::from_millis(500),
        }
    }

    /// Panics when armed and the stage has run half a second.
    #[track_caller]
    pub(super) fn check(&self, stage: &str) {
        if self.armed && Instant::now() >= self.after {
            panic!("fault injected into the {stage} stage (DIGIVIEW_FAULT)");
        }
    }
}
