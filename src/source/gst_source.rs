//! The GStreamer sources: a camera (V4L2 or any source description), a file, a still image
//! or an image sequence, decoded and converted (only where the camera's own layout is not
//! one the GPU ingests) to NV12, I420 or RGBA, delivered by an appsink to a [`FrameSlot`].

use super::{FrameSlot, SourceError, SourceSpec};
use crate::clock::clock_us;
use crate::frame::{Frame, PixelFormat, PlaneLayout};
use crate::gst::{GstError, bus_error, element, element_error, set_state};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// What a source pipeline ends in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Tail {
    /// Formats the GPU ingests, newest buffer only (the offline reader turns dropping off).
    Video,
    /// A thermal sensor's 16-bit counts (V4L2's Y16), newest buffer only.
    Thermal,
}

impl Tail {
    fn sink(self) -> &'static str {
        match self {
            Tail::Video => {
                "videoconvert ! video/x-raw,format={NV12,I420,RGBA} \
                 ! appsink name=digiview_sink max-buffers=1 drop=true"
            }
            Tail::Thermal => {
                "videoconvert ! video/x-raw,format=GRAY16_LE \
                 ! appsink name=digiview_sink max-buffers=1 drop=true"
            }
        }
    }
}

/// How a source stopped on its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ended {
    /// Its end (a file or sequence played once).
    Eos,
    /// Asked to stop.
    Stopped,
}

pub struct GstSource {
    pipeline: gst::Pipeline,
    looped: bool,
}

fn description(
    spec: &SourceSpec,
    fps: u32,
    looped: bool,
    tail: Tail,
) -> Result<(String, bool), SourceError> {
    // (description, whether to pace at the media's own timestamps)
    let sink = tail.sink();
    Ok(match spec {
        SourceSpec::Demo => return Err(SourceError::NotAPipeline),
        SourceSpec::V4l2(_) => (format!("v4l2src name=digiview_src ! {sink}"), false),
        // A thermal description is paced at its timestamps: a recorded core's raw file
        // replayed through `rawvideoparse` is not live, and would run as fast as it can.
        SourceSpec::Pipeline(d) => (format!("{d} ! {sink}"), tail == Tail::Thermal),
        SourceSpec::File(_) => (
            format!("filesrc name=digiview_src ! decodebin ! {sink}"),
            true,
        ),
        SourceSpec::Image(p) => (
            format!(
                "filesrc name=digiview_src ! decodebin ! {} imagefreeze is-live=true \
                 ! video/x-raw,framerate={fps}/1 ! {sink}",
                if tail == Tail::Video {
                    once_to_nv12(p)
                } else {
                    ""
                }
            ),
            true,
        ),
        SourceSpec::Sequence(p) => {
            let mime = if p.to_ascii_lowercase().ends_with(".png") {
                "image/png"
            } else {
                "image/jpeg"
            };
            (
                format!(
                    "multifilesrc name=digiview_src index=0 loop={looped} \
                     caps={mime},framerate={fps}/1 ! decodebin ! {sink}"
                ),
                true,
            )
        }
    })
}

/// For a still image of even size: its conversion to NV12 (BT.709, limited range, as the
/// renderer reads it), made once before `imagefreeze` repeats it. A 4K RGBA frame costs the
/// renderer a 33 MB upload each time; NV12, 12 MB (docs/serve.md: 30 fps out of a 4K PNG
/// instead of 20). Odd sizes, and files whose size cannot be read here, stay RGBA.
fn once_to_nv12(path: &std::path::Path) -> &'static str {
    match image::image_dimensions(path) {
        Ok((w, h)) if w % 2 == 0 && h % 2 == 0 => {
            "videoconvert ! video/x-raw,format=NV12,colorimetry=bt709 !"
        }
        _ => "",
    }
}

