//! The web page's preview: the encoder's own access units, handed to every page viewer
//! through a bounded broadcast, so the page costs no second encode. A viewer that falls behind
//! loses its oldest units (and waits for the next key frame) instead of holding up the
//! encoder, the RTSP clients or the other viewers; a viewer that joins asks the encoder for a
//! key frame, as an RTSP client does.

use super::encoder::AccessUnit;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use tokio::sync::broadcast;

/// Units a viewer may be behind before it loses some: a second at 30 fps.
const BEHIND: usize = 30;

/// How often one viewer may ask for a key frame.
pub const ASK_INTERVAL: Duration = Duration::from_secs(1);

/// One access unit for the page: Annex B H.264 (SPS and PPS before each key frame).
#[derive(Debug)]
pub struct PreviewUnit {
    pub key: bool,
    /// The unit's presentation time, µs (increasing; the decoder's timestamp).
    pub pts_us: u64,
    pub data: Vec<u8>,
}

pub struct Preview {
    units: broadcast::Sender<Arc<PreviewUnit>>,
    /// The encoder owes a joining viewer a key frame.
    key_wanted: Arc<AtomicBool>,
    viewers: AtomicUsize,
}

impl Preview {
    pub fn new(key_wanted: Arc<AtomicBool>) -> Preview {
        Preview {
            units: broadcast::channel(BEHIND).0,
            key_wanted,
            viewers: AtomicUsize::new(0),
        }
    }

    /// Hands a unit to the viewers; nothing is copied while none watches.
    pub fn push(&self, au: &AccessUnit) {
        if self.units.receiver_count() == 0 {
            return;
        }
        let Ok(map) = au.buffer.map_readable() else {
            return;
        };
        let unit = PreviewUnit {
            key: au.key,
            // As the frame loop stamped it (the encoder offsets its own), so the page can
            // match the rings placed on a frame to the frame it shows.
            pts_us: au
                .pushed_pts
                .map(|t| t.as_micros() as u64)
                .or_else(|| au.buffer.pts().map(|t| t.useconds()))
                .unwrap_or(0),
            data: map.as_slice().to_vec(),
        };
        // Err only when every viewer left meanwhile.
        let _ = self.units.send(Arc::new(unit));
    }

    /// A new viewer: its units start with the next key frame, which is asked for now.
    pub fn watch(self: &Arc<Preview>) -> Viewer {
        self.viewers.fetch_add(1, Ordering::Relaxed);
        self.key_wanted.store(true, Ordering::Relaxed);
        Viewer {
            preview: self.clone(),
            units: self.units.subscribe(),
            keyed: false,
            asked: None,
        }
    }

    pub fn viewers(&self) -> usize {
        self.viewers.load(Ordering::Relaxed)
    }
}

/// One page viewer's units.
pub struct Viewer {
    preview: Arc<Preview>,
    units: broadcast::Receiver<Arc<PreviewUnit>>,
    /// Whether a key frame has been given since the start or since units were lost.
    keyed: bool,
    /// When the viewer last asked for a key frame itself.
    asked: Option<Instant>,
}

impl Viewer {
    /// The viewer's own decoder fell behind and skips to a key frame: the encoder makes one
    /// soon, at most once per [`ASK_INTERVAL`] per viewer (each costs every client bits).
    pub fn ask_key(&mut self) {
        if self.asked.is_none_or(|t| t.elapsed() >= ASK_INTERVAL) {
            self.asked = Some(Instant::now());
            self.preview.key_wanted.store(true, Ordering::Relaxed);
        }
    }

    /// The next unit the viewer can decode; None when the stream has ended.
    pub async fn next(&mut self) -> Option<Arc<PreviewUnit>> {
        loop {
            match self.units.recv().await {
                Ok(unit) if self.keyed || unit.key => {
                    self.keyed = true;
                    return Some(unit);
                }
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(_)) => {
                    // Units were lost: nothing decodes until the next key frame.
                    self.keyed = false;
                    self.preview.key_wanted.store(true, Ordering::Relaxed);
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.preview.viewers.fetch_sub(1, Ordering::Relaxed);
    }
}
