//! The health log: one line every `health_interval_s` with frames in and out, frames dropped
//! and where, render and encode times, RTSP clients, relays taking the stream, and why the
//! source is down, if it is.

use super::Head;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::info;

impl Head {
    /// Logs a summary line every `health_interval_s` until the head stops.
    pub(super) fn health_thread(&self) {
        let every = self.cfg.health_interval_s;
        if every <= 0.0 {
            return;
        }
        let every = Duration::from_secs_f64(every);
        let mut last = (
            Instant::now(),
            self.slot.stats(),
            0u64,
            0u64,
            0u64,
            0u64,
            0u64,
            0u64,
        );
        let mut next = Instant::now() + every;
        while !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
            if Instant::now() < next {
                continue;
            }
            next += every;
            let s = &self.stats;
            let now = (
                Instant::now(),
                self.slot.stats(),
                s.out.load(Ordering::Relaxed),
                s.render_us.load(Ordering::Relaxed),
                s.encoded.load(Ordering::Relaxed),
                s.encode_us.load(Ordering::Relaxed),
                s.views.load(Ordering::Relaxed),
                s.view_us.load(Ordering::Relaxed),
            );
            let secs = (now.0 - last.0).as_secs_f64();
            let out = now.2 - last.2;
            let encoded = now.4 - last.4;
            info!(
                "health: in {:.1} fps, out {:.1} fps, dropped {} (renderer behind) + {} \
                 (encoder behind), render {:.1} ms, encode {:.1} ms, {} clients{}{}{}{}",
                (now.1.received - last.1.received) as f64 / secs,
                out as f64 / secs,
                now.1.dropped - last.1.dropped,
                s.encoder_dropped.load(Ordering::Relaxed),
                (now.3 - last.3) as f64 / 1000.0 / out.max(1) as f64,
                (now.5 - last.5) as f64 / 1000.0 / encoded.max(1) as f64,
                self.rtsp.clients(),
                match now.6 - last.6 {
                    0 => String::new(),
                    n => format!(
                        ", views alone {:.1} fps, {:.1} ms each",
                        n as f64 / secs,
                        (now.7 - last.7) as f64 / 1000.0 / n as f64
                    ),
                },
                match self.publishers.len() {
                    0 => String::new(),
                    n => format!(
                        ", publishing to {} of {n} relays",
                        self.publishers.iter().filter(|p| p.connected()).count()
                    ),
                },
                self.exposure_summary(),
                match self.source_error() {
                    Some(e) => format!(", source down: {e}"),
                    None => String::new(),
                }
            );
            last = now;
        }
    }
}
