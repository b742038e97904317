//! The capture hook of the live state: where CAPTURE requests go. The video pipeline takes
//! stills and records; without one (`serve --no-video`) there is nothing to capture and the
//! request is refused, saying why.

use std::path::PathBuf;
use std::sync::Arc;

/// What CAPTURE's GET reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaptureStatus {
    pub recording: bool,
    pub images: u16,
    pub videos: u16,
}

/// Why a still or a recording was refused.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    #[error("there is no video pipeline (serve --no-video) to {0}")]
    NoVideo(&'static str),
    #[error("capture directory {}: {source}", dir.display())]
    Directory {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error(
        "capture directory {} has {free_mb} MB free, under the {min_free_mb} MB kept free \
         (capture.min_free_mb)",
        dir.display()
    )]
    Full {
        dir: PathBuf,
        free_mb: u64,
        min_free_mb: u64,
    },
    /// The recorder would not start (the stream's own error).
    #[error(transparent)]
    Recorder(Box<dyn std::error::Error + Send + Sync>),
}

pub trait Capturer: Send + Sync {
    /// Takes one still of the next frame.
    fn still(&self) -> Result<(), CaptureError>;
    /// Starts (`on`) or stops recording.
    fn record(&self, on: bool) -> Result<(), CaptureError>;
    fn status(&self) -> CaptureStatus;
}

impl<T: Capturer> Capturer for Arc<T> {
    fn still(&self) -> Result<(), CaptureError> {
        T::still(self)
    }
    fn record(&self, on: bool) -> Result<(), CaptureError> {
        T::record(self, on)
    }
    fn status(&self) -> CaptureStatus {
        T::status(self)
    }
}

/// The capture hook of a control server without video.
pub struct NoVideo;

impl Capturer for NoVideo {
    fn still(&self) -> Result<(), CaptureError> {
        Err(CaptureError::NoVideo("take a still from"))
    }
    fn record(&self, on: bool) -> Result<(), CaptureError> {
        if on {
            Err(CaptureError::NoVideo("record"))
        } else {
            Ok(())
        }
    }
    fn status(&self) -> CaptureStatus {
        CaptureStatus::default()
    }
}
