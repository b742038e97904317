//! Sources: where fisheye frames come from. A V4L2 camera or any GStreamer source
//! description, a video file (looped or once), a still image, an image sequence, or the
//! built-in demo (the synthetic world through a lens of lens.cal). Every source runs on its
//! own thread and hands frames, in their native layout and with their capture time, to a
//! [`FrameSlot`] where the newest frame wins; a source that fails is retried with back-off.
//! `thermal` reads a thermal sensor's 16-bit frames the same ways.

pub mod demo;
mod gst_source;
pub mod thermal;

pub use gst_source::{Ended, FileFrames, GstSource, check, open};

use crate::frame::{Frame, FrameError};
use crate::gst::GstError;
use crate::supervise::{Backoff, Locked};
use std::path::PathBuf;

/// Why a `--source` string (or the config's `source`) was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    #[error(
        "source {0:?}: expected demo, v4l2:DEVICE, gst:DESCRIPTION, file:PATH, image:PATH or \
         sequence:PATTERN"
    )]
    Form(String),
    #[error("source {0:?}: nothing after {1}:")]
    Empty(String, String),
    #[error("source {0:?}: a sequence pattern numbers its files, e.g. frames/%05d.png")]
    Pattern(String),
    #[error("source {0:?}: unknown kind {1:?}")]
    Kind(String, String),
}

/// Why a source could not start, or stopped.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("{}: no such file", .0.display())]
    NoFile(PathBuf),
    #[error("the demo source is not a GStreamer pipeline")]
    NotAPipeline,
    #[error("{0} is not a file or an image sequence")]
    NotAFile(String),
    #[error("source {spec}: {source}")]
    Pipeline { spec: String, source: GstError },
    #[error("cannot read {spec}: {source}")]
    Unreadable { spec: String, source: GstError },
    #[error(transparent)]
    Gst(#[from] GstError),
    #[error("cannot loop the source: {0}")]
    Loop(gstreamer::glib::BoolError),
    /// A decoded sample that is not a frame the renderers take.
    #[error("{0}")]
    Sample(String),
    #[error(transparent)]
    Frame(#[from] FrameError),
}
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};

/// What to read frames from, written as one string (`--source`, or `source` in the config).
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    /// `demo`: the synthetic world.
    Demo,
    /// `v4l2:/dev/video0`
    V4l2(PathBuf),
    /// `gst:<source description>`, e.g. `gst:nvarguscamerasrc ! nvvidconv`.
    Pipeline(String),
    /// `file:clip.mp4` (any container and codec GStreamer decodes).
    File(PathBuf),
    /// `image:frame.png` (PNG or JPEG), repeated at the source frame rate.
    Image(PathBuf),
    /// `sequence:frames/%05d.png`, numbered from 0, at the source frame rate.
    Sequence(String),
}

impl std::str::FromStr for SourceSpec {
    type Err = SpecError;

    fn from_str(s: &str) -> Result<Self, SpecError> {
        let s = s.trim();
        if s == "demo" {
            return Ok(SourceSpec::Demo);
        }
        let (kind, rest) = s
            .split_once(':')
            .ok_or_else(|| SpecError::Form(s.to_string()))?;
        if rest.trim().is_empty() {
            return Err(SpecError::Empty(s.to_string(), kind.to_string()));
        }
        let rest = rest.trim().to_string();
        Ok(match kind {
            "v4l2" => SourceSpec::V4l2(rest.into()),
            "gst" => SourceSpec::Pipeline(rest),
            "file" => SourceSpec::File(rest.into()),
            "image" => SourceSpec::Image(rest.into()),
            "sequence" if rest.contains('%') => SourceSpec::Sequence(rest),
            "sequence" => return Err(SpecError::Pattern(s.to_string())),
            _ => return Err(SpecError::Kind(s.to_string(), kind.to_string())),
        })
    }
}

impl std::fmt::Display for SourceSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SourceSpec::Demo => write!(f, "demo"),
            SourceSpec::V4l2(p) => write!(f, "v4l2:{}", p.display()),
            SourceSpec::Pipeline(d) => write!(f, "gst:{d}"),
            SourceSpec::File(p) => write!(f, "file:{}", p.display()),
            SourceSpec::Image(p) => write!(f, "image:{}", p.display()),
            SourceSpec::Sequence(p) => write!(f, "sequence:{p}"),
        }
    }
}

/// Counters a slot keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlotStats {
    /// Frames put in.
    pub received: u64,
    /// Frames replaced by a newer one before the frame loop took them.
    pub dropped: u64,
}

