//! Where a frame's time goes between capture and the stream. The frame loop stamps each fresh
//! frame as it passes each stage ([`crate::clock::Stamps`]), the encoder's sink stamps it out
//! and hands it here; the health thread turns the frames of an interval into medians per
//! stage, for the log line and the web page's status.

use crate::clock::Stamps;
use crate::supervise::Locked;
use serde::Serialize;
use std::collections::VecDeque;
use std::sync::Mutex;

/// The frames kept: a few seconds at 30 fps.
const KEPT: usize = 300;

/// The last frames' stamps.
#[derive(Default)]
pub struct Latency {
    recent: Mutex<VecDeque<Stamps>>,
}

/// The medians of each stage over some frames, ms; the stages do not add up to the total's
/// median exactly.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stages {
    pub frames: usize,
    /// Capture to the slot: the source's own pipeline (the demo's synthesis, a camera's
    /// decoding and conversion).
    pub source_ms: f64,
    /// In the slot until the frame loop took it (its pacing).
    pub waiting_ms: f64,
    /// Plan, upload, draw and readback.
    pub render_ms: f64,
    /// Read back until the encoder took it (stills, the encoder's back-pressure).
    pub queued_ms: f64,
    pub encode_ms: f64,
    /// Out of the encoder until every output had it.
    pub send_ms: f64,
    /// Capture to sent: the median and the 90th percentile.
    pub total_ms: f64,
    pub total_p90_ms: f64,
}

impl Latency {
    pub fn record(&self, s: Stamps) {
        let mut recent = self.recent.locked();
        if recent.len() == KEPT {
            recent.pop_front();
        }
        recent.push_back(s);
    }

    /// The stages of the frames sent at `since_us` or later; None when there were none.
    pub fn since(&self, since_us: u64) -> Option<Stages> {
        let recent = self.recent.locked();
        let frames: Vec<&Stamps> = recent.iter().filter(|s| s.sent >= since_us).collect();
        if frames.is_empty() {
            return None;
        }
        let stage = |q: f64, f: &dyn Fn(&Stamps) -> (u64, u64)| {
            let mut ms: Vec<f64> = frames
                .iter()
                .map(|s| {
                    let (from, to) = f(s);
                    to.saturating_sub(from) as f64 / 1000.0
                })
                .collect();
            ms.sort_by(f64::total_cmp);
            ms[((ms.len() - 1) as f64 * q).round() as usize]
        };
        Some(Stages {
            frames: frames.len(),
            source_ms: stage(0.5, &|s| (s.captured, s.arrived)),
            waiting_ms: stage(0.5, &|s| (s.arrived, s.taken)),
            render_ms: stage(0.5, &|s| (s.taken, s.rendered)),
            queued_ms: stage(0.5, &|s| (s.rendered, s.encoder_in)),
            encode_ms: stage(0.5, &|s| (s.encoder_in, s.encoded)),
            send_ms: stage(0.5, &|s| (s.encoded, s.sent)),
            total_ms: stage(0.5, &|s| (s.captured, s.sent)),
            total_p90_ms: stage(0.9, &|s| (s.captured, s.sent)),
        })
    }
}

impl std::fmt::Display for Stages {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "latency over {} frames (medians): source {:.1} ms, waiting {:.1}, render {:.1}, \
             queued {:.1}, encode {:.1}, send {:.1}; capture to sent {:.1} ms (p90 {:.1})",
            self.frames,
            self.source_ms,
            self.waiting_ms,
            self.render_ms,
            self.queued_ms,
            self.encode_ms,
            self.send_ms,
            self.total_ms,
            self.total_p90_ms
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_stage_is_the_median_of_its_own_spans_over_the_frames_sent_since() {
        let l = Latency::default();
        for (i, render) in [3_000u64, 5_000, 4_000].into_iter().enumerate() {
            let t = 1_000_000 * (i as u64 + 1);
            l.record(Stamps {
                captured: t,
                arrived: t + 20_000,
                taken: t + 21_000,
                rendered: t + 21_000 + render,
                encoder_in: t + 21_000 + render,
                encoded: t + 24_000 + render,
                sent: t + 24_500 + render,
            });
        }
        let s = l.since(0).unwrap();
        assert_eq!(s.frames, 3);
        assert_eq!((s.source_ms, s.waiting_ms, s.render_ms), (20.0, 1.0, 4.0));
        assert_eq!((s.encode_ms, s.send_ms, s.total_ms), (3.0, 0.5, 28.5));
        assert_eq!(s.total_p90_ms, 29.5);
        // Only the frames sent since then.
        assert_eq!(l.since(2_500_000).unwrap().frames, 1);
        assert_eq!(l.since(9_000_000), None);
    }
}
