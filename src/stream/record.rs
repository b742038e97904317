//! Recording the encoded stream to fragmented MP4: h264parse (h265parse) → mp4mux with one-second
//! fragments written as they complete (`streamable`, nothing rewritten at the end), so a
//! power cut loses at most the last second and the file plays up to there. A recording
//! starts at a key frame; its timestamps start at zero. The file is written unbuffered and
//! opened O_SYNC, so what mp4mux has written is on the disk, not in a cache.

use super::{Codec, StreamError};
use crate::gst::{GstError, bus_error, element, launch, set_state, wait_eos};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use std::path::{Path, PathBuf};

pub struct Recorder {
    pipeline: gst::Pipeline,
    src: gst_app::AppSrc,
    path: PathBuf,
    first_pts: Option<gst::ClockTime>,
}

impl Recorder {
    pub fn start(path: &Path, codec: Codec) -> Result<Recorder, StreamError> {
        let pipeline = launch(&format!(
            "appsrc name=src format=time caps={} ! {} \
             ! mp4mux fragment-duration=1000 streamable=true \
             ! filesink name=file buffer-mode=unbuffered o-sync=true",
            codec.caps(),
            codec.parser()
        ))?;
        let src: gst_app::AppSrc = element(&pipeline, "src")?;
        element::<gst::Element>(&pipeline, "file")?
            .set_property("location", path.to_string_lossy().as_ref());
        set_state(&pipeline, gst::State::Playing, || {
            format!("cannot record to {}", path.display())
        })?;
        Ok(Recorder {
            pipeline,
            src,
            path: path.to_path_buf(),
            first_pts: None,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether it has begun (its first key frame arrived).
    pub fn started(&self) -> bool {
        self.first_pts.is_some()
    }

    /// Adds one access unit; units before the first key frame are skipped.
    pub fn push(&mut self, buffer: &gst::Buffer, key: bool) -> Result<(), StreamError> {
        if let Some(e) = bus_error(&self.pipeline) {
            return Err(self.failed(e));
        }
        let Some(pts) = buffer.pts() else {
            return Ok(());
        };
        let first = match self.first_pts {
            Some(f) => f,
            None if key => *self.first_pts.insert(pts),
            None => return Ok(()),
        };
        let mut b = buffer.copy();
        {
            let b = b.make_mut();
            let t = pts.saturating_sub(first);
            b.set_pts(t);
            b.set_dts(t);
        }
        self.src
            .push_buffer(b)
            .map(|_| ())
            .map_err(|flow| StreamError::RecordingFlow {
                path: self.path.clone(),
                flow,
            })
    }

    fn failed(&self, source: GstError) -> StreamError {
        StreamError::Recording {
            path: self.path.clone(),
            source,
        }
    }

    /// Ends the file cleanly (its last fragment written) and returns its path.
    pub fn finish(self) -> Result<PathBuf, StreamError> {
        let _ = self.src.end_of_stream();
        let ended = wait_eos(&self.pipeline, gst::ClockTime::from_seconds(5));
        let _ = self.pipeline.set_state(gst::State::Null);
        ended
            .map(|()| self.path.clone())
            .map_err(|e| self.failed(e))
    }
}

/// A recording dropped without `finish` (an interrupted render, a failing stage) is stopped
/// before its pipeline goes: disposing a playing pipeline aborts GStreamer's streaming
/// thread, and the process with it.
impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}
