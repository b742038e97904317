//! The views alone, beside the composed frame: each view's own stream (`PATH/camN`, what the
//! MAVLink cameras give ground stations), rendered and encoded only while someone watches,
//! its camera records it or it is published to a relay, and the stills the cameras take of their view. Both draw the view by
//! itself at the `[cameras]` size from the fisheye frame the composed frame was just rendered
//! from, with the same state, as further outputs of the frame loop's renderer: the frame is
//! uploaded once, and every view wanted is drawn in one submission after the composed frame
//! is handed to its encoder.

use super::capture::ViewStill;
use super::view_pacing::{RateMeter, ViewPacing};
use super::{Head, no_signal};
use crate::frame::{PixelFormat, PlaneLayout};
use crate::geometry::shutter::ShutterTable;
use crate::lens::Lens;
use crate::plan::{Filter, FramePlan};
use crate::render::gpu::{GpuError, OutputId, Renderer};
use crate::state::State;
use crate::state::capture::{CaptureError, Geotag};
use crate::stream::Encoder;
use crate::stream::encoder::Side;
use crate::stream::klv::ViewMetadata;
use crate::stream::rtsp::VIEW_MOUNTS;
use crate::supervise::Locked;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
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

/// A view's picture: its bytes and their layout.
type Picture = Result<(Vec<u8>, PlaneLayout), NoPicture>;

/// What the views' outputs keep from frame to frame.
#[derive(Default)]
pub(super) struct ViewOutputs {
    /// Which watched views are drawn with each frame.
    pacing: ViewPacing,
    /// Each view's output of the frame loop's renderer, once it was drawn.
    outputs: [Option<OutputId>; VIEW_MOUNTS],
    encoders: [Option<Encoder>; VIEW_MOUNTS],
    failed: [Option<Instant>; VIEW_MOUNTS],
}

impl ViewOutputs {
    /// Forgets the outputs (the GPU and its renderer were rebuilt).
    pub(super) fn reset_gpu(&mut self) {
        self.outputs = Default::default();
    }

    /// The frame loop spent `took` on this frame, views included.
    pub(super) fn frame_done(&mut self, took: Duration) {
        self.pacing.frame_done(took);
    }
}

/// What the frame last uploaded to the renderer was rendered with: the state, the lens at the
/// frame's size, its capture time (UNIX µs, for the views' KLV) and its rolling shutter's
/// table, which the views alone and the detection scans draw it with too.
pub(super) struct Framed {
    pub state: State,
    pub lens: Lens,
    pub unix_us: u64,
    pub shutter: Option<ShutterTable>,
}

/// When a still asked for at `asked` was asked, as UNIX µs (a frame's `unix_us`).
fn asked_unix_us(asked: Instant) -> u64 {
    let ago = asked.elapsed().as_micros() as u64;
    crate::clock::unix_us(crate::clock::clock_us().saturating_sub(ago))
}

/// The frame last rendered; None while the source is down.
pub(super) type Rendered<'a> = Option<&'a Framed>;

impl Head {
    /// The stills to take with this frame: of each view the oldest asked for before the frame
    /// was taken (a trigger's picture shows that moment or later, and two triggers never share
    /// a frame, however late the frames come), or that has waited [`STILL_PATIENCE`]; the rest
    /// wait for later frames. With no picture (the source fell silent a moment) a still waits
    /// as long for one before it is refused.
    fn stills_now(&self, rendered: Rendered) -> Vec<ViewStill> {
        let patience_over = |s: &ViewStill| s.1.elapsed() >= STILL_PATIENCE;
        let (mut now, mut later) = (vec![], vec![]);
        for s in self.outputs.capture.take_view_stills() {
            let ready = match rendered {
                Some(f) => asked_unix_us(s.1) <= f.unix_us || patience_over(&s),
                None => patience_over(&s),
            };
            let taken = now.iter().any(|n: &ViewStill| n.0 == s.0);
            match ready && (!taken || rendered.is_none()) {
                true => now.push(s),
                false => later.push(s),
            }
        }
        self.outputs.capture.put_back_view_stills(later);
        now
    }

