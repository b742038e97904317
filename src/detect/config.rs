//! `[detection]` in the serve configuration: which detector finds objects for the detection
//! tiles, how often it scans and looks again, and the ONNX and external detectors' settings.

use super::onnx::{DEFAULT_MODEL, Decoder, OnnxConfig};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

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
            model: super::onnx::locate_model(&self.model),
            decoder: self.decoder,
            classes: self.classes.clone(),
            runtime: self.onnxruntime.clone(),
            threads: self.threads,
        }
    }
}
