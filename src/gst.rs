//! GStreamer plumbing shared by the sources and the stream: building a pipeline from a
//! description, finding its named elements, reading its errors, and ending it cleanly.

use gstreamer as gst;
use gstreamer::prelude::*;

/// What went wrong with a pipeline.
#[derive(Clone, Debug, thiserror::Error)]
pub enum GstError {
    #[error("GStreamer cannot start: {0}")]
    Init(gst::glib::Error),
    /// The description does not parse, or names an element that is not installed.
    #[error("{0}")]
    Launch(gst::glib::Error),
    #[error("not a pipeline")]
    NotAPipeline,
    #[error("the pipeline has no {0} of the expected kind")]
    NoElement(String),
    #[error("the pipeline has no bus")]
    NoBus,
    /// An element posted an error: which element, and what it said.
    #[error("{element}: {message}")]
    Element { element: String, message: String },
    /// It would not change state and posted no error saying why.
    #[error("{0}")]
    Refused(String),
    #[error("not finished within {0}")]
    Timeout(gst::ClockTime),
}

/// GStreamer, initialised once; the error says what is missing.
pub fn init() -> Result<(), GstError> {
    gst::init().map_err(GstError::Init)
}

/// A pipeline from a gst-launch description.
pub fn launch(description: &str) -> Result<gst::Pipeline, GstError> {
    init()?;
    gst::parse::launch(description)
        .map_err(GstError::Launch)?
        .downcast::<gst::Pipeline>()
        .map_err(|_| GstError::NotAPipeline)
}

/// The element named `name` in `pipeline`, as the type it must be (an AppSrc, an AppSink…).
pub fn element<T: IsA<gst::Element>>(pipeline: &gst::Pipeline, name: &str) -> Result<T, GstError> {
    pipeline
        .by_name(name)
        .and_then(|e| e.downcast::<T>().ok())
        .ok_or_else(|| GstError::NoElement(name.to_string()))
}

/// An error message: which element, and what it said.
pub fn element_error(e: &gst::message::Error) -> GstError {
    GstError::Element {
        element: e
            .src()
            .map(|s| s.path_string().to_string())
            .unwrap_or_default(),
        message: e.error().to_string(),
    }
}

/// The first error waiting on `pipeline`'s bus, if any (other messages before it are dropped).
pub fn bus_error(pipeline: &gst::Pipeline) -> Option<GstError> {
    let bus = pipeline.bus()?;
    while let Some(msg) = bus.pop_filtered(&[gst::MessageType::Error]) {
        if let gst::MessageView::Error(e) = msg.view() {
            return Some(element_error(e));
        }
    }
    None
}

/// Changes `pipeline`'s state; the error is the one an element posted, else `refused`.
pub fn set_state(
    pipeline: &gst::Pipeline,
    state: gst::State,
    refused: impl FnOnce() -> String,
) -> Result<(), GstError> {
    match pipeline.set_state(state) {
        Ok(_) => Ok(()),
        Err(_) => Err(bus_error(pipeline).unwrap_or_else(|| GstError::Refused(refused()))),
    }
}

/// Waits up to `limit` for `pipeline` to reach its end of stream (Ok) or fail (the error).
pub fn wait_eos(pipeline: &gst::Pipeline, limit: gst::ClockTime) -> Result<(), GstError> {
    let bus = pipeline.bus().ok_or(GstError::NoBus)?;
    let msg = bus.timed_pop_filtered(limit, &[gst::MessageType::Eos, gst::MessageType::Error]);
    match msg.as_ref().map(|m| m.view()) {
        Some(gst::MessageView::Eos(_)) => Ok(()),
        Some(gst::MessageView::Error(e)) => Err(element_error(e)),
        _ => Err(GstError::Timeout(limit)),
    }
}