/// The pipeline for `spec` (any kind but the demo), its appsink, and whether the sink should
/// pace frames at their timestamps.
fn build(
    spec: &SourceSpec,
    fps: u32,
    looped: bool,
    tail: Tail,
) -> Result<(gst::Pipeline, gst_app::AppSink, bool), SourceError> {
    if let SourceSpec::File(p) | SourceSpec::Image(p) = spec
        && !p.is_file()
    {
        return Err(SourceError::NoFile(p.clone()));
    }
    let (description, sync) = description(spec, fps, looped, tail)?;
    let pipeline = crate::gst::launch(&description).map_err(|source| SourceError::Pipeline {
        spec: spec.to_string(),
        source,
    })?;
    if let Some(src) = pipeline.by_name("digiview_src") {
        match spec {
            SourceSpec::V4l2(dev) => src.set_property("device", dev.to_string_lossy().as_ref()),
            SourceSpec::File(p) | SourceSpec::Image(p) => {
                src.set_property("location", p.to_string_lossy().as_ref())
            }
            SourceSpec::Sequence(p) => src.set_property("location", p.as_str()),
            _ => {}
        }
    }
    let sink: gst_app::AppSink = element(&pipeline, "digiview_sink")?;
    Ok((pipeline, sink, sync))
}

/// Whether `spec` can ever open: its file exists and its pipeline builds (nothing is started,
/// so a camera that is not plugged in yet passes).
pub fn check(spec: &SourceSpec, fps: u32) -> Result<(), SourceError> {
    check_with(spec, fps, Tail::Video)
}

/// As [`check`], for a pipeline ending in `tail`.
pub(super) fn check_with(spec: &SourceSpec, fps: u32, tail: Tail) -> Result<(), SourceError> {
    if *spec == SourceSpec::Demo {
        return Ok(());
    }
    let (pipeline, _, _) = build(spec, fps, false, tail)?;
    let _ = pipeline.set_state(gst::State::Null);
    Ok(())
}

/// Builds and starts the pipeline for `spec` (any kind but the demo); frames go to `slot`.
/// `fps` paces images and sequences; `looped` replays files and sequences at their end.
pub fn open(
    spec: &SourceSpec,
    fps: u32,
    looped: bool,
    slot: Arc<FrameSlot>,
) -> Result<GstSource, SourceError> {
    open_with(
        spec,
        (fps, looped),
        Tail::Video,
        move |sample, base| match to_frame(sample, base) {
            Ok(frame) => slot.put(frame),
            Err(e) => tracing::warn!("source: dropped a frame: {e}"),
        },
    )
}

/// Builds and starts the pipeline for `spec` ending in `tail`, each sample handed to
/// `deliver` with the pipeline; `(fps, looped)` as [`open`] takes them.
pub(super) fn open_with(
    spec: &SourceSpec,
    (fps, looped): (u32, bool),
    tail: Tail,
    deliver: impl Fn(&gst::Sample, &gst::Pipeline) + Send + Sync + 'static,
) -> Result<GstSource, SourceError> {
    let (pipeline, sink, sync) = build(spec, fps, looped, tail)?;
    sink.set_sync(sync);
    let base = pipeline.clone();
    sink.set_callbacks(
        gst_app::AppSinkCallbacks::builder()
            .new_sample(move |sink| {
                let sample = sink.pull_sample().map_err(|_| gst::FlowError::Eos)?;
                deliver(&sample, &base);
                Ok(gst::FlowSuccess::Ok)
            })
            .build(),
    );
    set_state(&pipeline, gst::State::Playing, || {
        format!("source {spec} did not start")
    })?;
    Ok(GstSource { pipeline, looped })
}

/// Every frame of a video file or an image sequence, in order, as fast as they decode (for
/// offline rendering: nothing is dropped, the decoder waits for the caller).
pub struct FileFrames {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
}

