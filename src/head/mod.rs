//! The video head: source → upload → GPU render → readback → H.264 → RTSP (and recording),
//! frame after frame. One service among the others: it reads the operator's settings, what
//! is sensed and the vehicle's telemetry, and knows nothing of who writes them; it writes
//! what it reports (`crate::state::Report`); the serve assembly
//! (`crate::app`) builds it from its parts of the configuration ([`HeadConfig`]) and the
//! outputs it feeds ([`HeadParts`]). A source thread (`source_thread`: a camera, file or
//! image through GStreamer, or the demo) puts frames in a newest-wins slot; the frame loop
//! (`frame_loop`, paced by `pacing`) takes the newest, renders it with the live state and the
//! attitude at its capture time (`crate::telemetry`), and feeds the encoder, whose access
//! units go to the RTSP clients, the recorder (`capture`) and the relays it publishes to.
//! Output size and rate follow the live state's VIDEO_OUTPUT at each frame. Watched views get
//! streams of their own (`views`). A failed source is retried with back-off while a "no
//! signal" frame is streamed; a failed encoder or GPU is rebuilt; `health` logs a summary
//! line. `exposure` sets the camera's exposure and runs DigiView's auto exposure on new
//! frames. `detection` renders scan views of the frames for `crate::detect`'s detector and
//! tracker on a thread of their own, whose objects the detection tiles follow.

pub mod capture;
mod detection;
mod exposure;
mod external;
mod frame_loop;
mod geotag;
pub mod health;
pub mod latency;
mod no_signal;
pub mod pacing;
pub mod readout_probe;
mod recording;
mod source_thread;
mod supervise;
pub mod thermal;
mod view_pacing;
mod views;

pub use detection::DetectorError;

use crate::detect::DetectionConfig;
use crate::exposure::ExposureConfig;
use crate::frame::FrameError;
use crate::geometry::shutter::Readout;
use crate::lens::LensError;
use crate::render::gpu::GpuError;
use crate::source::demo::{DemoConfig, Flight};
use crate::source::{FrameSlot, SourceSpec};
use crate::state::{Gate, Report, Settings, State};
use crate::stream::rtsp::VIEW_MOUNTS;
use crate::stream::{EncoderConfig, Preview, Publisher, Rtsp, StreamError};
use crate::telemetry::Telemetry;
use capture::Capture;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// The head's parts of `digiview serve`'s configuration.
#[derive(Clone, Debug)]
pub struct HeadConfig {
    pub source: SourceSpec,
    /// Frame rate of image and sequence sources.
    pub source_fps: u32,
    /// Replay files and sequences from the start when they end.
    pub source_loop: bool,
    pub demo: DemoConfig,
    pub exposure: ExposureConfig,
    pub encoder: EncoderConfig,
    /// A view's own stream and stills: its picture's size (`[cameras] width`, `height`).
    pub view_size: (u32, u32),
    pub detection: DetectionConfig,
    /// Seconds between the one-line health summaries in the log (0: none).
    pub health_interval_s: f64,
    /// The camera whose view the composed stream's KLV metadata describes.
    pub klv_camera: usize,
    /// Whether the KLV lists the tracked objects (tag 74).
    pub klv_objects: bool,
    /// The camera's rolling shutter, corrected.
    pub readout: Readout,
}

/// Sends the demo's flight on as an autopilot would, from its start: what it returns runs
/// until dropped. The assembly gives one where the autopilot link listens on this machine.
pub type DemoAutopilot = Box<dyn Fn(&Flight, Instant) -> Box<dyn Send> + Send + Sync>;

