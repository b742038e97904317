//! Detection and tracking, beside the frame path: detectors look at rectilinear crops the
//! renderer draws from each fisheye frame (scan views tiling the lens's field, and a crop
//! around each tracked object); their boxes, turned into directions in the world
//! (`angular`), feed the tracker (`tracker`), which keeps the seed's scored objects. The live
//! state carries the objects to the frame loop, whose detection tiles follow them, and to
//! DETECTED_ROI.

pub mod angular;
mod config;
pub mod external;
pub mod motion;
pub mod onnx;
pub mod scan;
pub mod tracker;

#[cfg(test)]
mod tests;

pub use angular::{AngularBox, Detection};
pub use config::{DetectionConfig, Detector};
pub use motion::MotionDetector;
pub use onnx::{OnnxConfig, OnnxDetector, OnnxError};
pub use tracker::{Change, Object, Tracker, Why};
