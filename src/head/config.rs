//! `digiview serve`'s configuration file (TOML). Every key has a default, so an empty file
//! (or none) runs the demo source with the stream at rtsp://HOST:8554/digiview; docs/serve.md
//! lists them all. Unknown keys are errors that name the key.

use crate::cameras::CamerasConfig;
use crate::detect::onnx::{DEFAULT_MODEL, Decoder, OnnxConfig};
use crate::frame::PixelFormat;
use crate::http::HttpConfig;
use crate::source::SpecError;
use crate::stream::PublishTarget;
use crate::stream::publish::PublishError;
use crate::stream::rtsp::RtspConfigError;
use crate::stream::{EncoderConfig, RtspConfig};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// demo, v4l2:DEVICE, gst:DESCRIPTION, file:PATH, image:PATH or sequence:PATTERN.
    pub source: String,
    /// Frame rate of image and sequence sources.
    pub source_fps: u32,
    /// Replay files and sequences from the start when they end.
    pub source_loop: bool,
    /// Lens by name or lens_id in lens.cal (default: the state's, lens_id 0).
    pub lens: Option<String>,
    /// The initial state (a state file as `digiview render --state` takes).
    pub state: Option<PathBuf>,
    pub demo: DemoConfig,
    /// Who runs the auto exposure of a V4L2 camera.
    pub exposure: ExposureConfig,
    pub control: ControlConfig,
    pub rtsp: RtspConfig,
    pub encoder: EncoderConfig,
    pub capture: CaptureConfig,
    pub mavlink: MavlinkConfig,
    /// The views as MAVLink cameras, and their own streams.
    pub cameras: CamerasConfig,
    /// The head's HTTP server (the cameras' definition file).
    pub http: HttpConfig,
    /// Finding and tracking objects for the detection tiles.
    pub detection: DetectionConfig,
    /// Relays to publish the stream to: `rtsp://HOST:PORT/PATH` (RTSP RECORD) or
    /// `srt://HOST:PORT` (MPEG-TS over SRT).
    pub publish: Vec<String>,
    /// Seconds between the one-line health summaries in the log (0: none).
    pub health_interval_s: f64,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            source: "demo".into(),
            source_fps: 30,
            source_loop: true,
            lens: None,
            state: None,
            demo: DemoConfig::default(),
            exposure: ExposureConfig::default(),
            control: ControlConfig::default(),
            rtsp: RtspConfig::default(),
            encoder: EncoderConfig::default(),
            capture: CaptureConfig::default(),
            mavlink: MavlinkConfig::default(),
            cameras: CamerasConfig::default(),
            http: HttpConfig::default(),
            detection: DetectionConfig::default(),
            publish: Vec::new(),
            health_interval_s: 10.0,
        }
    }
}

/// Which detector finds objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Detector {
    /// Things that move, by comparing scans (built in, no model file).
    Motion,
    /// A detection model run by ONNX Runtime (`model`, `decoder`, `classes`).
    Onnx,
    /// Another process's detections, JSON lines on the local socket `socket`.
    External,
    /// None: the tracked objects are only those the state gives (`--track`).
    Off,
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectionConfig {
    pub detector: Detector,
    /// Scans of the whole field a second (at most: a model slower than this sets the pace).
    pub scan_hz: f64,
    /// Track steps a second at most: the ONNX detector looks again for each object in the
    /// tiles in a crop around it (0: no track step; a model slower than this sets the pace).
    pub crop_hz: f64,
    /// The ONNX detector's model, and which layout its outputs follow.
    pub model: PathBuf,
    pub decoder: Decoder,
    /// The classes that count (COCO names or numbers); empty, all.
    pub classes: Vec<String>,
    /// ONNX Runtime's library (libonnxruntime.so), if not in ORT_DYLIB_PATH or where
    /// scripts/setup.sh puts it.
    pub onnxruntime: Option<PathBuf>,
    /// Threads the model runs on.
    pub threads: usize,
    /// The external detector's socket (a Unix socket path).
    pub socket: PathBuf,
}

impl Default for DetectionConfig {
    fn default() -> Self {
        DetectionConfig {
            detector: Detector::Motion,
            scan_hz: 3.0,
            crop_hz: 10.0,
            model: DEFAULT_MODEL.into(),
            decoder: Decoder::Nanodet,
            classes: vec![],
            onnxruntime: None,
            threads: 1,
            socket: "/tmp/digiview-detections.sock".into(),
        }
    }
}