    /// Feeds the watched views' streams that are due (`ViewPacing`) and takes the stills
    /// asked for, drawn from the frame `renderer` rendered last.
    /// Each of views `wanted` alone at `(w, h)` as `framed`'s state has it, with the thermal
    /// picture where the view shows it.
    fn view_plans(&self, framed: &Framed, wanted: &[usize], (w, h): (u32, u32)) -> Vec<FramePlan> {
        let (state, lens) = (&framed.state, &framed.lens);
        wanted
            .iter()
            .map(|&i| {
                let plan = FramePlan::single_view(state, lens, i, w, h)
                    .with_shutter(framed.shutter.clone());
                let layer = self.thermal_layer(state, &plan, std::iter::once((0, i)));
                plan.with_thermal(layer)
            })
            .collect()
    }

    pub(super) fn render_views(
        self: &Arc<Head>,
        outs: &mut ViewOutputs,
        renderer: &mut Renderer,
        rendered: Rendered,
        pts: Duration,
        fps: u32,
    ) {
        let mut stills = self.stills_now(rendered);
        // Watched, recorded by its camera or published: its stream is encoded.
        let watched: [bool; VIEW_MOUNTS] = std::array::from_fn(|i| {
            self.outputs.clients.view_watched(i)
                || self.outputs.capture.view_recording(i)
                || !self.outputs.view_publishers[i].is_empty()
        });
        for (i, watched) in watched.into_iter().enumerate() {
            if !watched && outs.encoders[i].take().is_some() {
                // Nobody watches: no render, no encoder.
                outs.pacing.forget(i);
                self.gate.sensed().set_view_rate(i, None);
            }
        }
        let now = Instant::now();
        let period = Duration::from_secs_f64(1.0 / fps as f64);
        let behind = self.input.slot.pending();
        let due = outs.pacing.pick(watched, period, now, behind);
        let wanted: Vec<usize> = (0..VIEW_MOUNTS)
            .filter(|&i| due[i] || stills.iter().any(|s| s.0 == i))
            .collect();
        if wanted.is_empty() {
            return;
        }
        let pictures = match rendered {
            Some(framed) => {
                let size = self.cfg.view_size;
                let objects = self.cfg.klv_objects;
                let plans = self.view_plans(framed, &wanted, size);
                let pictures = draw_views(outs, renderer, framed, (&wanted, &plans), objects);
                let took = now.elapsed();
                outs.pacing.drawn(&wanted, took, now);
                self.meters
                    .stats
                    .view_us
                    .fetch_add(took.as_micros() as u64, Ordering::Relaxed);
                self.meters
                    .stats
                    .views
                    .fetch_add(wanted.len() as u64, Ordering::Relaxed);
                pictures
            }
            None => wanted
                .iter()
                .map(|_| (Err(NoPicture::NoSignal), None))
                .collect(),
        };
        for (i, (picture, klv)) in wanted.into_iter().zip(pictures) {
            let asked: Vec<_>;
            (asked, stills) = stills.into_iter().partition(|s| s.0 == i);
            for (_, _, done) in asked {
                match (&picture, rendered) {
                    (Ok((data, layout)), Some(f)) => {
                        let tag = Geotag::of_view(&f.state, f.unix_us, i, self.cfg.view_size);
                        self.outputs
                            .capture
                            .save_view_still((data.clone(), *layout), tag, done)
                    }
                    (Err(e), _) => done(Err(CaptureError::Still(Box::new(e.clone())))),
                    (Ok(_), None) => done(Err(CaptureError::Still(Box::new(NoPicture::NoSignal)))),
                }
            }
            if due[i] {
                let (w, h) = self.cfg.view_size;
                let (data, layout) = picture.unwrap_or_else(|_| no_signal::frame(w, h));
                let side = Side { stamps: None, klv };
                self.feed_view(outs, i, data, &layout, (pts, fps), side);
            }
        }
    }

