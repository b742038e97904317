//! The thermal sensor's frames (`serve --thermal SOURCE`): 16-bit radiometric counts from a
//! V4L2 camera in Y16 (a FLIR Boson or Lepton on a PureThermal board), any GStreamer source
//! description that gives GRAY16_LE, a 16-bit image (PNG or TIFF) or image sequence, or a file
//! GStreamer decodes to 16-bit grey. Each frame goes with its capture time to a
//! [`ThermalSlot`], where the newest wins, as the fisheye's frames go to their `FrameSlot`.
//! The demo's thermal camera draws its frames itself (`scene::thermal`).

use super::gst_source::{
    GstSource, Tail, captured_us, check_with, open_with, readable, sample_error,
};
use super::{SourceError, SourceSpec, SpecError};
use crate::geometry::Euler;
use crate::supervise::Locked;
use crate::thermal::{Calibration, ThermalError, ThermalFrame};
use crate::units::Angle;
use gstreamer as gst;
use gstreamer_video as gst_video;
use gstreamer_video::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// `[thermal]` in the serve configuration: the thermal sensor beside the fisheye
/// (docs/thermal.md).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ThermalConfig {
    /// `off`, `demo`, `v4l2:DEVICE`, `gst:DESCRIPTION`, `file:PATH`, `image:PATH` or
    /// `sequence:PATTERN` (`serve --thermal`).
    pub source: String,
    /// Frame rate of the demo, images and sequences (a Lepton gives 9, a Boson 30 or 60).
    pub fps: u32,
    /// Its lens, by name in lens.cal.
    pub lens: String,
    /// Where it looks relative to the fisheye: zero looks where the fisheye looks; yaw, pitch
    /// and roll turn it about the fisheye's mount axes (radians, or `"2deg"`).
    pub mount: ThermalMount,
    /// kelvin = counts × `kelvin_per_count` + `kelvin_offset` (TLinear: 0.01 and 0).
    pub kelvin_per_count: f64,
    pub kelvin_offset: f64,
}

/// The thermal camera's mount relative to the fisheye's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ThermalMount {
    pub yaw: Angle,
    pub pitch: Angle,
    pub roll: Angle,
}

impl Default for ThermalConfig {
    fn default() -> Self {
        ThermalConfig {
            source: "off".into(),
            fps: 9,
            lens: "BOSON320".into(),
            mount: ThermalMount::default(),
            kelvin_per_count: 0.01,
            kelvin_offset: 0.0,
        }
    }
}

/// A thermal sensor as `[thermal]` describes it, checked (its lens is found when the head
/// starts, in the lens.cal it reads).
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalSetup {
    pub spec: SourceSpec,
    pub fps: u32,
    pub lens: String,
    pub mount: Euler,
    pub cal: Calibration,
}

/// Why `[thermal]` is refused.
#[derive(Debug, thiserror::Error)]
pub enum ThermalConfigError {
    #[error("thermal source: {0}")]
    Source(#[from] SpecError),
    #[error(transparent)]
    Calibration(#[from] ThermalError),
}

impl ThermalConfig {
    /// The sensor, its source and calibration checked (its numbers' ranges are the serve
    /// configuration's rules, `app::config_rules`); None when `source` is `off`.
    pub fn setup(&self) -> Result<Option<ThermalSetup>, ThermalConfigError> {
        let cal = Calibration::new(self.kelvin_per_count, self.kelvin_offset)?;
        let m = &self.mount;
        if self.source.eq_ignore_ascii_case("off") {
            return Ok(None);
        }
        Ok(Some(ThermalSetup {
            spec: self.source.parse()?,
            fps: self.fps,
            lens: self.lens.clone(),
            mount: Euler::new(m.yaw.0, m.pitch.0, m.roll.0),
            cal,
        }))
    }
}

/// A thermal frame and when it was captured ([`crate::clock::clock_us`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Stamped {
    pub frame: Arc<ThermalFrame>,
    pub captured_us: u64,
}

/// The newest thermal frame; readers share it without copying.
#[derive(Default)]
pub struct ThermalSlot {
    newest: Mutex<Option<Arc<Stamped>>>,
    received: AtomicU64,
}

impl ThermalSlot {
    pub fn put(&self, frame: ThermalFrame, captured_us: u64) {
        let stamped = Arc::new(Stamped {
            frame: Arc::new(frame),
            captured_us,
        });
        *self.newest.locked() = Some(stamped);
        self.received.fetch_add(1, Ordering::Relaxed);
    }

    /// The newest frame, if one came.
    pub fn newest(&self) -> Option<Arc<Stamped>> {
        self.newest.locked().clone()
    }