impl DetectionConfig {
    /// The ONNX detector's settings.
    pub fn onnx(&self) -> OnnxConfig {
        OnnxConfig {
            model: crate::detect::onnx::locate_model(&self.model),
            decoder: self.decoder,
            classes: self.classes.clone(),
            runtime: self.onnxruntime.clone(),
            threads: self.threads,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DemoConfig {
    /// The demo camera's frame size (the lens is scaled to it) and rate.
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    /// Fly a circle (true) or hover at the state's attitude and position (false).
    pub motion: bool,
    /// Hover yawing 90°/s and rolling ±20° at 1 Hz, by the monotonic clock (for tests with a
    /// simulated autopilot that reports the same; the demo then sends no flight of its own).
    pub spin: bool,
    /// The layout frames arrive in, as a camera's would.
    pub format: PixelFormat,
    /// Draw each frame's capture time (ms) as a barcode at the image centre, for
    /// glass-to-glass latency (scripts/latency.sh; 4:2:0 formats only).
    pub stamp: bool,
}

impl Default for DemoConfig {
    fn default() -> Self {
        DemoConfig {
            width: 1280,
            height: 720,
            fps: 30,
            motion: true,
            spin: false,
            format: PixelFormat::Nv12,
            stamp: false,
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExposureConfig {
    /// With CAM_SENSOR's ae on: `camera` (the camera's own auto exposure, where it has one;
    /// target_brightness is then the camera's to ignore) or `software` (DigiView's, towards
    /// target_brightness, on any camera).
    pub auto: AutoExposureMode,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AutoExposureMode {
    #[default]
    Camera,
    Software,
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControlConfig {
    /// Where the control protocol listens, TCP and UDP.
    pub listen: String,
    /// Who may SET: any, none, loopback, or addresses and CIDR ranges, comma-separated.
    pub allow_set: String,
    /// Who may QUIT.
    pub allow_quit: String,
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            listen: "0.0.0.0:5010".into(),
            allow_set: "any".into(),
            allow_quit: "loopback".into(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StillFormat {
    Jpeg,
    Png,
}

impl StillFormat {
    pub fn extension(self) -> &'static str {
        match self {
            StillFormat::Jpeg => "jpg",
            StillFormat::Png => "png",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CaptureConfig {
    /// Where stills and recordings go (made if missing).
    pub dir: PathBuf,
    pub still_format: StillFormat,
    /// Also save the raw fisheye frame beside each still.
    pub raw: bool,
    /// A capture is refused while the disk has less free space than this.
    pub min_free_mb: u64,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        CaptureConfig {
            dir: "captures".into(),
            still_format: StillFormat::Jpeg,
            raw: false,
            min_free_mb: 200,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct MavlinkConfig {
    /// The autopilot link (docs/mavlink.md): `udpin:ADDR:PORT`, `udpout:HOST:PORT`,
    /// `tcpin:ADDR:PORT`, `tcpout:HOST:PORT`, `serial:DEVICE:BAUD`, or `off`.
    pub endpoint: String,
    /// Take the autopilot from this system id only (default: the first autopilot heard).
    pub system_id: Option<u8>,
    /// The ATTITUDE rate asked of the autopilot, Hz.
    pub attitude_hz: f64,
    /// The GLOBAL_POSITION_INT rate asked of the autopilot, Hz.
    pub position_hz: f64,
    /// MAVLink 2 signing: 64 hex digits (the 32-byte key), or a passphrase whose SHA-256 is
    /// the key. With it, unsigned and badly signed messages are ignored (and counted), and
    /// DigiView signs what it sends.
    pub signing_key: Option<String>,
    /// Which attitude a frame is rendered with: `interpolated` (slerp at its capture time)
    /// or `latest` (the newest sample when it is rendered; only to see what interpolation
    /// is worth).
    pub attitude_sample: AttitudeSample,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AttitudeSample {
    #[default]
    Interpolated,
    Latest,
}

impl Default for MavlinkConfig {
    fn default() -> Self {
        MavlinkConfig {
            endpoint: "udpin:0.0.0.0:14550".into(),
            system_id: None,
            attitude_hz: 100.0,
            position_hz: 10.0,
            signing_key: None,
            attitude_sample: AttitudeSample::Interpolated,
        }
    }
}

/// Why a configuration is refused.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    In {
        path: PathBuf,
        source: Box<ConfigError>,
    },
    #[error(transparent)]
    Toml(#[from] toml::de::Error),
    #[error("source: {0}")]
    Source(#[from] SpecError),
    #[error(transparent)]
    Rtsp(#[from] RtspConfigError),
    #[error(transparent)]
    Publish(#[from] PublishError),
    #[error(transparent)]
    Mavlink(#[from] crate::autopilot::EndpointError),
    /// A value outside its range: the key, the value and the range.
    #[error("{0}")]
    Range(String),
}

fn out_of_range(message: String) -> Result<(), ConfigError> {
    Err(ConfigError::Range(message))
}

impl Config {
    /// The relays of `publish`, checked.
    pub fn publish_targets(&self) -> Result<Vec<PublishTarget>, PublishError> {
        self.publish.iter().map(|u| u.parse()).collect()
    }

    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.into(),
            source,
        })?;
        Config::parse(&text).map_err(|e| ConfigError::In {
            path: path.into(),
            source: Box::new(e),
        })
    }

    pub fn parse(text: &str) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text)?;
        cfg.check()?;
        Ok(cfg)
    }

    /// Ranges and forms the types alone do not hold.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.source.parse::<crate::source::SourceSpec>()?;
        if !(1..=240).contains(&self.source_fps) {
            return out_of_range(format!("source_fps {} is outside 1..=240", self.source_fps));
        }
        let d = &self.demo;
        if d.width < 64 || d.height < 64 || d.width > 7680 || d.height > 4320 {
            return out_of_range(format!(
                "demo size {}x{} is outside 64x64..7680x4320",
                d.width, d.height
            ));
        }
        if d.format.is_yuv() && (d.width % 2 == 1 || d.height % 2 == 1) {
            return out_of_range(format!(
                "demo size {}x{} must be even for {}",
                d.width, d.height, d.format
            ));
        }
        if d.stamp && !d.format.is_yuv() {
            return out_of_range("demo stamp needs a 4:2:0 format (nv12 or i420)".into());
        }
        if !(1..=120).contains(&d.fps) {
            return out_of_range(format!("demo fps {} is outside 1..=120", d.fps));
        }
        if !(0.5..=30.0).contains(&self.detection.scan_hz) {
            return out_of_range(format!(
                "detection scan_hz {} is outside 0.5..=30",
                self.detection.scan_hz
            ));
        }
        if !(0.0..=30.0).contains(&self.detection.crop_hz) {
            return out_of_range(format!(
                "detection crop_hz {} is outside 0..=30",
                self.detection.crop_hz
            ));
        }
        if !(1..=16).contains(&self.detection.threads) {
            return out_of_range(format!(
                "detection threads {} is outside 1..=16",
                self.detection.threads
            ));
        }
        if let Err(e) = crate::detect::onnx::wanted(&self.detection.classes) {
            return out_of_range(format!("detection classes: {e}"));
        }
        self.rtsp.check()?;
        if let Err(e) = self.http.address() {
            return out_of_range(e);
        }
        let c = &self.cameras;
        let ((lo_w, lo_h), (hi_w, hi_h)) = (crate::state::MIN_OUTPUT, crate::state::MAX_OUTPUT);
        if c.width < lo_w || c.height < lo_h || c.width > hi_w || c.height > hi_h {
            return out_of_range(format!(
                "cameras size {}x{} is outside {lo_w}x{lo_h}..{hi_w}x{hi_h}",
                c.width, c.height
            ));
        }
        if c.width % 2 == 1 || c.height % 2 == 1 {
            return out_of_range(format!(
                "cameras size {}x{} must be even",
                c.width, c.height
            ));
        }
        if let Some(h) = &c.public_host
            && (h.is_empty() || h.contains(['/', ' ', '@']) || h == "0.0.0.0" || h == "::")
        {
            return out_of_range(format!(
                "cameras public_host {h:?} must be a host name or address ground stations reach"
            ));
        }
        self.publish_targets()?;
        self.mavlink
            .endpoint
            .parse::<crate::autopilot::Endpoint>()?;
        for (key, hz) in [
            ("attitude_hz", self.mavlink.attitude_hz),
            ("position_hz", self.mavlink.position_hz),
        ] {
            if !(0.1..=500.0).contains(&hz) {
                return out_of_range(format!("mavlink {key} {hz} is outside 0.1..=500"));
            }
        }
        let (lo, hi) = crate::stream::encoder::BITRATE_KBPS;
        if !(lo..=hi).contains(&self.encoder.bitrate_kbps) {
            return out_of_range(format!(
                "encoder bitrate_kbps {} is outside {lo}..={hi}",
                self.encoder.bitrate_kbps
            ));
        }
        if !(0.1..=60.0).contains(&self.encoder.key_interval_s) {
            return out_of_range(format!(
                "encoder key_interval_s {} is outside 0.1..=60",
                self.encoder.key_interval_s
            ));
        }
        if !(0.0..=3600.0).contains(&self.health_interval_s) {
            return out_of_range(format!(
                "health_interval_s {} is outside 0..=3600",
                self.health_interval_s
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_file_is_the_documented_defaults() {
        let cfg = Config::parse("").unwrap();
        assert_eq!(cfg, Config::default());
        assert_eq!(cfg.source, "demo");
        assert_eq!((cfg.rtsp.port, cfg.rtsp.path.as_str()), (8554, "/digiview"));
    }

    #[test]
    fn bad_values_are_errors_that_name_the_key() {
        for (text, says) in [
            ("sorce = \"demo\"", "sorce"),
            ("source = \"cam\"", "source"),
            ("[rtsp]\npath = \"x\"", "rtsp path"),
            ("[rtsp]\nuser = \"a\"", "password"),
            ("[demo]\nwidth = 641\nheight = 480", "even"),
            ("[encoder]\nbitrate_kbps = 5", "bitrate_kbps"),
            ("[capture]\nstill_format = \"gif\"", "still_format"),
        ] {
            let e = Config::parse(text).unwrap_err().to_string();
            assert!(e.contains(says), "{text:?}: {e}");
        }
    }
}