    /// Hands view `i`'s picture to its encoder, starting one for a new watcher.
    fn feed_view(
        self: &Arc<Head>,
        outs: &mut ViewOutputs,
        i: usize,
        data: Vec<u8>,
        layout: &PlaneLayout,
        (pts, fps): (Duration, u32),
        side: Side,
    ) {
        if outs.encoders[i].is_none() {
            if outs.failed[i].is_some_and(|t| t.elapsed() < RETRY) {
                return;
            }
            let head = self.clone();
            // The rate its stream really has, from the units that leave its encoder (one
            // behind drops frames it was given) by their timestamps: what
            // VIDEO_STREAM_INFORMATION says.
            let meter = Mutex::new(RateMeter::default());
            match Encoder::new(&self.cfg.encoder, fps, move |au| {
                if let Some(pts) = au.buffer.pts() {
                    let rate = meter.locked().tick(pts.into());
                    head.gate.sensed().set_view_rate(i, rate);
                }
                head.outputs.clients.push_view(i, &au.buffer);
                head.outputs.capture.on_view_access_unit(i, &au);
                for p in &head.outputs.view_publishers[i] {
                    if p.push(&au) {
                        head.outputs.view_key_wanted[i].store(true, Ordering::Relaxed);
                    }
                }
            }) {
                Ok(e) => {
                    info!(
                        "camera {i}: its own stream is watched, recorded or published; encoding it"
                    );
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
        let relay_wants = self.outputs.view_key_wanted[i].swap(false, Ordering::Relaxed);
        if self.outputs.clients.view_key_wanted(i)
            | self.outputs.capture.take_view_key_request(i)
            | relay_wants
        {
            encoder.force_key_unit();
        }
        if let Err(e) = encoder.push_with(data, layout, pts, fps, side) {
            error!("camera {i}'s stream: {e}; starting its encoder again");
            outs.encoders[i] = None;
        }
    }
}

/// Views `wanted`, each alone as its plan says, drawn from the frame last uploaded to
/// `renderer`, in one submission: I420, with the mip filter as the composed frame
/// where a view is minified, else bilinear (`FramePlan::cheapest_filter`); and each view's
/// KLV packet for the frame captured at `time_us` (with its tracked objects if `objects`).
fn draw_views(
    outs: &mut ViewOutputs,
    renderer: &mut Renderer,
    framed: &Framed,
    (wanted, plans): (&[usize], &[FramePlan]),
    objects: bool,
) -> Vec<(Picture, Option<Arc<[u8]>>)> {
    let (state, time_us) = (&framed.state, framed.unix_us);
    let mut jobs = Vec::with_capacity(wanted.len());
    let drawn = wanted.iter().zip(plans).try_for_each(|(&i, plan)| {
        let id = match outs.outputs[i] {
            Some(id) => id,
            None => *outs.outputs[i].insert(renderer.add_output(PixelFormat::I420, Filter::Mip)?),
        };
        renderer.set_filter(id, plan.cheapest_filter())?;
        jobs.push((id, plan));
        Ok(())
    });
    let klv = wanted.iter().zip(plans).map(|(&i, plan)| {
        let name = format!("DigiView cam {i}");
        let r = plan.views[0].rect;
        let frame = Some((r.w, r.h));
        let m = ViewMetadata::of(plan, &plan.views[0], state, (time_us, frame), name)?;
        Some(m.with_objects(objects).packet().into())
    });
    let pictures: Vec<Picture> = match drawn.and_then(|()| renderer.redraw(&jobs)) {
        Ok(frames) => frames.into_iter().map(|f| Ok((f.data, f.layout))).collect(),
        Err(e) => {
            let e = Arc::new(e);
            wanted
                .iter()
                .map(|_| Err(NoPicture::Gpu(e.clone())))
                .collect()
        }
    };
    pictures.into_iter().zip(klv).collect()
}
