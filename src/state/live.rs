//! The live handle of the operator's settings: the one [`Settings`] that the frame loop
//! snapshots once per frame and the control paths change (through the gate, `super::Gate`),
//! and the lenses of lens.cal it may name.
//!
//! Readers never wait: a snapshot is an `Arc` loaded lock-free. Writers take a short mutex
//! among themselves only, copy the settings, change the copy, check it and publish it whole,
//! so a reader sees either the old settings or the new ones, never half of a change, and a
//! refused change leaves nothing behind.

use super::Invalid;
use super::settings::Settings;
use super::view::follow;
use crate::lens::{LensCal, Lenses};
use crate::supervise::Locked;
use arc_swap::ArcSwap;
use std::sync::{Arc, Mutex};

pub struct LiveSettings {
    settings: ArcSwap<Settings>,
    writer: Mutex<()>,
    lenses: Lenses,
}

impl LiveSettings {
    /// The initial settings must be valid and name a lens of `cal`.
    pub fn new(settings: Settings, cal: &LensCal) -> Result<LiveSettings, Invalid> {
        let lenses = Lenses::new(cal);
        settings.validate(&lenses)?;
        Ok(LiveSettings {
            settings: ArcSwap::from_pointee(settings),
            writer: Mutex::new(()),
            lenses,
        })
    }

    /// The settings now: what the renderer uses for one frame.
    pub fn snapshot(&self) -> Arc<Settings> {
        self.settings.load_full()
    }

    /// Changes the settings: `change` edits a copy, which is published only if `change`
    /// succeeds and the result is valid. Concurrent updates are applied one after another.
    pub fn update<T, E: From<Invalid>>(
        &self,
        change: impl FnOnce(&mut Settings) -> Result<T, E>,
    ) -> Result<T, E> {
        let _one_writer = self.writer.locked();
        let mut next = Settings::clone(&self.settings.load());
        let detecting = next.detection.run_ai;
        let out = change(&mut next)?;
        // Detection turned off (run_ai, from any entry) takes its objects with it at once:
        // the views that followed one stop, aimed where they were (the objects themselves
        // are no longer shown: `State::now`).
        if detecting && !next.detection.run_ai {
            follow::drop_lost(&mut next.cameras, &[]);
        }
        next.validate(&self.lenses)?;
        self.settings.store(Arc::new(next));
        Ok(out)
    }

    /// Every lens of lens.cal, by lens_id.
    pub fn lenses(&self) -> &Lenses {
        &self.lenses
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modes::LayoutMode;
    use std::sync::mpsc;

    fn live() -> LiveSettings {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal");
        let cal = LensCal::load(&path).unwrap();
        LiveSettings::new(Settings::default(), &cal).unwrap()
    }

    #[test]
    fn a_refused_or_invalid_change_leaves_the_settings_as_they_were() {
        let live = live();
        let before = live.snapshot();
        let refused = live.update(|s| {
            s.output.layout = LayoutMode::TwoAndPanorama;
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
            s.output.layout = LayoutMode::TwoAndPanorama;
            Ok::<_, Invalid>(())
        })
        .unwrap();
        assert_eq!(live.snapshot().output.layout, LayoutMode::TwoAndPanorama);
        assert_eq!(
            before.output.layout,
            LayoutMode::Four,
            "an older snapshot is unchanged"
        );
    }

    #[test]
    fn a_reader_gets_the_old_settings_while_a_writer_is_mid_change() {
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
}