    /// Frames put in so far.
    pub fn received(&self) -> u64 {
        self.received.load(Ordering::Relaxed)
    }
}

/// Whether a thermal `spec` can ever open (as [`super::check`]; the demo always can).
pub fn check(spec: &SourceSpec, fps: u32) -> Result<(), SourceError> {
    check_with(spec, fps, Tail::Thermal)
}

/// Builds and starts the pipeline for a thermal `spec` (any kind but the demo); frames go to
/// `slot`. `fps` paces images and sequences, which are looped.
pub fn open(spec: &SourceSpec, fps: u32, slot: Arc<ThermalSlot>) -> Result<GstSource, SourceError> {
    open_with(
        spec,
        (fps, true),
        Tail::Thermal,
        move |sample, pipeline| match to_thermal(sample) {
            Ok(frame) => {
                let at = sample
                    .buffer()
                    .map(|b| captured_us(b, pipeline))
                    .unwrap_or_else(crate::clock::clock_us);
                slot.put(frame, at)
            }
            Err(e) => tracing::warn!("thermal source: dropped a frame: {e}"),
        },
    )
}

/// The counts of a GRAY16_LE sample, rows packed.
fn to_thermal(sample: &gst::Sample) -> Result<ThermalFrame, SourceError> {
    let video = readable(sample)?;
    if video.format() != gst_video::VideoFormat::Gray16Le {
        let f = video.format();
        return Err(sample_error(format_args!("in {f:?}, not 16-bit grey")));
    }
    let (w, h) = (video.width(), video.height());
    let src = video.plane_data(0).map_err(sample_error)?;
    let stride = video.plane_stride()[0] as usize;
    let mut bytes = Vec::with_capacity(w as usize * h as usize * 2);
    for y in 0..h as usize {
        bytes.extend_from_slice(&src[y * stride..y * stride + w as usize * 2]);
    }
    ThermalFrame::from_le_bytes(w, h, &bytes).map_err(|e| SourceError::Sample(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    fn first(spec: &str) -> Arc<Stamped> {
        let slot = Arc::new(ThermalSlot::default());
        let spec: SourceSpec = spec.parse().unwrap();
        let _source = open(&spec, 9, slot.clone()).unwrap();
        let end = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(f) = slot.newest() {
                return f;
            }
            assert!(Instant::now() < end, "no thermal frame from {spec} in 20 s");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn setup_of(text: &str) -> Result<Option<ThermalSetup>, String> {
        let cfg: ThermalConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        cfg.setup().map_err(|e| e.to_string())
    }

    #[test]
    fn the_thermal_section_is_read_with_its_angles_and_refused_in_words() {
        assert_eq!(setup_of(""), Ok(None), "off by default");
        let setup = setup_of("source = \"demo\"\nmount = { yaw = \"2deg\", pitch = -0.1 }")
            .unwrap()
            .unwrap();
        assert_eq!(setup.spec, SourceSpec::Demo);
        assert!((setup.mount.yaw - 2f64.to_radians()).abs() < 1e-12);
        assert_eq!((setup.mount.pitch, setup.mount.roll), (-0.1, 0.0));
        assert_eq!(setup.lens, "BOSON320");
        for (text, words) in [
            ("mount = { yaw = \"nan\" }", "`nan` is not a finite angle"),
            (
                "kelvin_per_count = 0",
                "kelvin_per_count must be a number from 0.0001 to 1 K",
            ),
            (
                "kelvin_offset = 5000",
                "kelvin_offset must be a number from -1000 to 1000 K",
            ),
            ("lens = \"X\"\nsource = \"nowhere:x\"", "thermal source: "),
            ("palette = \"ironbow\"", "unknown field `palette`"),
        ] {
            let full = match text.contains("source") {
                true => text.to_string(),
                false => format!("source = \"demo\"\n{text}"),
            };
            let e = setup_of(&full).unwrap_err();
            assert!(e.contains(words), "{text}: {e}");
        }
    }

    #[test]
    fn a_16_bit_png_comes_through_count_for_count() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("thermal.png");
        let (w, h) = (64u32, 48u32);
        let counts: Vec<u16> = (0..w * h).map(|i| 28_000 + (i * 7 % 4000) as u16).collect();
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, counts.clone());
        img.unwrap().save(&path).unwrap();
        let got = first(&format!("image:{}", path.display()));
        assert_eq!((got.frame.width, got.frame.height), (w, h));
        assert_eq!(got.frame.counts, counts);
    }

    #[test]
    fn a_gstreamer_pipeline_in_gray16_le_gives_frames_of_its_size() {
        let got = first(
            "gst:videotestsrc pattern=gradient is-live=true \
             ! video/x-raw,format=GRAY16_LE,width=160,height=120,framerate=9/1",
        );
        assert_eq!((got.frame.width, got.frame.height), (160, 120));
        // A vertical gradient: darker at the top than at the bottom, in 16 bits.
        let (top, bottom) = (got.frame.at(80, 2), got.frame.at(80, 117));
        assert!(bottom > top + 10_000, "{top} {bottom}");
    }
}
