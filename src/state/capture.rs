//! The capture hooks, shared below the services: where CAPTURE requests go ([`Capturer`], the
//! control protocol's), and where the MAVLink cameras ask for stills and recordings of one view
//! ([`ViewShooter`]). The video pipeline takes stills and records; without one (`serve
//! --no-video`) there is nothing to capture and the request is refused, saying why.

use std::path::{Path, PathBuf};
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
        "capture directory {} is full: {free_mb} MB free, {min_free_mb} MB needed \
         (capture.min_free_mb, and 1 MB at least)",
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
    /// A still was not made: no picture (no signal, a renderer that failed), or it could
    /// not be written.
    #[error(transparent)]
    Still(Box<dyn std::error::Error + Send + Sync>),
}

/// Where and how a view's still was taken, from the frame it was drawn from: what its
/// EXIF and XMP say and what CAMERA_IMAGE_CAPTURED reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geotag {
    /// The frame's capture time, µs since 1970 (UTC).
    pub unix_us: u64,
    /// The vehicle's position at the frame.
    pub position: crate::geometry::GeoPosition,
    /// The view's orientation in the world (NED): yaw from north, pitch up from the horizon,
    /// roll, radians.
    pub view: crate::geometry::Euler,
    /// The vehicle's attitude at the frame.
    pub vehicle: crate::geometry::Euler,
    /// The view's horizontal fov, radians, when it is drawn as a pinhole (rectilinear, no
    /// distortion); None for a panorama or a fisheye crop.
    pub pinhole_fov: Option<f64>,
    /// The still's size, pixels.
    pub size: (u32, u32),
    /// Which camera took it.
    pub camera: usize,
}

impl Geotag {
    /// Camera `camera`'s still of `size` drawn with `state` (the vehicle as at the frame)
    /// from the frame captured at `unix_us`.
    pub fn of_view(state: &super::State, unix_us: u64, camera: usize, size: (u32, u32)) -> Geotag {
        use crate::modes::Crop;
        let v = &state.vehicle;
        let vehicle = v.attitude.euler();
        let cam = &state.settings.cameras[camera];
        let world = cam.steering().world_from_view(vehicle, &v.position);
        let pinhole = matches!(cam.crop(), Crop::Rectilinear | Crop::RectifiedCrop);
        Geotag {
            unix_us,
            position: v.position,
            view: crate::geometry::Euler::from_matrix(&world),
            vehicle,
            pinhole_fov: pinhole.then_some(cam.fov()),
            size,
            camera,
        }
    }
}

/// A written still: its file and where it was taken.
pub type Written = (PathBuf, Geotag);

/// Called with the still a view's still was written to, or why it was not.
pub type StillDone = Box<dyn FnOnce(Result<Written, CaptureError>) + Send>;

/// Stills and video of one view alone: what the MAVLink cameras take.
pub trait ViewShooter: Send + Sync {
    /// Takes a still of the next frame; `done` gets the file written, or why not.
    fn shoot(&self, view: usize, done: StillDone) -> Result<(), CaptureError>;
    /// Starts (`on`) or ends the recording of the view's own stream.
    fn record(&self, view: usize, on: bool) -> Result<(), CaptureError>;
    fn recording(&self, view: usize) -> bool;
    /// The directory stills and recordings go to (STORAGE_INFORMATION measures it).
    fn dir(&self) -> &Path;
    /// Removes DigiView's captures (the files it names `digiview-*`) from [`Self::dir`],
    /// never a file being written (a running recording stays whole and playable); how many.
    fn format(&self) -> std::io::Result<usize>;
}

/// Removes the files DigiView names `digiview-*` from `dir`, but those in `keep`; how many.
pub fn remove_captures(dir: &Path, keep: &[&Path]) -> std::io::Result<usize> {
    let mut n = 0;
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let path = entry.path();
        if name.to_string_lossy().starts_with("digiview-")
            && entry.file_type()?.is_file()
            && !keep.iter().any(|k| *k == path)
        {
            std::fs::remove_file(path)?;
            n += 1;
        }
    }
    Ok(n)
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
