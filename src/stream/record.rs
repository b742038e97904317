//! Recording the encoded stream to fragmented MP4: h264parse (h265parse) → mp4mux with
//! half-second fragments written as they complete (`streamable`, nothing rewritten at the end),
//! so a power cut loses at most the last half second and the file plays up to there. Or to MPEG-TS
//! (`Container::Ts`), which carries each frame's KLV metadata beside the video as the
//! published TS does, for mapping software, and which plays up to any cut by its nature. A
//! recording starts at a key frame; its timestamps start at zero. The file is written
//! unbuffered and opened O_SYNC, so what the muxer has written is on the disk, not in a
//! cache; once it ends, however it ends, it is cut back to what plays (`record_file`).

use super::record_file::{self, Left};
use super::{AccessUnit, Codec, StreamError};
use crate::gst::{GstError, bus_error, element, launch, set_state, wait_eos};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use std::path::{Path, PathBuf};
use tracing::warn;

/// What a recording is written as.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Container {
    /// Fragmented MP4: plays everywhere, browsers included; no KLV.
    #[default]
    Mp4,
    /// MPEG-TS with the KLV metadata (MISB ST 0601), as mapping software reads it.
    Ts,
}

impl Container {
    /// The file name's extension, with its dot.
    pub fn extension(self) -> &'static str {
        match self {
            Container::Mp4 => ".mp4",
            Container::Ts => ".ts",
        }
    }
}

pub struct Recorder {
    pipeline: gst::Pipeline,
    src: gst_app::AppSrc,
    /// The KLV metadata's, in a TS recording.
    klv: Option<gst_app::AppSrc>,
    path: PathBuf,
    container: Container,
    first_pts: Option<gst::ClockTime>,
}

impl Recorder {
    pub fn start(path: &Path, codec: Codec, container: Container) -> Result<Recorder, StreamError> {
        let video = format!(
            "appsrc name=src format=time caps={} ! {}",
            codec.caps(),
            codec.parser()
        );
        let file = "filesink name=file buffer-mode=unbuffered o-sync=true";
        let pipeline = launch(&match container {
            Container::Mp4 => {
                format!("{video} ! mp4mux fragment-duration=500 streamable=true ! {file}")
            }
            Container::Ts => format!(
                "{video} ! mpegtsmux name=mux alignment=7 ! {file} {}",
                super::klv::muxer_input(false)
            ),
        })?;
        let src: gst_app::AppSrc = element(&pipeline, "src")?;
        let klv = match container {
            Container::Ts => Some(element(&pipeline, "klv")?),
            Container::Mp4 => None,
        };
        element::<gst::Element>(&pipeline, "file")?
            .set_property("location", path.to_string_lossy().as_ref());
        set_state(&pipeline, gst::State::Playing, || {
            format!("cannot record to {}", path.display())
        })?;
        Ok(Recorder {
            pipeline,
            src,
            klv,
            path: path.to_path_buf(),
            container,
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

    /// Adds one access unit, and in a TS recording its KLV; units before the first key frame
    /// are skipped.
    pub fn push_unit(&mut self, au: &AccessUnit) -> Result<(), StreamError> {
        let Some(t) = self.push(&au.buffer, au.key)? else {
            return Ok(());
        };
        if let (Some(src), Some(packet)) = (&self.klv, &au.klv) {
            let _ = src.push_buffer(super::klv::buffer(packet, Some(t)));
        }
        Ok(())
    }

    /// Adds one access unit; units before the first key frame are skipped. Its time in the
    /// recording, where it was added.
    pub fn push(
        &mut self,
        buffer: &gst::Buffer,
        key: bool,
    ) -> Result<Option<gst::ClockTime>, StreamError> {
        if let Some(e) = bus_error(&self.pipeline) {
            return Err(self.failed(e));
        }
        let Some(pts) = buffer.pts() else {
            return Ok(None);
        };
        let first = match self.first_pts {
            Some(f) => f,
            None if key => *self.first_pts.insert(pts),
            None => return Ok(None),
        };
        let mut b = buffer.copy();
        let t = pts.saturating_sub(first);
        {
            let b = b.make_mut();
            b.set_pts(t);
            b.set_dts(t);
        }
        self.src
            .push_buffer(b)
            .map(|_| Some(t))
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

    /// Ends the file cleanly (its last fragment written): what was left of it (removed when
    /// it held no frame).
    pub fn finish(self) -> Result<Left, StreamError> {
        let _ = self.src.end_of_stream();
        if let Some(klv) = &self.klv {
            let _ = klv.end_of_stream();
        }
        let ended = wait_eos(&self.pipeline, gst::ClockTime::from_seconds(5));
        let _ = self.pipeline.set_state(gst::State::Null);
        let left = self.tidy();
        ended.map(|()| left).map_err(|e| self.failed(e))
    }

    /// Stops a recording that failed (its disk, its muxer): the file is cut back to what
    /// plays, or removed when it held no frame.
    pub fn abandon(self) -> Left {
        let _ = self.pipeline.set_state(gst::State::Null);
        self.tidy()
    }

    fn tidy(&self) -> Left {
        record_file::tidy(&self.path, self.container).unwrap_or_else(|e| {
            warn!("recording {}: {e}", self.path.display());
            Left::Kept { cut: 0 }
        })
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
