//! GStreamer plumbing shared by the sources and the stream: building a pipeline from a
//! description, finding its named elements, reading its errors, and ending it cleanly.

use gstreamer as gst;
use gstreamer::prelude::*;

/// GStreamer, initialised once; the error says what is missing.
pub fn init() -> Result<(), String> {
    gst::init().map_err(|e| format!("GStreamer cannot start: {e}"))
}

/// A pipeline from a gst-launch description.
pub fn launch(description: &str) -> Result<gst::Pipeline, String> {
    init()?;
    gst::parse::launch(description)
        .map_err(|e| e.to_string())?
        .downcast::<gst::Pipeline>()
        .map_err(|_| "not a pipeline".to_string())
}

/// The element named `name` in `pipeline`, as the type it must be (an AppSrc, an AppSink…).
pub fn element<T: IsA<gst::Element>>(pipeline: &gst::Pipeline, name: &str) -> Result<T, String> {
    pipeline
        .by_name(name)
        .and_then(|e| e.downcast::<T>().ok())
        .ok_or_else(|| format!("the pipeline has no {name} of the expected kind"))
}

/// An error message: which element, and what it said.
pub fn error_text(e: &gst::message::Error) -> String {
    let src = e
        .src()
        .map(|s| s.path_string().to_string())
        .unwrap_or_default();
    format!("{src}: {}", e.error())
}

/// The first error waiting on `pipeline`'s bus, if any (other messages before it are dropped).
pub fn bus_error(pipeline: &gst::Pipeline) -> Option<String> {
    let bus = pipeline.bus()?;
    while let Some(msg) = bus.pop_filtered(&[gst::MessageType::Error]) {
        if let gst::MessageView::Error(e) = msg.view() {
            return Some(error_text(e));
        }
    }
    None
}

/// Waits up to `limit` for `pipeline` to reach its end of stream (Ok) or fail (the error).
pub fn wait_eos(pipeline: &gst::Pipeline, limit: gst::ClockTime) -> Result<(), String> {
    let bus = pipeline.bus().ok_or("the pipeline has no bus")?;
    let msg = bus.timed_pop_filtered(limit, &[gst::MessageType::Eos, gst::MessageType::Error]);
    match msg.as_ref().map(|m| m.view()) {
        Some(gst::MessageView::Eos(_)) => Ok(()),
        Some(gst::MessageView::Error(e)) => Err(error_text(e)),
        _ => Err(format!("not finished within {limit}")),
    }
}
