//! The views alone, beside the composed frame: each view's own stream (`PATH/camN`, what the
//! MAVLink cameras give ground stations), rendered and encoded only while someone watches or
//! its camera records it, and the stills the cameras take of their view. Both render the view by itself at the
//! `[cameras]` size from the same fisheye frame and state as the composed frame, on a
//! renderer of their own (its output size never changes), after the composed frame is
//! handed to its encoder.

use super::{Head, no_signal};
use crate::frame::Frame;
use crate::lens::Lens;
use crate::render::FramePlan;
use crate::render::gpu::{Gpu, GpuError, Renderer};
use crate::state::State;
use crate::state::capture::CaptureError;
use crate::stream::Encoder;
use crate::stream::rtsp::VIEW_MOUNTS;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{error, info};

/// After an encoder for a view would not start, the next try waits this long.
const RETRY: Duration = Duration::from_secs(1);
/// A still asked for while the source is silent waits this long for a picture.
const STILL_PATIENCE: Duration = Duration::from_secs(3);

/// Why a view alone has no picture this frame: every still asked for of it is told.
#[derive(Clone, Debug, thiserror::Error)]
enum NoPicture {
    #[error("no signal from the source")]
    NoSignal,
    #[error(transparent)]
    Gpu(Arc<GpuError>),
}

/// What the views' outputs keep from frame to frame.
#[derive(Default)]
pub(super) struct ViewOutputs {
    renderer: Option<Renderer>,
    encoders: [Option<Encoder>; VIEW_MOUNTS],
    failed: [Option<Instant>; VIEW_MOUNTS],
}

impl ViewOutputs {
    /// Forgets the renderer (the GPU was rebuilt).
    pub(super) fn reset_gpu(&mut self) {
        self.renderer = None;
    }
}

/// The frame just rendered: the fisheye frame and the state and lens it was rendered with
/// (None while the source is down).
pub(super) type Rendered<'a> = Option<(&'a Frame, &'a State, &'a Lens)>;

impl Head {
    /// Feeds each watched view's stream and takes the stills asked for, from `rendered`.
    pub(super) fn render_views(
        self: &Arc<Head>,
        outs: &mut ViewOutputs,
        gpu: &Gpu,
        rendered: Rendered,
        pts: Duration,
        fps: u32,
    ) {
        let mut stills = self.capture.take_view_stills();
        if rendered.is_none() {
            // No picture now (the source fell silent a moment): a still waits for the next
            // frame that has one, up to STILL_PATIENCE, before it is refused.
            let (waiting, late) = stills
                .into_iter()
                .partition(|s| s.1.elapsed() < STILL_PATIENCE);
            self.capture.put_back_view_stills(waiting);
            stills = late;
        }
        let (w, h) = self.cfg.view_size;
        for i in 0..VIEW_MOUNTS {
            // Watched, or recorded by its camera: its stream is encoded.
            let watched = self.rtsp.view_watched(i) || self.capture.view_recording(i);
            if !watched {
                // Nobody watches: no render, no encoder.
                outs.encoders[i] = None;
            }
            let asked: Vec<_>;
            (asked, stills) = stills.into_iter().partition(|s| s.0 == i);
            if !watched && asked.is_empty() {
                continue;
            }
            let picture = match rendered {
                Some((frame, state, lens)) => {
                    let t0 = Instant::now();
                    let r = self.render_view(outs, gpu, frame, state, lens, i, w, h);
                    self.stats
                        .view_us
                        .fetch_add(t0.elapsed().as_micros() as u64, Ordering::Relaxed);
                    self.stats.views.fetch_add(1, Ordering::Relaxed);
                    r
                }
                None => Err(NoPicture::NoSignal),
            };
            for (_, _, done) in asked {
                match &picture {
                    Ok((data, layout)) => {
                        self.capture.save_view_still(data.clone(), *layout, i, done)
                    }
                    Err(e) => done(Err(CaptureError::Still(Box::new(e.clone())))),
                }
            }
            if watched {
                let (data, layout) = picture.unwrap_or_else(|_| no_signal::frame(w, h));
                self.feed_view(outs, i, data, &layout, pts, fps);
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn render_view(
        &self,
        outs: &mut ViewOutputs,
        gpu: &Gpu,
        frame: &Frame,
        state: &State,
        lens: &Lens,
        i: usize,
        w: u32,
        h: u32,
    ) -> Result<(Vec<u8>, crate::frame::PlaneLayout), NoPicture> {
        let gpu_error = |e| NoPicture::Gpu(Arc::new(e));
        if outs.renderer.is_none() {
            outs.renderer = Some(self.renderer(gpu).map_err(gpu_error)?);
        }
        let renderer = outs.renderer.as_mut().expect("made above");
        let plan = FramePlan::single_view(state, lens, i, w, h);
        let out = renderer
            .render(&frame.data, &frame.layout, &plan)
            .map_err(gpu_error)?;
        Ok((out.data, out.layout))
    }

    /// Hands view `i`'s picture to its encoder, starting one for a new watcher.
    fn feed_view(
        self: &Arc<Head>,
        outs: &mut ViewOutputs,
        i: usize,
        data: Vec<u8>,
        layout: &crate::frame::PlaneLayout,
        pts: Duration,
        fps: u32,
    ) {
        if outs.encoders[i].is_none() {
            if outs.failed[i].is_some_and(|t| t.elapsed() < RETRY) {
                return;
            }
            let head = self.clone();
            match Encoder::new(&self.cfg.encoder, fps, move |au| {
                head.rtsp.push_view(i, &au.buffer);
                head.capture.on_view_access_unit(i, &au);
            }) {
                Ok(e) => {
                    info!("camera {i}: its own stream is watched or recorded; encoding it");
                    outs.encoders[i] = Some(e);
                    outs.failed[i] = None;
                }
                Err(e) => {
                    error!("camera {i}'s stream: {e}");
                    outs.failed[i] = Some(Instant::now());
                    return;
                }
            }
        }
        let encoder = outs.encoders[i].as_mut().expect("started above");
        if self.rtsp.view_key_wanted(i) | self.capture.take_view_key_request(i) {
            encoder.force_key_unit();
        }
        if let Err(e) = encoder.push(data, layout, pts, fps) {
            error!("camera {i}'s stream: {e}; starting its encoder again");
            outs.encoders[i] = None;
        }
    }
}