/// Why the video head stopped, or could not start.
#[derive(Debug, thiserror::Error)]
pub enum HeadError {
    #[error("starting the {0} thread: {1}")]
    Thread(&'static str, std::io::Error),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Stream(#[from] StreamError),
    #[error(transparent)]
    Lens(#[from] LensError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("the {0} stage kept failing: {1}")]
    Panicked(&'static str, String),
}

/// Shared by the head's threads.
pub struct Head {
    pub cfg: HeadConfig,
    /// The settings and what is sensed; the detection stage keeps its followers through it.
    pub gate: Arc<Gate>,
    /// What the head reports: status, failures, the last frame.
    pub report: Arc<Report>,
    pub capture: Arc<Capture>,
    pub telemetry: Arc<Telemetry>,
    pub rtsp: Arc<Rtsp>,
    /// The relays the stream is published to.
    pub publishers: Vec<Publisher>,
    /// Each view's own stream's relays, and whether one of them owes a key frame.
    pub view_publishers: [Vec<Publisher>; VIEW_MOUNTS],
    view_key_wanted: [Arc<AtomicBool>; VIEW_MOUNTS],
    pub slot: Arc<FrameSlot>,
    pub stop: Arc<AtomicBool>,
    /// Set by the RTSP server when a client joins: the encoder owes it a key frame.
    pub key_wanted: Arc<AtomicBool>,
    /// The web page's viewers of the stream.
    pub preview: Arc<Preview>,
    /// Why the source is down, while it is.
    source_error: Mutex<Option<String>>,
    stats: Stats,
    /// Where the frames' time goes, stage by stage.
    latency: latency::Latency,
    /// The KLV metadata of the composed stream's last frame.
    klv: Mutex<Option<crate::stream::klv::ViewMetadata>>,
    /// Where the demo's movers are, while the demo runs; the tracker scored against them.
    demo_truth: Mutex<Option<detection::score::DemoTruth>>,
    demo_score: Mutex<Option<detection::score::Score>>,
    /// The readout estimate, when one is asked for.
    pub readout_probe: Arc<readout_probe::ReadoutProbe>,
    /// The figures over the last second.
    health: Mutex<health::Health>,
    exposure: exposure::ExposureStage,
    /// The newest scan and the newest crops for the detection thread.
    scans: detection::ScanSlot,
    /// The ONNX detector, once loaded.
    model: std::sync::OnceLock<detection::Model>,
    /// What the external detector sends, once its socket listens.
    external: std::sync::OnceLock<Arc<crate::detect::external::Inbox>>,
    /// The newest frame's width and height (high and low 32 bits; 0 before the first).
    frame_size: AtomicU64,
    /// Where the demo's flight goes as an autopilot's would (None: straight into the
    /// telemetry).
    demo_autopilot: Option<DemoAutopilot>,
    /// The thermal sensor beside the fisheye, if there is one.
    pub thermal: Option<Arc<thermal::Sensor>>,
}

/// What the head reads, writes and feeds, built by the assembly.
pub struct HeadParts {
    pub gate: Arc<Gate>,
    pub report: Arc<Report>,
    pub capture: Arc<Capture>,
    pub rtsp: Arc<Rtsp>,
    /// The relays the stream is published to.
    pub publishers: Vec<Publisher>,
    /// Each view's own stream's relays, and their key-frame requests.
    pub view_publishers: [Vec<Publisher>; VIEW_MOUNTS],
    pub view_key_wanted: [Arc<AtomicBool>; VIEW_MOUNTS],
    pub telemetry: Arc<Telemetry>,
    /// Set by the RTSP server and the relays when a client joins: a key frame is owed.
    pub key_wanted: Arc<AtomicBool>,
    pub demo_autopilot: Option<DemoAutopilot>,
    /// The thermal sensor, its lens found (`[thermal]`).
    pub thermal: Option<Arc<thermal::Sensor>>,
}

/// Counters the frame loop keeps and the health log reads.
#[derive(Default)]
struct Stats {
    out: AtomicU64,
    encoder_dropped: AtomicU64,
    render_us: AtomicU64,
    encode_us: AtomicU64,
    encoded: AtomicU64,
    /// Access units out of the encoder since the start (the stream is really serving).
    units: AtomicU64,
    /// Views rendered alone (their own streams and stills), and the time it took.
    views: AtomicU64,
    view_us: AtomicU64,
    /// Scans rendered (their time), and detected and tracked (theirs).
    scan_us: AtomicU64,
    scans: AtomicU64,
    detect_us: AtomicU64,
    /// Crops looked at again by the track step.
    crops: AtomicU64,
}

impl Head {
    pub fn new(cfg: HeadConfig, parts: HeadParts) -> Arc<Head> {
        let HeadParts {
            gate,
            report,
            capture,
            rtsp,
            publishers,
            view_publishers,
            view_key_wanted,
            telemetry,
            key_wanted,
            demo_autopilot,
            thermal,
        } = parts;
        let exposure = exposure::ExposureStage::new(&cfg.source, cfg.exposure.auto);
        Arc::new(Head {
            cfg,
            gate,
            report,
            capture,
            telemetry,
            rtsp,
            publishers,
            view_publishers,
            view_key_wanted,
            slot: Arc::default(),
            stop: Arc::default(),
            preview: Arc::new(Preview::new(key_wanted.clone())),
            key_wanted,
            source_error: Mutex::new(None),
            stats: Stats::default(),
            latency: latency::Latency::default(),
            klv: Mutex::default(),
            demo_truth: Mutex::default(),
            demo_score: Mutex::default(),
            readout_probe: Arc::default(),
            health: Mutex::default(),
            exposure,
            scans: detection::ScanSlot::default(),
            model: std::sync::OnceLock::new(),
            external: std::sync::OnceLock::new(),
            frame_size: AtomicU64::new(0),
            demo_autopilot,
            thermal,
        })
    }

    /// Runs the source thread, the health log and the frame loop until `stop` is set.
    pub fn run(self: &Arc<Head>) -> Result<(), HeadError> {
        let spec = self.cfg.source.clone();
        let source = {
            let head = self.clone();
            thread("source", move || {
                head.supervised("source", || {
                    head.source_thread(spec.clone());
                    Ok(())
                })
            })?
        };
        let health = {
            let head = self.clone();
            thread("health", move || {
                head.supervised("health", || {
                    head.health_thread();
                    Ok(())
                })
            })?
        };
        let detection = {
            let head = self.clone();
            thread("detection", move || {
                head.supervised("detection", || {
                    head.detection_thread();
                    Ok(())
                })
            })?
        };
        let thermal = match self.thermal.clone() {
            Some(sensor) => {
                let head = self.clone();
                Some(thread("thermal", move || {
                    head.supervised("thermal", || {
                        head.thermal_thread(&sensor);
                        Ok(())
                    })
                })?)
            }
            None => None,
        };
        let exposure = self.start_exposure();
        let result = self.supervised("frames", || self.frame_loop());
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = exposure {
            let _ = t.join();
        }
        let thermal = thermal.map_or(Ok(()), |t| t.join().unwrap_or(Ok(())));
        self.capture.finish();
        // The first failure is the one to report: a stage that gave up stopped the others.
        let others = [source, health, detection].map(|t| t.join().unwrap_or(Ok(())));
        result
            .and(thermal)
            .and(others.into_iter().collect::<Result<Vec<()>, _>>().map(drop))
    }

    /// Whether the encoder has put out a picture: what `serve` waits for before it says the
    /// stream is served.
    pub fn streaming(&self) -> bool {
        self.stats.units.load(Ordering::Relaxed) > 0
    }

    fn set_source_error(&self, e: Option<String>) {
        *self.source_error.lock().unwrap_or_else(|e| e.into_inner()) = e;
    }

    /// Why the source is down, while it is.
    fn source_error(&self) -> Option<String> {
        self.source_error
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The newest frame's size, or the sensor's in the settings before the first.
    fn frame_size_or_sensor(&self, state: &State) -> (u32, u32) {
        let size = self.frame_size.load(Ordering::Relaxed);
        match ((size >> 32) as u32, size as u32) {
            (0, _) | (_, 0) => (state.settings.sensor.width, state.settings.sensor.height),
            wh => wh,
        }
    }

    /// Where the demo's movers are, while the demo is the source.
    fn demo_truth(&self) -> Option<detection::score::DemoTruth> {
        let truth = self.demo_truth.lock().unwrap_or_else(|e| e.into_inner());
        truth.clone()
    }
}

impl Head {
    /// The operator's settings now.
    pub fn settings(&self) -> Arc<Settings> {
        self.gate.settings().snapshot()
    }

    /// The state now: the settings with the vehicle and objects as last sensed.
    pub fn state(&self) -> State {
        State::now(self.gate.settings(), self.gate.sensed())
    }

    /// Puts in `s` the vehicle's attitude and position at `t_us`, as far as the telemetry
    /// knows them (what it does not know is left as it was).
    fn vehicle_at(&self, s: &mut State, t_us: u64) {
        let (attitude, position) = self.telemetry.at(t_us);
        if let Some(a) = attitude {
            let v = &mut s.vehicle.attitude;
            (v.yaw, v.pitch, v.roll) = (a.yaw, a.pitch, a.roll);
        }
        if let Some(p) = position {
            s.vehicle.position = p;
        }
    }

    /// Waits `d`, or less once the head is stopping.
    fn pause(&self, d: std::time::Duration) {
        let until = Instant::now() + d;
        while Instant::now() < until && !self.stop.load(Ordering::Relaxed) {
            std::thread::sleep(std::time::Duration::from_millis(20).min(d));
        }
    }
}

/// Starts a named thread of the head.
fn thread<T: Send + 'static>(
    name: &'static str,
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<std::thread::JoinHandle<T>, HeadError> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(work)
        .map_err(|e| HeadError::Thread(name, e))
}
