//! `digiview serve`'s configuration file (TOML), the assembly's: one section per service,
//! each section's type owned by the service it configures. Every key has a default, so an
//! empty file (or none) runs the demo source with the stream at rtsp://HOST:8554/digiview;
//! docs/serve.md lists them all. Unknown keys are errors that name the key.

use crate::autopilot::{EndpointError, MavlinkConfig};
use crate::cameras::CamerasConfig;
use crate::control::ControlConfig;
use crate::detect::DetectionConfig;
use crate::exposure::ExposureConfig;
use crate::geometry::shutter::Readout;
use crate::head::HeadConfig;
use crate::head::capture::CaptureConfig;
use crate::http::HttpConfig;
use crate::modes::GpuBackend;
use crate::source::demo::DemoConfig;
use crate::source::thermal::ThermalConfig;
use crate::source::{SourceSpec, SpecError};
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
    /// A thermal sensor beside the fisheye (docs/thermal.md); off by default.
    pub thermal: ThermalConfig,
    /// Who runs the auto exposure of a V4L2 camera.
    pub exposure: ExposureConfig,
    pub control: ControlConfig,
    pub rtsp: RtspConfig,
    pub encoder: EncoderConfig,
    pub capture: CaptureConfig,
    pub mavlink: MavlinkConfig,
    /// The payload SDK's link: one view as a Gremsy-style payload (docs/mavlink.md).
    pub payload: crate::payload::PayloadConfig,
    /// The views as MAVLink cameras, and their own streams.
    pub cameras: CamerasConfig,
    /// The head's HTTP server (the cameras' definition file).
    pub http: HttpConfig,
    /// Finding and tracking objects for the detection tiles.
    pub detection: DetectionConfig,
    /// Relays to publish the stream to: `rtsp://HOST:PORT/PATH` (RTSP RECORD),
    /// `srt://HOST:PORT` (MPEG-TS over SRT) or `udp://HOST:PORT` (MPEG-TS over UDP, unicast
    /// or multicast). The MPEG-TS ones carry KLV metadata (MISB ST 0601) beside the video.
    pub publish: Vec<String>,
    /// Relays for the views' own streams, `CAMERA=URL` (`2=udp://239.1.2.3:5602`), the URLs
    /// as in `publish`; a view published is rendered and encoded all the time.
    pub publish_views: Vec<String>,
    /// The camera whose view the composed stream's KLV metadata describes (0..=3).
    pub klv_camera: usize,
    /// Whether the KLV lists the tracked objects (ST 0903 VMTI in tag 74); false leaves them
    /// out, for readers that fail on tag 74 (klvdata 0.0.3).
    pub klv_objects: bool,
    /// Seconds between the one-line health summaries in the log (0: none).
    pub health_interval_s: f64,
    /// The camera's rolling shutter, corrected in every view (docs/serve.md, "Rolling
    /// shutter"); none by default.
    pub readout: Readout,
    /// Which GPU backend renders: auto (the best adapter that draws a known frame right),
    /// vulkan or gl (docs/onboard.md).
    pub gpu_backend: GpuBackend,
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
            thermal: ThermalConfig::default(),
            exposure: ExposureConfig::default(),
            control: ControlConfig::default(),
            rtsp: RtspConfig::default(),
            encoder: EncoderConfig::default(),
            capture: CaptureConfig::default(),
            mavlink: MavlinkConfig::default(),
            payload: Default::default(),
            cameras: CamerasConfig::default(),
            http: HttpConfig::default(),
            detection: DetectionConfig::default(),
            publish: Vec::new(),
            publish_views: Vec::new(),
            klv_camera: 0,
            klv_objects: true,
            health_interval_s: 10.0,
            readout: Readout::default(),
            gpu_backend: GpuBackend::Auto,
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
    Mavlink(#[from] EndpointError),
    /// A value outside its range: the key, the value and the range.
    #[error("{0}")]
    Range(String),
}

fn out_of_range(message: String) -> Result<(), ConfigError> {
    Err(ConfigError::Range(message))
}

impl Config {
    /// The head's parts, from a checked configuration.
    pub fn head(&self) -> Result<HeadConfig, ConfigError> {
        Ok(HeadConfig {
            source: self.source.parse()?,
            source_fps: self.source_fps,
            source_loop: self.source_loop,
            demo: self.demo.clone(),
            exposure: self.exposure.clone(),
            encoder: self.encoder.clone(),
            view_size: (self.cameras.width, self.cameras.height),
            detection: self.detection.clone(),
            health_interval_s: self.health_interval_s,
            klv_camera: self.klv_camera,
            klv_objects: self.klv_objects,
            readout: self.readout,
            gpu_backend: self.gpu_backend,
        })
    }

    /// The relays of `publish`, checked.
    pub fn publish_targets(&self) -> Result<Vec<PublishTarget>, PublishError> {
        self.publish.iter().map(|u| u.parse()).collect()
    }

