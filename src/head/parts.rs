//! The head's parts, each owned by the stage that uses it: where the frames come from
//! ([`Input`]: the source's slot and state, the thermal sensor), where they go ([`Outputs`]:
//! the viewers through [`Clients`], the page, the recording, the relays), what watches them
//! beside the loop ([`Observers`]: the KLV, the demo's score, the readout probe, each shown
//! every frame about to be drawn, [`Seen`], through one call of the loop) and the
//! figures the health line reads ([`Meters`]). The frame loop's viewers are a trait so the
//! loop runs in a test with a fake that keeps what it is handed.

use super::capture::Capture;
use super::detection::score::{DemoTruth, Score, rings};
use super::{DemoAutopilot, health, latency, readout_probe, thermal};
use crate::frame::Frame;
use crate::geometry::shutter::Readout;
use crate::lens::Lens;
use crate::plan::FramePlan;
use crate::render::choose::GpuChoice;
use crate::source::FrameSlot;
use crate::state::State;
use crate::stream::klv::ViewMetadata;
use crate::stream::rtsp::VIEW_MOUNTS;
use crate::stream::{Preview, Publisher, Rtsp};
use crate::supervise::Locked;
use crate::telemetry::Telemetry;
use gstreamer as gst;
use std::sync::atomic::{AtomicBool, AtomicU64};
use std::sync::{Arc, Mutex};

/// Where the streams go to their viewers: the RTSP server, or a test's fake.
pub trait Clients: Send + Sync {
    /// Hands the composed stream's access unit to its viewers.
    fn push(&self, unit: &gst::Buffer);
    /// Hands view `i`'s own stream's access unit to its viewers.
    fn push_view(&self, i: usize, unit: &gst::Buffer);
    /// Whether someone watches view `i`'s own stream.
    fn view_watched(&self, i: usize) -> bool;
    /// Whether a viewer of view `i`'s stream joined since last asked (it owes a key frame).
    fn view_key_wanted(&self, i: usize) -> bool;
    /// How many watch the composed stream.
    fn clients(&self) -> usize;
}

impl Clients for Rtsp {
    fn push(&self, unit: &gst::Buffer) {
        Rtsp::push(self, unit)
    }
    fn push_view(&self, i: usize, unit: &gst::Buffer) {
        Rtsp::push_view(self, i, unit)
    }
    fn view_watched(&self, i: usize) -> bool {
        Rtsp::view_watched(self, i)
    }
    fn view_key_wanted(&self, i: usize) -> bool {
        Rtsp::view_key_wanted(self, i)
    }
    fn clients(&self) -> usize {
        Rtsp::clients(self)
    }
}

/// Where the frames go: the composed stream's and each view's.
pub struct Outputs {
    pub clients: Arc<dyn Clients>,
    /// The web page's viewers of the stream.
    pub preview: Arc<Preview>,
    pub capture: Arc<Capture>,
    /// The relays the stream is published to.
    pub publishers: Vec<Publisher>,
    /// Each view's own stream's relays, and whether one of them owes a key frame.
    pub view_publishers: [Vec<Publisher>; VIEW_MOUNTS],
    pub view_key_wanted: [Arc<AtomicBool>; VIEW_MOUNTS],
    /// Set by the RTSP server and the relays when a client joins: a key frame is owed.
    pub key_wanted: Arc<AtomicBool>,
}

/// Where the frames come from.
pub struct Input {
    pub slot: Arc<FrameSlot>,
    /// Why the source is down, while it is.
    pub error: Mutex<Option<String>>,
    /// The newest frame's width and height (high and low 32 bits; 0 before the first).
    pub frame_size: AtomicU64,
    /// Where the demo's flight goes as an autopilot's would (None: straight into the
    /// telemetry).
    pub demo_autopilot: Option<DemoAutopilot>,
    /// The thermal sensor beside the fisheye, if there is one.
    pub thermal: Option<Arc<thermal::Sensor>>,
}

/// What watches the frames beside the loop.
#[derive(Default)]
pub struct Observers {
    /// The KLV metadata of the composed stream's last frame.
    pub klv: Mutex<Option<ViewMetadata>>,
    /// Where the demo's movers are, while the demo runs; the tracker scored against them.
    pub demo_truth: Mutex<Option<DemoTruth>>,
    pub demo_score: Mutex<Option<Score>>,
    /// The readout estimate, when one is asked for.
    pub readout_probe: Arc<readout_probe::ReadoutProbe>,
}

/// A frame about to be drawn: what the observers see of it.
pub struct Seen<'a> {
    pub frame: &'a Frame,
    pub plan: &'a FramePlan,
    /// The state it is drawn with, the vehicle as at its capture.
    pub state: &'a State,
    /// The lens at the frame's size.
    pub lens: &'a Lens,
}

impl Observers {
    /// Shows the observers a frame about to be drawn: the readout probe takes it while it
    /// measures (`like` the readout configured), the demo's score places its rings on it.
    /// They keep what they need and never hold the frame loop up.
    pub fn frame_planned(&self, seen: &Seen, like: Readout, telemetry: &Arc<Telemetry>) {
        let camera = (seen.lens, seen.state.settings.mount.euler());
        self.readout_probe
            .offer(seen.frame, camera, like, telemetry);
        let truth = self.demo_truth.locked();
        let Some(truth) = truth.as_ref() else {
            return;
        };
        let mut shared = self.demo_score.locked();
        if let Some(score) = shared.as_mut() {
            let at = (seen.plan, seen.state);
            rings(&mut score.rings, truth, at, seen.frame.captured_us);
        }
    }
}

/// The figures the health line reads.
#[derive(Default)]
pub struct Meters {
    pub stats: Stats,
    /// Where the frames' time goes, stage by stage.
    pub latency: latency::Latency,
    /// The figures over the last second.
    pub health: Mutex<health::Health>,
    /// The adapter the frame loop renders on, and why (None until it has one).
    pub gpu: Mutex<Option<GpuChoice>>,
    /// A lens pair's exposure match as the last frame left it (empty for one lens).
    pub lenses: Mutex<String>,
}

/// Counters the frame loop keeps and the health log reads.
#[derive(Default)]
pub struct Stats {
    pub out: AtomicU64,
    pub encoder_dropped: AtomicU64,
    pub render_us: AtomicU64,
    pub encode_us: AtomicU64,
    pub encoded: AtomicU64,
    /// Access units out of the encoder since the start (the stream is really serving).
    pub units: AtomicU64,
    /// Views rendered alone (their own streams and stills), and the time it took.
    pub views: AtomicU64,
    pub view_us: AtomicU64,
    /// Scans rendered (their time), and detected and tracked (theirs).
    pub scan_us: AtomicU64,
    pub scans: AtomicU64,
    pub detect_us: AtomicU64,
    /// Crops looked at again by the track step.
    pub crops: AtomicU64,
}
