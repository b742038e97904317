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

/// The H.264 caps between the encoder, the RTSP media and the recorder.
pub(crate) const H264_CAPS: &str = "video/x-h264,stream-format=byte-stream,alignment=au";
