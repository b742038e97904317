//! A decoding RTSP client: rtspsrc (TCP) → rtph264depay → h264parse → avdec_h264 → RGB
//! frames with their timestamps.

use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use image::RgbImage;
use std::time::Duration;

/// rtspsrc (TCP, latency 0) → `chain` → an appsink, playing.
pub fn play(url: &str, chain: &str) -> (gst::Pipeline, gst_app::AppSink) {
    gst::init().unwrap();
    let pipeline = gst::parse::launch(&format!(
        "rtspsrc location={url} latency=0 protocols=tcp ! {chain} ! appsink name=sink sync=false"
    ))
    .unwrap()
    .downcast::<gst::Pipeline>()
    .unwrap();
    let sink = pipeline
        .by_name("sink")
        .unwrap()
        .downcast::<gst_app::AppSink>()
        .unwrap();
    pipeline.set_state(gst::State::Playing).unwrap();
    (pipeline, sink)
}

/// A decoding RTSP client: rtspsrc → H.264 decoder → RGB frames with their timestamps.
pub struct Viewer {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
}

impl Viewer {
    pub fn open(url: &str) -> Viewer {
        Viewer::open_with(url, "rtph264depay ! h264parse ! avdec_h264")
    }

    /// A client whose depayloader, parser and decoder are `chain`.
    pub fn open_with(url: &str, chain: &str) -> Viewer {
        let (pipeline, sink) = play(
            url,
            &format!("{chain} ! videoconvert ! video/x-raw,format=RGB"),
        );
        Viewer { pipeline, sink }
    }

    /// The next decoded frame and its presentation time.
    pub fn frame(&self) -> (RgbImage, gst::ClockTime) {
        let sample = self
            .sink
            .try_pull_sample(gst::ClockTime::from_seconds(20))
            .expect("a frame within 20 s");
        let info = gst_video::VideoInfo::from_caps(sample.caps().unwrap()).unwrap();
        let buffer = sample.buffer().unwrap();
        let frame = gst_video::VideoFrameRef::from_buffer_ref_readable(buffer, &info).unwrap();
        let (w, h) = (info.width(), info.height());
        let stride = frame.plane_stride()[0] as usize;
        let data = frame.plane_data(0).unwrap();
        let mut img = RgbImage::new(w, h);
        for y in 0..h as usize {
            let row = &data[y * stride..y * stride + 3 * w as usize];
            img.as_mut()[y * 3 * w as usize..(y + 1) * 3 * w as usize].copy_from_slice(row);
        }
        (img, buffer.pts().unwrap())
    }

    /// A frame decoded after this call: the frames queued before it are skipped.
    pub fn fresh_frame(&self) -> RgbImage {
        while self.sink.try_pull_sample(gst::ClockTime::ZERO).is_some() {}
        self.frame().0
    }

    /// A frame decoded after `wait` has passed.
    pub fn frame_after(&self, wait: Duration) -> RgbImage {
        std::thread::sleep(wait);
        self.fresh_frame()
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}