#[derive(Default)]
struct SlotInner {
    frame: Option<Frame>,
    stats: SlotStats,
    last_put: Option<Instant>,
    last_taken: Option<Instant>,
}

/// A one-frame mailbox between a source and the frame loop: a new frame replaces one not yet
/// taken (counted as dropped), so a slow renderer always gets the newest frame and nothing
/// queues up.
#[derive(Default)]
pub struct FrameSlot {
    inner: Mutex<SlotInner>,
    ready: Condvar,
}

impl FrameSlot {
    pub fn put(&self, frame: Frame) {
        let mut inner = self.inner.locked();
        inner.stats.received += 1;
        if inner.frame.replace(frame).is_some() {
            inner.stats.dropped += 1;
        }
        inner.last_put = Some(Instant::now());
        self.ready.notify_all();
    }

    /// The newest frame not yet taken and when it arrived, waiting for one until `deadline`.
    pub fn take_until(&self, deadline: Instant) -> Option<(Frame, Instant)> {
        let mut inner = self.inner.locked();
        loop {
            if let Some(f) = inner.frame.take() {
                inner.last_taken = Some(Instant::now());
                let arrived = inner.last_put.unwrap_or_else(Instant::now);
                return Some((f, arrived));
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            inner = self
                .ready
                .wait_timeout(inner, deadline - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// Whether a frame waits to be taken.
    pub fn pending(&self) -> bool {
        self.inner.locked().frame.is_some()
    }

    pub fn stats(&self) -> SlotStats {
        self.inner.locked().stats
    }

    /// How long the source has been silent (None: it never delivered): since it last put a
    /// frame, or since its frame was taken if that was later. A source that waits while its
    /// last frame is not taken (the demo) puts nothing while the frame loop is late; once the
    /// loop takes that frame, it starts on the next, and its silence starts then.
    pub fn silence(&self) -> Option<Duration> {
        let inner = self.inner.locked();
        inner.last_put.max(inner.last_taken).map(|t| t.elapsed())
    }
}

/// Waits between attempts to (re)open a failed source: 0.5 s, then 1 s, so a camera that
/// comes back shows within 2 s (reopening a camera that is not there costs next to nothing).
pub const fn backoff() -> Backoff {
    Backoff::new(Duration::from_millis(500), Duration::from_secs(1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{PixelFormat, PlaneLayout};

    #[test]
    fn source_strings_parse_and_print_back() {
        for s in [
            "demo",
            "v4l2:/dev/video0",
            "gst:videotestsrc is-live=true",
            "file:clip.mp4",
            "image:a.png",
            "sequence:f/%05d.png",
        ] {
            let spec: SourceSpec = s.parse().unwrap();
            assert_eq!(spec.to_string(), s);
        }
        for bad in ["", "cam", "file:", "sequence:f/a.png", "rtsp:x"] {
            assert!(bad.parse::<SourceSpec>().is_err(), "{bad:?} accepted");
        }
    }

    /// The demo put a frame, the loop took it 100 ms late: the source is silent from the take,
    /// not the put (from the put, a loop a second late then showed "no signal" over the demo
    /// while it drew its next frame).
    #[test]
    fn a_frame_taken_late_starts_the_silence_when_it_was_taken() {
        let slot = FrameSlot::default();
        assert_eq!(slot.silence(), None);
        let layout = PlaneLayout::tight(PixelFormat::Rgba, 1, 1).unwrap();
        let put_at = Instant::now();
        slot.put(Frame {
            data: vec![0; 4],
            layout,
            captured_us: 0,
        });
        std::thread::sleep(Duration::from_millis(100));
        assert!(slot.take_until(Instant::now()).is_some());
        let silence = slot.silence().unwrap();
        let since_put = put_at.elapsed();
        assert!(
            silence + Duration::from_millis(100) <= since_put,
            "silent {silence:?}, put {since_put:?} ago"
        );
    }

    #[test]
    fn a_slot_hands_over_the_newest_frame_and_counts_the_ones_it_replaced() {
        let slot = FrameSlot::default();
        let layout = PlaneLayout::tight(PixelFormat::Rgba, 1, 1).unwrap();
        for i in 0..3u8 {
            slot.put(Frame {
                data: vec![i; 4],
                layout,
                captured_us: i as u64,
            });
        }
        let (f, _) = slot.take_until(Instant::now()).unwrap();
        assert_eq!(f.captured_us, 2);
        assert_eq!(
            slot.stats(),
            SlotStats {
                received: 3,
                dropped: 2
            }
        );
        assert!(
            slot.take_until(Instant::now() + Duration::from_millis(20))
                .is_none()
        );
    }
}
