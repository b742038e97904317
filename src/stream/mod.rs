//! Stream: from rendered frames to the network and to disk. `encoder` turns I420 frames into
//! H.264 access units (x264 tuned for zero latency, or a hardware encoder, which `probe`
//! picks: present, and started within its deadline); `rtsp` serves them
//! as one shared media to any number of RTSP clients; `record` writes them to fragmented MP4.
//! One encoder feeds both, so recording costs no second encode; `publish` pushes the same
//! units to media relays, and `preview` to the web page's viewers. `klv` makes each frame's
//! MISB ST 0601 metadata, which travels with the frame through the encoder to the MPEG-TS
//! outputs (published and recorded).

mod delimit;
pub mod encoder;
pub mod klv;
pub mod preview;
pub mod probe;
pub mod publish;
pub mod record;
pub mod record_file;
pub mod rtsp;

pub use encoder::{AccessUnit, Encoder, EncoderConfig};
pub use preview::Preview;
pub use publish::{PublishTarget, Publisher};
pub use record::Recorder;
pub use rtsp::{Rtsp, RtspConfig};

pub use crate::gst::init;

use crate::frame::PixelFormat;
use crate::gst::GstError;
use std::path::PathBuf;

/// What went wrong encoding, serving or recording.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    #[error(transparent)]
    Gst(#[from] GstError),
    /// Every encoder tried, and why each failed.
    #[error("no H.264 encoder would start ({0})")]
    NoEncoder(String),
    #[error("not installed")]
    NotInstalled,
    #[error("did not start within {0:?}: abandoned")]
    NoStart(std::time::Duration),
    #[error("encoder {name}: {source}")]
    Encoder { name: String, source: GstError },
    #[error("encoder {name}: {flow:?}")]
    Flow {
        name: String,
        flow: gstreamer::FlowError,
    },
    #[error("the encoder takes I420, not {0}")]
    Format(PixelFormat),
    #[error("describing the frames to the encoder: {0}")]
    Caps(gstreamer::glib::BoolError),
    #[error("recording {}: {source}", path.display())]
    Recording { path: PathBuf, source: GstError },
    #[error("recording {}: {flow:?}", path.display())]
    RecordingFlow {
        path: PathBuf,
        flow: gstreamer::FlowError,
    },
    #[error(transparent)]
    Rtsp(#[from] rtsp::RtspConfigError),
    #[error("cannot serve RTSP on {0} (port in use, or not allowed)")]
    Listen(String),
    #[error("the RTSP server has no mount points")]
    NoMountPoints,
    #[error("starting the RTSP server: {0}")]
    Context(gstreamer::glib::BoolError),
    #[error("starting the {0} thread: {1}")]
    Thread(&'static str, std::io::Error),
    #[error("publishing to {url}: {source}")]
    Publish { url: String, source: GstError },
}

/// The video coding of every stream: H.264 (the default, which every player and browser
/// decodes) or H.265 (half the bitrate for the same picture, where the players take it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Codec {
    #[default]
    H264,
    H265,
}

impl Codec {
    /// The caps between the encoder, the RTSP media, the recorder and the relays: Annex B,
    /// one access unit per buffer.
    pub fn caps(self) -> &'static str {
        match self {
            Codec::H264 => "video/x-h264,stream-format=byte-stream,alignment=au",
            Codec::H265 => "video/x-h265,stream-format=byte-stream,alignment=au",
        }
    }

    /// The parser that repeats the parameter sets and fills in the caps.
    pub fn parser(self) -> &'static str {
        match self {
            Codec::H264 => "h264parse",
            Codec::H265 => "h265parse",
        }
    }

    /// The RTP payloader (RFC 6184, RFC 7798).
    pub fn payloader(self) -> &'static str {
        match self {
            Codec::H264 => "rtph264pay",
            Codec::H265 => "rtph265pay",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Codec::H264 => "H.264",
            Codec::H265 => "H.265",
        }
    }
}

/// The least step between two access units' timestamps: a millisecond, 90 ticks of the
/// RTP clock, so that units the encoder hands over together still reach clients with
/// timestamps that increase (a step under one tick, 11 µs, gives two frames the same RTP
/// timestamp, which players take for one frame).
const MIN_STEP_NS: u64 = 1_000_000;

/// Access units' timestamps moved onto a live pipeline's running time: the encoder's spacing
/// (the frames' capture spacing) kept, shifted by an offset that makes the first unit "now",
/// but never ahead of now (a live pipeline's sinks would hold an early unit back, which is
/// latency: a unit that comes out of the encoder sooner than those before moves the offset
/// down), and each at least [`MIN_STEP_NS`] after the last.
#[derive(Debug, Default)]
pub(crate) struct Restamp {
    /// Encoder timestamps + offset = running time (ns).
    offset: Option<i128>,
    last: u64,
}

impl Restamp {
    /// The running time for a unit stamped `pts` by the encoder, arriving at running time `now`.
    pub fn stamp(
        &mut self,
        pts: gstreamer::ClockTime,
        now: gstreamer::ClockTime,
    ) -> gstreamer::ClockTime {
        let (pts, now) = (pts.nseconds() as i128, now.nseconds() as i128);
        let offset = self.offset.get_or_insert(now - pts);
        if pts + *offset > now {
            *offset = now - pts;
        }
        let t = ((pts + *offset).max(0) as u64).max(self.last + MIN_STEP_NS);
        self.last = t;
        gstreamer::ClockTime::from_nseconds(t)
    }

    /// A copy of `au` stamped for a live pipeline whose running time is `now`.
    pub fn restamped(
        &mut self,
        au: &gstreamer::Buffer,
        now: gstreamer::ClockTime,
    ) -> Option<gstreamer::Buffer> {
        let t = self.stamp(au.pts()?, now);
        let mut buffer = au.copy();
        let b = buffer.make_mut();
        b.set_pts(t);
        b.set_dts(t);
        Some(buffer)
    }
}

#[cfg(test)]
mod tests {
    use super::Restamp;
    use gstreamer::ClockTime;

    fn ms(n: u64) -> ClockTime {
        ClockTime::from_mseconds(n)
    }

    #[test]
    fn units_keep_their_spacing_are_never_early_and_always_increase() {
        let mut r = Restamp::default();
        // The first unit arrives at 500 ms: its time is now.
        assert_eq!(r.stamp(ms(0), ms(500)), ms(500));
        // On time, 33 ms later: its own spacing.
        assert_eq!(r.stamp(ms(33), ms(540)), ms(533));
        // Late by 20 ms: still its spacing (the client's jitter buffer absorbs it).
        assert_eq!(r.stamp(ms(66), ms(586)), ms(566));
        // Two at once, sooner than the spacing says: never ahead of now, the offset moves.
        assert_eq!(r.stamp(ms(100), ms(590)), ms(590));
        assert_eq!(
            r.stamp(ms(133), ms(590)),
            ms(591),
            "a millisecond after the last"
        );
        assert_eq!(r.stamp(ms(166), ms(623)), ms(623));
    }
}
