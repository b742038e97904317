//! H.264 encoding: an appsrc taking the renderer's I420 frames (strides as the renderer pads
//! them, told by a video meta), the encoder, h264parse repeating SPS/PPS before every key
//! frame, and an appsink handing each access unit to the caller. A new output size or frame
//! rate is a caps change on the appsrc: the encoder reconfigures in place, the stream goes on.

use super::{Codec, StreamError, probe};
use crate::clock::{Stamps, clock_us};
use crate::frame::{PixelFormat, PlaneLayout};
use crate::gst::{GstError, bus_error, element, launch, wait_eos};
use crate::supervise::Locked;
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Frames the encoder may hold before new ones are dropped (it has fallen behind).
const BACKLOG: usize = 3;

/// The bitrates every entry takes (the config's `encoder.bitrate_kbps`, `render
/// --bitrate-kbps`), in kbit/s.
pub const BITRATE_KBPS: (u32, u32) = (100, 100_000);

#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct EncoderConfig {
    /// "auto" (a hardware encoder if one is installed, else x264 or x265), "x264", "x265",
    /// or an element name such as "vaapih264enc".
    pub kind: String,
    /// "h264" (the default) or "h265".
    pub codec: Codec,
    pub bitrate_kbps: u32,
    /// Seconds between key frames (clients joining also get one at once).
    pub key_interval_s: f64,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            kind: "auto".into(),
            codec: Codec::H264,
            bitrate_kbps: 4000,
            key_interval_s: 2.0,
        }
    }
}

/// One encoded access unit.
pub struct AccessUnit {
    pub buffer: gst::Buffer,
    pub key: bool,
    /// From push to this unit leaving the encoder.
    pub encode_time: Option<Duration>,
    /// The frame's stamps as pushed, with `encoded` set as it left the encoder.
    pub stamps: Option<Stamps>,
    /// The frame's KLV metadata as pushed (`Side::klv`), for the MPEG-TS outputs.
    pub klv: Option<Arc<[u8]>>,
    /// The presentation time the frame was pushed with (the encoder shifts its output's by
    /// an offset of its own): what the frame loop and the page's rings know it by.
    pub pushed_pts: Option<Duration>,
}

/// What a frame carries to its access unit besides its picture.
#[derive(Clone, Debug, Default)]
pub struct Side {
    /// Its way out, stage by stage (`encoder_in` is set as it is pushed).
    pub stamps: Option<Stamps>,
    /// Its KLV packet (MISB ST 0601), stamped with the unit's time where it is muxed.
    pub klv: Option<Arc<[u8]>>,
}

type Sink = Box<dyn Fn(AccessUnit) + Send + Sync>;

/// The frames in the encoder, oldest first: when each was pushed, its presentation time, and
/// what it carries.
type Pending = Arc<Mutex<VecDeque<(Instant, Duration, Side)>>>;

pub struct Encoder {
    pipeline: gst::Pipeline,
    src: gst_app::AppSrc,
    element: gst::Element,
    name: String,
    caps: Option<(u32, u32, u32)>,
    pending: Pending,
    /// Frames refused because the encoder was behind.
    pub dropped: u64,
    /// Wait for the encoder instead of dropping (offline rendering).
    blocking: bool,
}

fn element_description(name: &str, cfg: &EncoderConfig, fps: u32) -> String {
    let key = ((cfg.key_interval_s * fps as f64).round() as u32).max(1);
    match name {
        "x264enc" | "x265enc" => format!(
            "{name} name=enc tune=zerolatency speed-preset=ultrafast bitrate={} key-int-max={key}",
            cfg.bitrate_kbps
        ),
        "vaapih264enc" | "vaapih265enc" => format!(
            "{name} name=enc rate-control=cbr bitrate={} keyframe-period={key}",
            cfg.bitrate_kbps
        ),
        // Low-latency preset, constant bitrate, no B-frames, no lookahead.
        "nvh264enc" | "nvh265enc" => format!(
            "{name} name=enc preset=low-latency-hq rc-mode=cbr zerolatency=true bitrate={} \
             gop-size={key}",
            cfg.bitrate_kbps
        ),
        "nvv4l2h264enc" | "nvv4l2h265enc" => format!(
            "{name} name=enc bitrate={} iframeinterval={key} insert-sps-pps=true",
            cfg.bitrate_kbps * 1000
        ),
        other => format!("{other} name=enc"),
    }
}

impl Encoder {
    /// Starts the encoder; `sink` gets every access unit, on GStreamer's streaming thread.
    pub fn new(
        cfg: &EncoderConfig,
        fps: u32,
        sink: impl Fn(AccessUnit) + Send + Sync + 'static,
    ) -> Result<Encoder, StreamError> {
        super::init()?;
        let names = probe::candidates(&cfg.kind, cfg.codec, probe::usable);
        Self::first_to_start(&names, cfg, fps, sink)
    }