impl FileFrames {
    /// `spec` is a file or a sequence (read at `fps`).
    pub fn open(spec: &SourceSpec, fps: u32) -> Result<FileFrames, SourceError> {
        if !matches!(spec, SourceSpec::File(_) | SourceSpec::Sequence(_)) {
            return Err(SourceError::NotAFile(spec.to_string()));
        }
        let (pipeline, sink, _) = build(spec, fps, false, Tail::Video)?;
        sink.set_sync(false);
        sink.set_drop(false);
        sink.set_max_buffers(2);
        let unreadable = |source| SourceError::Unreadable {
            spec: spec.to_string(),
            source,
        };
        let refused = || "it would not start".to_string();
        set_state(&pipeline, gst::State::Paused, refused).map_err(unreadable)?;
        // Wait for the first frame (or the error that there is none).
        let bus = pipeline.bus().ok_or(GstError::NoBus)?;
        let settled = bus.timed_pop_filtered(
            gst::ClockTime::from_seconds(30),
            &[gst::MessageType::AsyncDone, gst::MessageType::Error],
        );
        if let Some(gst::MessageView::Error(e)) = settled.as_ref().map(|m| m.view()) {
            let _ = pipeline.set_state(gst::State::Null);
            return Err(unreadable(element_error(e)));
        }
        set_state(&pipeline, gst::State::Playing, refused).map_err(unreadable)?;
        Ok(FileFrames { pipeline, sink })
    }

    /// The media's length, when the container says.
    pub fn duration(&self) -> Option<std::time::Duration> {
        self.pipeline
            .query_duration::<gst::ClockTime>()
            .map(|d| std::time::Duration::from_nanos(d.nseconds()))
    }

    /// The next frame, its timestamp from the start, and the stream's frame rate (None if
    /// variable); None at the end.
    #[allow(clippy::type_complexity)]
    pub fn next_frame(
        &mut self,
    ) -> Result<Option<(Frame, std::time::Duration, Option<f64>)>, SourceError> {
        if let Some(e) = bus_error(&self.pipeline) {
            return Err(e.into());
        }
        let Ok(sample) = self.sink.pull_sample() else {
            return match bus_error(&self.pipeline) {
                Some(e) => Err(e.into()),
                None => Ok(None),
            };
        };
        let frame = to_frame(&sample, &self.pipeline)?;
        let segment = sample
            .segment()
            .and_then(|s| s.downcast_ref::<gst::ClockTime>().cloned());
        let buffer = sample
            .buffer()
            .ok_or_else(|| sample_error("without buffer"))?;
        let pts = match (buffer.pts(), segment) {
            (Some(p), Some(seg)) => seg.to_stream_time(p).unwrap_or(p),
            (Some(p), None) => p,
            _ => gst::ClockTime::ZERO,
        };
        let fps = sample
            .caps()
            .and_then(|c| gst_video::VideoInfo::from_caps(c).ok())
            .map(|i| i.fps())
            .filter(|f| f.numer() > 0 && f.denom() > 0)
            .map(|f| f.numer() as f64 / f.denom() as f64);
        Ok(Some((
            frame,
            std::time::Duration::from_nanos(pts.nseconds()),
            fps,
        )))
    }
}

