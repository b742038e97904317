//! The video head: source → upload → GPU render → readback → H.264 → RTSP (and recording),
//! frame after frame. One service among the others: it reads the operator's settings, what
//! is sensed and the vehicle's telemetry, and knows nothing of who writes them; it writes
//! what it reports (`crate::state::Report`); the serve assembly
//! (`crate::app`) builds it from its parts of the configuration ([`HeadConfig`]) and the
//! outputs it feeds ([`HeadParts`]). A source thread (`source_thread`: a camera, file or
//! image through GStreamer, or the demo) puts frames in a newest-wins slot; the frame loop
//! (`frame_loop`, paced by `pacing`) takes the newest, renders it with the live state and the
//! attitude at its capture time (`crate::telemetry`), and feeds the encoder, whose access
//! units go to the viewers (the RTSP server, behind the `Clients` trait so the loop runs in a
//! test with a fake), the recorder (`capture`) and the relays it publishes to.
//! Output size and rate follow the live state's VIDEO_OUTPUT at each frame. Watched views get
//! streams of their own (`views`). A failed source is retried with back-off while a "no
//! signal" frame is streamed; a failed encoder or GPU is rebuilt; `health` logs a summary
//! line. `exposure` sets the camera's exposure and runs DigiView's auto exposure on new
//! frames. `detection` renders scan views of the frames for `crate::detect`'s detector and
//! tracker on a thread of their own, whose objects the detection tiles follow. Each thread
//! runs under the one supervisor (`crate::supervise`); what each stage owns is grouped in
//! `parts`.

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
mod parts;
pub mod readout_probe;
mod recording;
mod source_thread;
pub mod thermal;
mod view_pacing;
mod views;

pub use detection::DetectorError;
pub use parts::Clients;

use crate::detect::DetectionConfig;
use crate::exposure::ExposureConfig;
use crate::frame::FrameError;
use crate::geometry::shutter::Readout;
use crate::lens::LensError;
use crate::modes::GpuBackend;
use crate::render::gpu::GpuError;
use crate::source::SourceSpec;
use crate::source::demo::{DemoConfig, Flight};
use crate::state::{Gate, Report, Settings, State};
use crate::stream::rtsp::VIEW_MOUNTS;
use crate::stream::{EncoderConfig, Preview, Publisher, StreamError};
use crate::supervise::Locked;
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
    /// The backend the renderer's adapter is chosen from.
    pub gpu_backend: GpuBackend,
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

/// Shared by the head's threads: the live state it reads and writes, and its parts, each
/// owned by the stage that uses it (`parts`).
pub struct Head {
    pub cfg: HeadConfig,
    /// The settings and what is sensed; the detection stage keeps its followers through it.
    pub gate: Arc<Gate>,
    /// What the head reports: status, failures, the last frame.
    pub report: Arc<Report>,
    pub telemetry: Arc<Telemetry>,
    pub stop: Arc<AtomicBool>,
    input: parts::Input,
    outputs: parts::Outputs,
    observers: parts::Observers,
    meters: parts::Meters,
    exposure: exposure::ExposureStage,
    detection: detection::DetectionParts,
}

/// What the head reads, writes and feeds, built by the assembly.
pub struct HeadParts {
    pub gate: Arc<Gate>,
    pub report: Arc<Report>,
    pub capture: Arc<Capture>,
    /// The viewers of the streams: the RTSP server.
    pub clients: Arc<dyn Clients>,
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

impl Head {
    pub fn new(cfg: HeadConfig, parts: HeadParts) -> Arc<Head> {
        let HeadParts {
            gate,
            report,
            capture,
            clients,
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
            telemetry,
            stop: Arc::default(),
            input: parts::Input {
                slot: Arc::default(),
                error: Mutex::new(None),
                frame_size: AtomicU64::new(0),
                demo_autopilot,
                thermal,
            },
            outputs: parts::Outputs {
                clients,
                preview: Arc::new(Preview::new(key_wanted.clone())),
                capture,
                publishers,
                view_publishers,
                view_key_wanted,
                key_wanted,
            },
            observers: parts::Observers::default(),
            meters: parts::Meters::default(),
            exposure,
            detection: detection::DetectionParts::default(),
        })
    }

