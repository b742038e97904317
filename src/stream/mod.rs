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

use gstreamer as gst;

/// GStreamer, initialised once; the error says what is missing.
pub fn init() -> Result<(), String> {
    gst::init().map_err(|e| format!("GStreamer cannot start: {e}"))
}

/// The H.264 caps between the encoder, the RTSP media and the recorder.
pub(crate) const H264_CAPS: &str = "video/x-h264,stream-format=byte-stream,alignment=au";

/// The first error message on `pipeline`'s bus, if one is waiting.
pub(crate) fn bus_error(pipeline: &gst::Pipeline) -> Option<String> {
    use gst::prelude::*;
    let bus = pipeline.bus()?;
    while let Some(msg) = bus.pop_filtered(&[gst::MessageType::Error]) {
        if let gst::MessageView::Error(e) = msg.view() {
            let src = e.src().map(|s| s.name().to_string()).unwrap_or_default();
            return Some(format!(
                "{src}: {} ({})",
                e.error(),
                e.debug().unwrap_or_default()
            ));
        }
    }
    None
}