impl Drop for FileFrames {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// A sample that is not a frame the renderers take.
pub(super) fn sample_error(what: impl std::fmt::Display) -> SourceError {
    SourceError::Sample(format!("a decoded sample {what}"))
}

/// Copies a decoded sample into a tightly packed frame with its capture time.
fn to_frame(sample: &gst::Sample, pipeline: &gst::Pipeline) -> Result<Frame, SourceError> {
    let video = readable(sample)?;
    let info = video.info();
    let format = match info.format() {
        gst_video::VideoFormat::Nv12 => PixelFormat::Nv12,
        gst_video::VideoFormat::I420 => PixelFormat::I420,
        gst_video::VideoFormat::Rgba => PixelFormat::Rgba,
        f => return Err(sample_error(format_args!("in the unexpected format {f:?}"))),
    };
    let layout = PlaneLayout::tight(format, info.width(), info.height())?;
    // Filled as it is copied, never zeroed first: a 4K frame is 12 MB written once, not twice.
    // A tight layout's planes follow one another and its rows have no padding.
    let mut data = Vec::with_capacity(layout.size as usize);
    for (k, plane) in layout.planes().into_iter().enumerate() {
        let src = video.plane_data(k as u32).map_err(sample_error)?;
        let stride = video.plane_stride()[k] as usize;
        let row = plane.bytes as usize;
        for y in 0..plane.rows as usize {
            data.extend_from_slice(&src[y * stride..y * stride + row]);
        }
    }
    debug_assert_eq!(data.len(), layout.size as usize);
    Ok(Frame {
        data,
        layout,
        captured_us: captured_us(video.buffer(), pipeline),
    })
}

/// A decoded sample's frame, mapped for reading.
pub(super) fn readable(
    sample: &gst::Sample,
) -> Result<gst_video::VideoFrameRef<&gst::BufferRef>, SourceError> {
    let caps = sample.caps().ok_or_else(|| sample_error("without caps"))?;
    let info = gst_video::VideoInfo::from_caps(caps).map_err(sample_error)?;
    let buffer = sample
        .buffer()
        .ok_or_else(|| sample_error("without buffer"))?;
    gst_video::VideoFrameRef::from_buffer_ref_readable(buffer, &info).map_err(sample_error)
}

/// A buffer's capture time: its running time on the pipeline's clock, as a clock reading (the
/// clock's now where the pipeline has none).
pub(super) fn captured_us(buffer: &gst::BufferRef, pipeline: &gst::Pipeline) -> u64 {
    match (buffer.pts(), pipeline.base_time()) {
        (Some(pts), Some(base)) if pipeline.clock().is_some() => (pts + base).useconds(),
        _ => clock_us(),
    }
}

impl GstSource {
    /// Runs until the source ends, fails (the error says what failed) or `stop` is set.
    pub fn run(&self, stop: &AtomicBool) -> Result<Ended, SourceError> {
        let bus = self.pipeline.bus().ok_or(GstError::NoBus)?;
        while !stop.load(Ordering::Relaxed) {
            let Some(msg) = bus.timed_pop(gst::ClockTime::from_mseconds(100)) else {
                continue;
            };
            match msg.view() {
                gst::MessageView::Error(e) => return Err(element_error(e).into()),
                gst::MessageView::Eos(_) if self.looped => {
                    self.pipeline
                        .seek_simple(
                            gst::SeekFlags::FLUSH | gst::SeekFlags::KEY_UNIT,
                            gst::ClockTime::ZERO,
                        )
                        .map_err(SourceError::Loop)?;
                }
                gst::MessageView::Eos(_) => return Ok(Ended::Eos),
                _ => {}
            }
        }
        Ok(Ended::Stopped)
    }
}

impl Drop for GstSource {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{PixelFormat, yuv};
    use image::{Rgb, RgbImage};
    use std::time::{Duration, Instant};

    /// The first frame an `image:` source hands over for a picture of one colour.
    fn first_frame(dir: &std::path::Path, (w, h): (u32, u32), rgb: [u8; 3]) -> Frame {
        let path = dir.join(format!("still_{w}x{h}.png"));
        RgbImage::from_pixel(w, h, Rgb(rgb)).save(&path).unwrap();
        let slot = Arc::new(FrameSlot::default());
        let _source = open(&SourceSpec::Image(path), 10, false, slot.clone()).unwrap();
        let (frame, _) = slot
            .take_until(Instant::now() + Duration::from_secs(20))
            .expect("a frame within 20 s");
        frame
    }

    #[test]
    fn a_still_image_is_converted_once_to_bt709_nv12_and_an_odd_sized_one_stays_rgba() {
        let dir = tempfile::tempdir().unwrap();
        // A saturated colour: BT.601 would give it another luma (Y 101 rather than 92).
        let rgb = [200, 60, 40];
        let frame = first_frame(dir.path(), (64, 36), rgb);
        assert_eq!(frame.layout.format, PixelFormat::Nv12);
        let want = yuv::encode(&RgbImage::from_pixel(64, 36, Rgb(rgb)), &frame.layout);
        let (cb, cr) = frame.layout.chroma_at(10, 10);
        for at in [0, 64 * 20 + 30, cb, cr] {
            let (got, want) = (frame.data[at], want[at]);
            assert!(
                got.abs_diff(want) <= 2,
                "byte {at}: {got}, BT.709 says {want}"
            );
        }
        let frame = first_frame(dir.path(), (63, 35), rgb);
        assert_eq!(frame.layout.format, PixelFormat::Rgba);
        assert_eq!(&frame.data[..3], &rgb);
    }
}