    /// The views' relays of `publish_views`, checked: (camera, target).
    pub fn view_publish_targets(&self) -> Result<Vec<(usize, PublishTarget)>, PublishError> {
        let view_target = crate::stream::publish::view_target;
        self.publish_views.iter().map(|t| view_target(t)).collect()
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
        self.source.parse::<SourceSpec>()?;
        self.readout
            .check()
            .map_err(|e| ConfigError::Range(e.to_string()))?;
        // Every number against its rule (config_rules); what joins numbers follows.
        self.check_ranges()?;
        let d = &self.demo;
        if d.format.is_yuv() && (d.width % 2 == 1 || d.height % 2 == 1) {
            return out_of_range(format!(
                "demo size {}x{} must be even for {}",
                d.width, d.height, d.format
            ));
        }
        if d.stamp && !d.format.is_yuv() {
            return out_of_range("demo stamp needs a 4:2:0 format (nv12 or i420)".into());
        }
        if let Err(e) = self.thermal.setup() {
            return out_of_range(e.to_string());
        }
        if let Err(e) = crate::detect::onnx::wanted(&self.detection.classes) {
            return out_of_range(format!("detection classes: {e}"));
        }
        self.rtsp.check()?;
        let dir = &self.capture.dir;
        if dir.exists() && !dir.is_dir() {
            return out_of_range(format!(
                "capture dir {} is not a directory: name a directory (made where missing)",
                dir.display()
            ));
        }
        if let Err(e) = self.http.address() {
            return out_of_range(e.to_string());
        }
        let c = &self.cameras;
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
        self.view_publish_targets()?;
        self.check_mavlink()?;
        self.check_encoder()
    }

    /// The MAVLink link's key and endpoint.
    fn check_mavlink(&self) -> Result<(), ConfigError> {
        if self
            .mavlink
            .signing_key
            .as_ref()
            .is_some_and(|k| k.trim().is_empty())
        {
            return out_of_range(
                "mavlink signing_key is empty: give 64 hex digits or a passphrase, or leave the \
                 key out to sign nothing"
                    .into(),
            );
        }
        self.mavlink
            .endpoint
            .parse::<crate::autopilot::Endpoint>()?;
        let payload = self
            .payload
            .endpoint
            .parse::<crate::autopilot::Endpoint>()?;
        if payload != crate::autopilot::Endpoint::Off {
            if !self.cameras.enabled {
                return out_of_range(
                    "payload endpoint needs the views as cameras: set [cameras] enabled = true"
                        .into(),
                );
            }
            if self.payload.endpoint == self.mavlink.endpoint {
                return out_of_range(format!(
                    "payload endpoint {} is the autopilot link's too: give it a port of its own \
                     (the SDK's is 14566)",
                    self.payload.endpoint
                ));
            }
        }
        Ok(())
    }

    /// An encoder named for the codec it encodes.
    fn check_encoder(&self) -> Result<(), ConfigError> {
        let named = match self.encoder.kind.as_str() {
            "x264" | "x265" => Some(&self.encoder.kind[..]),
            k if k.contains("h264") => Some("x264"),
            k if k.contains("h265") => Some("x265"),
            _ => None,
        };
        let wanted = match self.encoder.codec {
            crate::stream::Codec::H264 => "x264",
            crate::stream::Codec::H265 => "x265",
        };
        if named.is_some_and(|n| n != wanted) {
            return out_of_range(format!(
                "encoder kind {} does not encode {} (codec = \"{}\"): use \"auto\" or an {} encoder",
                self.encoder.kind,
                self.encoder.codec.name(),
                format!("{:?}", self.encoder.codec).to_lowercase(),
                self.encoder.codec.name()
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
            ("klv_camera = 4", "klv_camera"),
            ("[thermal]\nfps = 0", "thermal fps 0 is outside 1..=240 fps"),
            (
                "[thermal]\nmount = { pitch = \"95deg\" }",
                "thermal mount pitch 95.00deg is outside -90.00deg..=90.00deg",
            ),
            (
                "[thermal]\nmount.yaw = nan",
                "thermal mount yaw NaNdeg is outside",
            ),
            ("[thermal]\nsource = \"cam\"", "thermal source: "),
            ("publish_views = [\"4=udp://h:5600\"]", "CAMERA=URL"),
            ("[mavlink]\nsigning_key = \"\"", "signing_key is empty"),
            ("[mavlink]\nsigning_key = \"  \"", "signing_key is empty"),
            ("publish_views = [\"udp://h:5600\"]", "CAMERA=URL"),
            ("publish_views = [\"1=udp://h\"]", "needs a port"),
            (
                "[readout]\ntime_ms = 250",
                "readout time_ms 250.0 is outside 0..=100",
            ),
            ("[readout]\ntime_ms = nan", "readout time_ms NaN"),
            ("[readout]\ndirection = \"sideways\"", "top_to_bottom"),
            ("[readout]\ntimestamp = \"now\"", "start"),
            (
                "[payload]\nendpoint = \"udpin:0.0.0.0:14550\"",
                "a port of its own",
            ),
            (
                "[payload]\nendpoint = \"udp:14566\"",
                "mavlink endpoint \"udp:14566\"",
            ),
            ("[payload]\nview = 4", "payload view 4 is outside 0..=3"),
            (
                "[payload]\nendpoint = \"udpin:0.0.0.0:14566\"\n[cameras]\nenabled = false",
                "needs the views as cameras",
            ),
            (
                "[demo]\nreadout_ms = -1",
                "demo readout_ms -1 is outside 0..=100 ms",
            ),
            ("[demo]\nfps = 200", "demo fps 200 is outside 1..=120 fps"),
            (
                "[mavlink]\nsystem_id = 0",
                "mavlink system_id 0 is outside 1..=255",
            ),
        ] {
            let e = Config::parse(text).unwrap_err().to_string();
            assert!(e.contains(says), "{text:?}: {e}");
        }
    }
}