    /// Starts the first of encoders `names` that starts within [`probe::START_DEADLINE`];
    /// the log says which, and why each before it was passed over.
    pub fn first_to_start(
        names: &[String],
        cfg: &EncoderConfig,
        fps: u32,
        sink: impl Fn(AccessUnit) + Send + Sync + 'static,
    ) -> Result<Encoder, StreamError> {
        let sink: Arc<Sink> = Arc::new(Box::new(sink));
        let mut errors = vec![];
        for name in names {
            if probe::has_hung(name) {
                errors.push(format!("{name}: hung starting before, not tried again"));
                continue;
            }
            match Self::start(name, cfg, fps, sink.clone()) {
                Ok(e) => {
                    if !errors.is_empty() {
                        tracing::warn!("encoder: {name}, after {}", errors.join("; "));
                    }
                    return Ok(e);
                }
                Err(e) => errors.push(format!("{name}: {e}")),
            }
        }
        Err(StreamError::NoEncoder(errors.join("; ")))
    }

    fn start(
        name: &str,
        cfg: &EncoderConfig,
        fps: u32,
        sink: Arc<Sink>,
    ) -> Result<Encoder, StreamError> {
        if gst::ElementFactory::find(name).is_none() {
            return Err(StreamError::NotInstalled);
        }
        let description = format!(
            "appsrc name=src is-live=true format=time ! {} ! {} config-interval=-1 \
             ! {} ! appsink name=sink sync=false",
            element_description(name, cfg, fps),
            cfg.codec.parser(),
            cfg.codec.caps()
        );
        let pipeline = launch(&description)?;
        let src: gst_app::AppSrc = element(&pipeline, "src")?;
        let encoder: gst::Element = element(&pipeline, "enc")?;
        let appsink: gst_app::AppSink = element(&pipeline, "sink")?;
        let pending: Pending = Arc::default();
        let waiting = pending.clone();
        appsink.set_callbacks(
            gst_app::AppSinkCallbacks::builder()
                .new_sample(move |appsink| {
                    let sample = appsink.pull_sample().map_err(|_| gst::FlowError::Eos)?;
                    let Some(buffer) = sample.buffer_owned() else {
                        return Ok(gst::FlowSuccess::Ok);
                    };
                    // One unit per frame, in order (no B-frames; the encoder shifts
                    // timestamps, so they cannot be matched).
                    let pushed = waiting.locked().pop_front();
                    let encode_time = pushed.as_ref().map(|(at, _, _)| at.elapsed());
                    let pushed_pts = pushed.as_ref().map(|(_, pts, _)| *pts);
                    let side = pushed.map(|(_, _, side)| side).unwrap_or_default();
                    let stamps = side.stamps.map(|s| Stamps {
                        encoded: clock_us(),
                        ..s
                    });
                    let key = !buffer.flags().contains(gst::BufferFlags::DELTA_UNIT);
                    sink(AccessUnit {
                        buffer,
                        key,
                        encode_time,
                        stamps,
                        klv: side.klv,
                        pushed_pts,
                    });
                    Ok(gst::FlowSuccess::Ok)
                })
                .build(),
        );
        match probe::play_within(&pipeline, probe::START_DEADLINE) {
            Ok(()) => {}
            Err(Some(e)) => return Err(e.into()),
            Err(None) => {
                probe::hung(name);
                return Err(StreamError::NoStart(probe::START_DEADLINE));
            }
        }
        tracing::info!("encoder: {name}");
        Ok(Encoder {
            pipeline,
            src,
            element: encoder,
            name: name.to_string(),
            caps: None,
            pending,
            dropped: 0,
            blocking: false,
        })
    }

    /// An encoder that never drops: `push` waits while it is behind (offline rendering).
    pub fn offline(
        cfg: &EncoderConfig,
        fps: u32,
        sink: impl Fn(AccessUnit) + Send + Sync + 'static,
    ) -> Result<Encoder, StreamError> {
        let mut e = Encoder::new(cfg, fps, sink)?;
        e.blocking = true;
        Ok(e)
    }

    /// Encodes what was pushed and hands out every access unit before returning.
    pub fn finish(self) -> Result<(), StreamError> {
        let _ = self.src.end_of_stream();
        wait_eos(&self.pipeline, gst::ClockTime::from_seconds(60)).map_err(|e| self.failed(e))
    }

    fn failed(&self, source: GstError) -> StreamError {
        StreamError::Encoder {
            name: self.name.clone(),
            source,
        }
    }

    /// The encoder element in use.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Queues one I420 frame shown at `pts`. A frame is dropped (counted) while the encoder
    /// is `BACKLOG` frames behind; a new size or `fps` renegotiates the encoder first.
    pub fn push(
        &mut self,
        data: Vec<u8>,
        layout: &PlaneLayout,
        pts: Duration,
        fps: u32,
    ) -> Result<(), StreamError> {
        self.push_with(data, layout, pts, fps, Side::default())
    }