    /// The thermal sensor beside the fisheye, if there is one.
    pub fn thermal(&self) -> Option<&Arc<thermal::Sensor>> {
        self.input.thermal.as_ref()
    }

    /// The web page's viewers of the stream.
    pub fn preview(&self) -> Arc<Preview> {
        self.outputs.preview.clone()
    }

    /// The readout estimate, when one is asked for.
    pub fn readout_probe(&self) -> &readout_probe::ReadoutProbe {
        &self.observers.readout_probe
    }

    /// Runs the source thread, the health log and the frame loop until `stop` is set.
    pub fn run(self: &Arc<Head>) -> Result<(), HeadError> {
        let source = self.stage("source", |h| h.source_thread(h.cfg.source.clone()))?;
        let health = self.stage("health", |h| h.health_thread())?;
        let detection = self.stage("detection", |h| h.detection_thread())?;
        let thermal = match &self.input.thermal {
            Some(_) => Some(self.stage("thermal", |h| {
                if let Some(sensor) = &h.input.thermal {
                    h.thermal_thread(sensor)
                }
            })?),
            None => None,
        };
        let exposure = self.start_exposure();
        let result = self.supervised("frames", || self.frame_loop());
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = exposure {
            let _ = t.join();
        }
        let thermal = thermal.map_or(Ok(()), |t| t.join().unwrap_or(Ok(())));
        self.outputs.capture.finish();
        // The first failure is the one to report: a stage that gave up stopped the others.
        let others = [source, health, detection].map(|t| t.join().unwrap_or(Ok(())));
        result
            .and(thermal)
            .and(others.into_iter().collect::<Result<Vec<()>, _>>().map(drop))
    }

    /// Runs `work` on a thread of its own named `stage`, under the one supervisor.
    fn stage(
        self: &Arc<Head>,
        stage: &'static str,
        work: fn(&Arc<Head>),
    ) -> Result<std::thread::JoinHandle<Result<(), HeadError>>, HeadError> {
        let head = self.clone();
        thread(stage, move || {
            head.supervised(stage, || {
                work(&head);
                Ok(())
            })
        })
    }

    /// Runs `work` until it returns, started again after each panic by the one supervisor
    /// (`crate::supervise`); once it is given up, the head stops.
    fn supervised<T>(
        &self,
        stage: &'static str,
        work: impl FnMut() -> Result<T, HeadError>,
    ) -> Result<T, HeadError> {
        crate::supervise::supervised(&*self.report, stage, &self.stop, work).unwrap_or_else(|why| {
            self.stop.store(true, Ordering::Relaxed);
            Err(HeadError::Panicked(stage, why))
        })
    }

    /// Whether the encoder has put out a picture: what `serve` waits for before it says the
    /// stream is served.
    pub fn streaming(&self) -> bool {
        self.meters.stats.units.load(Ordering::Relaxed) > 0
    }

    fn set_source_error(&self, e: Option<String>) {
        *self.input.error.locked() = e;
    }

    /// Why the source is down, while it is.
    fn source_error(&self) -> Option<String> {
        self.input.error.locked().clone()
    }

    /// The newest frame's size, or the sensor's in the settings before the first.
    fn frame_size_or_sensor(&self, state: &State) -> (u32, u32) {
        let size = self.input.frame_size.load(Ordering::Relaxed);
        match ((size >> 32) as u32, size as u32) {
            (0, _) | (_, 0) => (state.settings.sensor.width, state.settings.sensor.height),
            wh => wh,
        }
    }

    /// Where the demo's movers are, while the demo is the source.
    fn demo_truth(&self) -> Option<detection::score::DemoTruth> {
        let truth = self.observers.demo_truth.locked();
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
        crate::supervise::sleep_unless(&self.stop, d);
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
