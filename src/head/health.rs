//! The head's health: every second the frame counters are turned into [`Health`] (frames in
//! and out, frames dropped and where, render and encode times, RTSP and page viewers, relays,
//! the exposure, why the source is down), which the web page reads; every
//! `health_interval_s` the same figures, over that interval, go to the log as one line.

use super::Head;
use crate::supervise::Locked;
use serde::Serialize;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::info;

/// The video head's figures over the last second (the web page's status).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Health {
    pub fps_in: f64,
    pub fps_out: f64,
    /// Frames the renderer was too slow to take (the source's newer frame replaced them).
    pub dropped_renderer: u64,
    /// Frames the encoder was too slow to take, since the start.
    pub dropped_encoder: u64,
    pub render_ms: f64,
    pub encode_ms: f64,
    pub rtsp_clients: usize,
    pub page_viewers: usize,
    /// Relays taking the stream, of those configured.
    pub relays: (usize, usize),
    /// `exposure 8.0 ms gain 1.00, luma 101` (empty when the head does not see it).
    pub exposure: String,
    /// Why the source is down, while it is.
    pub source_down: Option<String>,
    /// Views rendered alone (their own streams and stills) per second, and ms each.
    pub views_alone: (f64, f64),
    /// Detection: scans a second, ms to render each (in the frame loop) and ms to detect and
    /// track in each (on its own thread); and the objects tracked.
    pub scans: (f64, f64, f64),
    /// Crops the track step looked at again, a second.
    pub crops: f64,
    pub tracked: usize,
    /// Where the frames' time went, capture to sent (None while none went out).
    pub latency: Option<super::latency::Stages>,
    /// The KLV metadata of the composed stream's last frame, field by field.
    pub klv: Option<crate::stream::klv::ViewMetadata>,
    /// On the demo: the tracker against the demo's own movers, since detection started.
    pub demo_score: Option<super::detection::score::Score>,
    /// The rolling-shutter readout corrected, ms (0: a global shutter, nothing corrected).
    pub readout_ms: f64,
    /// The adapter that renders, its backend, and why it was chosen.
    pub gpu: Option<crate::render::choose::GpuChoice>,
    /// A lens pair's exposure match: how far the second lens is from the first (empty for
    /// one lens).
    pub lenses: String,
}

/// The counters at one moment.
#[derive(Clone, Copy)]
struct Sample {
    at: Instant,
    /// `at` on `crate::clock::clock_us`.
    clock_us: u64,
    received: u64,
    dropped: u64,
    out: u64,
    render_us: u64,
    encoded: u64,
    encode_us: u64,
    views: u64,
    view_us: u64,
    scans: u64,
    scan_us: u64,
    detect_us: u64,
    crops: u64,
}

impl std::fmt::Display for Health {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "health: in {:.1} fps, out {:.1} fps, dropped {} (renderer behind) + {} \
             (encoder behind), render {:.1} ms, encode {:.1} ms, {} clients",
            self.fps_in,
            self.fps_out,
            self.dropped_renderer,
            self.dropped_encoder,
            self.render_ms,
            self.encode_ms,
            self.rtsp_clients
        )?;
        if self.page_viewers > 0 {
            write!(f, ", {} page viewers", self.page_viewers)?;
        }
        if self.views_alone.0 > 0.0 {
            let (fps, ms) = self.views_alone;
            write!(f, ", views alone {fps:.1} fps, {ms:.1} ms each")?;
        }
        if self.scans.0 > 0.0 {
            let (hz, render, detect) = self.scans;
            write!(
                f,
                ", detection {hz:.1} scans/s ({render:.1} ms render, {detect:.1} ms detect), \
                 {} tracked",
                self.tracked
            )?;
            if self.crops > 0.0 {
                write!(f, ", {:.1} crops/s", self.crops)?;
            }
            if let Some(s) = &self.demo_score {
                write!(
                    f,
                    " (against the demo's movers: {:.1}% on one, {} of {} entries late, a \
                     tile on none {:.1} s at most, {:.1}% of rings within {} px)",
                    s.precision * 100.0,
                    s.late_entries,
                    s.entries.len(),
                    s.longest_false_tile,
                    100.0 * s.rings.within as f64 / s.rings.count.max(1) as f64,
                    super::detection::score::RING_LIMIT
                )?;
            }
        }
        if self.relays.1 > 0 {
            write!(
                f,
                ", publishing to {} of {} relays",
                self.relays.0, self.relays.1
            )?;
        }
        if !self.exposure.is_empty() {
            write!(f, ", {}", self.exposure)?;
        }
        if !self.lenses.is_empty() {
            write!(f, ", {}", self.lenses)?;
        }
        if let Some(e) = &self.source_down {
            write!(f, ", source down: {e}")?;
        }
        Ok(())
    }
}