    /// As [`Encoder::push`], what the frame carries (`side`) handed on with its access unit
    /// (its stamps with `encoder_in` set now).
    pub fn push_with(
        &mut self,
        data: Vec<u8>,
        layout: &PlaneLayout,
        pts: Duration,
        fps: u32,
        side: Side,
    ) -> Result<(), StreamError> {
        if let Some(e) = bus_error(&self.pipeline) {
            return Err(self.failed(e));
        }
        if layout.format != PixelFormat::I420 {
            return Err(StreamError::Format(layout.format));
        }
        let pushed_pts = pts;
        let pts = gst::ClockTime::from_nseconds(pts.as_nanos() as u64);
        loop {
            let mut q = self.pending.locked();
            if q.len() < BACKLOG {
                let stamps = side.stamps.map(|s| Stamps {
                    encoder_in: clock_us(),
                    ..s
                });
                q.push_back((Instant::now(), pushed_pts, Side { stamps, ..side }));
                break;
            }
            if !self.blocking {
                self.dropped += 1;
                return Ok(());
            }
            drop(q);
            if let Some(e) = bus_error(&self.pipeline) {
                return Err(self.failed(e));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        self.set_caps(layout, fps)?;
        let buffer = i420_buffer(data, layout, pts, fps)?;
        self.src
            .push_buffer(buffer)
            .map_err(|flow| StreamError::Flow {
                name: self.name.clone(),
                flow,
            })?;
        Ok(())
    }

    /// The source's caps for I420 frames of `layout` at `fps`, set when they change.
    fn set_caps(&mut self, layout: &PlaneLayout, fps: u32) -> Result<(), StreamError> {
        let dims = (layout.width, layout.height, fps);
        if self.caps == Some(dims) {
            return Ok(());
        }
        let caps = gst_video::VideoInfo::builder(
            gst_video::VideoFormat::I420,
            layout.width,
            layout.height,
        )
        .fps(gst::Fraction::new(fps as i32, 1))
        // Said, not left to GStreamer's default, which is BT.601 below 720 lines: the
        // stream's VUI then tells players the matrix the renderer really used.
        .colorimetry(&bt709())
        .build()
        .map_err(StreamError::Caps)?
        .to_caps()
        .map_err(StreamError::Caps)?;
        self.src.set_caps(Some(&caps));
        if self.caps.is_some() {
            tracing::info!(
                "encoder: output now {}x{} at {fps} fps",
                layout.width,
                layout.height
            );
        }
        self.caps = Some(dims);
        Ok(())
    }

    /// Asks for a key frame (with SPS/PPS) as soon as possible: a client joined, or a
    /// recording starts.
    pub fn force_key_unit(&self) {
        force_key_unit(&self.element);
    }
}

fn force_key_unit(element: &gst::Element) {
    let event = gst_video::UpstreamForceKeyUnitEvent::builder()
        .all_headers(true)
        .build();
    if let Some(pad) = element.static_pad("src") {
        pad.send_event(event);
    }
}

impl Drop for Encoder {
    fn drop(&mut self) {
        let _ = self.src.end_of_stream();
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// An I420 frame as a GStreamer buffer: its planes described (`VideoMeta`), stamped at `pts`
/// for one period of `fps`.
fn i420_buffer(
    data: Vec<u8>,
    layout: &PlaneLayout,
    pts: gst::ClockTime,
    fps: u32,
) -> Result<gst::Buffer, StreamError> {
    let mut buffer = gst::Buffer::from_mut_slice(data);
    let b = buffer.get_mut().expect("a new buffer is writable");
    b.set_pts(pts);
    b.set_duration(gst::ClockTime::SECOND / fps as u64);
    gst_video::VideoMeta::add_full(
        b,
        gst_video::VideoFrameFlags::empty(),
        gst_video::VideoFormat::I420,
        layout.width,
        layout.height,
        &[0, layout.chroma[0] as usize, layout.chroma[1] as usize],
        &[
            layout.stride as i32,
            layout.chroma_stride as i32,
            layout.chroma_stride as i32,
        ],
    )
    .map_err(StreamError::Caps)?;
    Ok(buffer)
}

/// BT.709 limited range, what the renderer writes (frame::yuv).
fn bt709() -> gst_video::VideoColorimetry {
    gst_video::VideoColorimetry::new(
        gst_video::VideoColorRange::Range16_235,
        gst_video::VideoColorMatrix::Bt709,
        gst_video::VideoTransferFunction::Bt709,
        gst_video::VideoColorPrimaries::Bt709,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nvenc_is_told_the_bitrate_in_kbit_and_the_key_interval_in_frames() {
        let cfg = EncoderConfig {
            bitrate_kbps: 6000,
            key_interval_s: 2.0,
            ..EncoderConfig::default()
        };
        let d = element_description("nvh264enc", &cfg, 30);
        assert!(
            d.contains("bitrate=6000 ") && d.ends_with("gop-size=60"),
            "{d}"
        );
        assert!(d.contains("zerolatency=true"), "{d}");
    }
}
