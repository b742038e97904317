//! Stream: from rendered frames to the network and to disk. `encoder` turns I420 frames into
//! H.264 access units (x264 tuned for zero latency, or a hardware encoder); `rtsp` serves them
//! as one shared media to any number of RTSP clients; `record` writes them to fragmented MP4.
//! One encoder feeds both, so recording costs no second encode.

pub mod encoder;
pub mod record;
pub mod rtsp;

pub use encoder::{Encoder, EncoderConfig};
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
}

/// The H.264 caps between the encoder, the RTSP media and the recorder.
pub(crate) const H264_CAPS: &str = "video/x-h264,stream-format=byte-stream,alignment=au";