impl Head {
    fn sample(&self) -> Sample {
        let s = &self.meters.stats;
        let slot = self.input.slot.stats();
        Sample {
            at: Instant::now(),
            clock_us: crate::clock::clock_us(),
            received: slot.received,
            dropped: slot.dropped,
            out: s.out.load(Ordering::Relaxed),
            render_us: s.render_us.load(Ordering::Relaxed),
            encoded: s.encoded.load(Ordering::Relaxed),
            encode_us: s.encode_us.load(Ordering::Relaxed),
            views: s.views.load(Ordering::Relaxed),
            view_us: s.view_us.load(Ordering::Relaxed),
            scans: s.scans.load(Ordering::Relaxed),
            scan_us: s.scan_us.load(Ordering::Relaxed),
            detect_us: s.detect_us.load(Ordering::Relaxed),
            crops: s.crops.load(Ordering::Relaxed),
        }
    }

    /// The figures between two samples.
    fn health_between(&self, a: &Sample, b: &Sample) -> Health {
        let secs = (b.at - a.at).as_secs_f64().max(1e-3);
        let out = b.out - a.out;
        let views = b.views - a.views;
        let scans = b.scans - a.scans;
        let per = |us: u64, n: u64| us as f64 / 1000.0 / n.max(1) as f64;
        Health {
            fps_in: (b.received - a.received) as f64 / secs,
            fps_out: out as f64 / secs,
            dropped_renderer: b.dropped - a.dropped,
            dropped_encoder: self.meters.stats.encoder_dropped.load(Ordering::Relaxed),
            render_ms: per(b.render_us - a.render_us, out),
            encode_ms: per(b.encode_us - a.encode_us, b.encoded - a.encoded),
            rtsp_clients: self.outputs.clients.clients(),
            page_viewers: self.outputs.preview.viewers(),
            relays: {
                let all = || {
                    self.outputs
                        .publishers
                        .iter()
                        .chain(self.outputs.view_publishers.iter().flatten())
                };
                (all().filter(|p| p.connected()).count(), all().count())
            },
            exposure: self.exposure_summary().trim_start_matches(", ").to_string(),
            source_down: self.source_error(),
            views_alone: (views as f64 / secs, per(b.view_us - a.view_us, views)),
            scans: (
                scans as f64 / secs,
                per(b.scan_us - a.scan_us, scans),
                per(b.detect_us - a.detect_us, scans),
            ),
            crops: (b.crops - a.crops) as f64 / secs,
            tracked: self.state().tracked.len(),
            latency: self.meters.latency.since(a.clock_us),
            klv: self.observers.klv.locked().clone(),
            demo_score: self.observers.demo_score.locked().clone(),
            readout_ms: self.cfg.readout.time_ms,
            gpu: self.meters.gpu.locked().clone(),
            lenses: self.meters.lenses.locked().clone(),
        }
    }

    /// The figures over the last second.
    pub fn health(&self) -> Health {
        self.meters.health.locked().clone()
    }

    /// Updates [`Head::health`] every second and logs a line every `health_interval_s`,
    /// until the head stops.
    pub(super) fn health_thread(&self) {
        let every = self.cfg.health_interval_s;
        let log_every = (every > 0.0).then(|| Duration::from_secs_f64(every));
        let mut logged = self.sample();
        let mut last = logged;
        while !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
            let now = self.sample();
            if now.at - last.at >= Duration::from_secs(1) {
                *self.meters.health.locked() = self.health_between(&last, &now);
                last = now;
            }
            if log_every.is_some_and(|e| now.at - logged.at >= e) {
                let health = self.health_between(&logged, &now);
                info!("{health}");
                if let Some(l) = health.latency {
                    info!("{l}");
                }
                logged = now;
            }
        }
    }
}
