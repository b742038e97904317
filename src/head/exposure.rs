//! The head's exposure stage: who sets the camera's exposure for this source (the demo's
//! simulated sensor, a V4L2 camera's controls, or nobody: files and images are answered
//! CAM_SENSOR SET with DATA_ERROR), DigiView's auto exposure fed with the frame loop's new
//! frames, and for a V4L2 camera a thread that keeps its controls as the live state says.

use super::Head;
use crate::clock::clock_us;
use crate::exposure::auto::AutoExposure;
use crate::exposure::v4l2::{Device, Mapping};
use crate::exposure::{AutoExposureMode, Limits, Setting, UNITY_GAIN, circle_luma};
use crate::frame::Frame;
use crate::source::SourceSpec;
use crate::state::{Invalid, MAX_GAIN, State};
use crate::supervise::Locked;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

/// Who sets the exposure.
enum Control {
    /// The demo camera reads the live state for each frame; it has no auto exposure of its
    /// own.
    Demo,
    /// A V4L2 camera's controls; `software`: DigiView runs the auto exposure even where the
    /// camera has its own.
    V4l2 { path: PathBuf, software: bool },
    /// The source has no exposure to set; why.
    Nobody(String),
}

pub(super) struct ExposureStage {
    control: Control,
    ae: Mutex<AutoExposure>,
    /// The V4L2 camera's controls, while its node is open.
    mapping: Mutex<Option<Mapping>>,
    /// The last luma measured in the image circle (f64 bits; NaN before any).
    pub luma: std::sync::atomic::AtomicU64,
}

/// Frames a V4L2 camera takes to show a new setting.
const V4L2_LAG_FRAMES: u64 = 3;

impl ExposureStage {
    pub(super) fn new(spec: &SourceSpec, mode: AutoExposureMode) -> ExposureStage {
        let control = match spec {
            SourceSpec::Demo => Control::Demo,
            SourceSpec::V4l2(path) => Control::V4l2 {
                path: path.clone(),
                software: mode == AutoExposureMode::Software,
            },
            other => Control::Nobody(format!(
                "the source {other} is not a camera DigiView sets exposure on (set it in the \
                 pipeline or the file instead)"
            )),
        };
        ExposureStage {
            control,
            ae: Mutex::default(),
            mapping: Mutex::default(),
            luma: f64::NAN.to_bits().into(),
        }
    }

    fn mapping(&self) -> Option<Mapping> {
        self.mapping.locked().clone()
    }

    /// Whether DigiView runs the auto exposure (rather than the camera, or nobody).
    fn software(&self) -> bool {
        match &self.control {
            Control::Demo => true,
            Control::V4l2 { software, .. } => {
                *software || self.mapping().is_some_and(|m| !m.has_auto())
            }
            Control::Nobody(_) => false,
        }
    }

    /// What the exposure and gain can be set to now.
    fn limits(&self, state: &State) -> Limits {
        let longest = state.settings.sensor.longest_exposure_us();
        match self.mapping() {
            Some(m) => m.limits(longest),
            None => Limits {
                exposure_us: (1, longest),
                gain: (UNITY_GAIN, MAX_GAIN),
            },
        }
    }

    fn settle_us(&self, state: &State) -> u64 {
        match self.control {
            Control::V4l2 { .. } => {
                V4L2_LAG_FRAMES * 1_000_000 / state.settings.sensor.fps.max(1) as u64
            }
            _ => 0,
        }
    }
}

impl Head {
    /// Says, for a source with no exposure to set, why CAM_SENSOR SET is refused; starts the
    /// thread that keeps a V4L2 camera's controls.
    pub(super) fn start_exposure(
        self: &std::sync::Arc<Head>,
    ) -> Option<std::thread::JoinHandle<()>> {
        match &self.exposure.control {
            Control::Nobody(why) => {
                self.report.set_sensor_refusal(Some(why.clone()));
                None
            }
            Control::Demo => None,
            Control::V4l2 { path, .. } => {
                let (head, path) = (self.clone(), path.clone());
                std::thread::Builder::new()
                    .name("exposure".into())
                    .spawn(move || head.v4l2_controls(path))
                    .map_err(|e| error!("starting the exposure thread: {e}"))
                    .ok()
            }
        }
    }

    /// The frame loop's new frame: measured in the image circle, and with DigiView's auto
    /// exposure on, the next exposure and gain written to the settings.
    pub(super) fn observe_exposure(&self, frame: &Frame, state: &State) {
        let stage = &self.exposure;
        let s = &state.settings.sensor;
        if matches!(stage.control, Control::Nobody(_)) {
            return;
        }
        let size = (frame.layout.width, frame.layout.height);
        let Ok(lens) = self
            .gate
            .settings()
            .lenses()
            .for_frame(state.settings.lens, size, s.roi())
        else {
            return;
        };
        // A little inside the circle: its rim is soft.
        let Some(luma) = circle_luma(frame, lens.centre(), 0.97 * lens.circle_radius()) else {
            return;
        };
        stage.luma.store(luma.to_bits(), Ordering::Relaxed);
        let mut ae = stage.ae.locked();
        if !s.ae || !stage.software() {
            ae.reset();
            return;
        }
        let current = Setting {
            exposure_us: s.exposure_us,
            gain: s.gain,
        };
        let limits = stage.limits(state);
        let settle = stage.settle_us(state);
        let next = ae.observe(
            frame.captured_us,
            luma,
            s.target_brightness,
            current,
            &limits,
            clock_us(),
            settle,
        );
        if let Some(next) = next {
            // Only while auto exposure is still on: a SET may have turned it off meanwhile.
            let _ = self.gate.change(|s| {
                if s.sensor.ae {
                    (s.sensor.exposure_us, s.sensor.gain) = (next.exposure_us, next.gain);
                }
                Ok::<_, Invalid>(())
            });
        }
    }

    /// Keeps a V4L2 camera's controls as the live state says, opening its node again when it
    /// goes (a camera unplugged); with the camera's own auto exposure, reads its exposure and
    /// gain back into the state each second for GET.
    fn v4l2_controls(&self, path: PathBuf) {
        let software = matches!(self.exposure.control, Control::V4l2 { software: true, .. });
        let mut told = false;
        while !self.stop.load(Ordering::Relaxed) {
            let device = match Device::open(&path) {
                Ok(d) => d,
                Err(e) => {
                    if !std::mem::replace(&mut told, true) {
                        warn!("{e}; CAM_SENSOR is kept and set once it opens");
                    }
                    self.pause(Duration::from_secs(2));
                    continue;
                }
            };
            told = false;
            let controls = device.controls();
            let mapping = Mapping::new(&controls);
            info!(
                "camera {}: exposure {}, gain {}, auto exposure {}",
                path.display(),
                if mapping.exposure.is_some() {
                    "set"
                } else {
                    "not settable"
                },
                if mapping.gain.is_some() {
                    "set"
                } else {
                    "not settable"
                },
                if mapping.has_auto() && !software {
                    "the camera's"
                } else {
                    "DigiView's"
                }
            );
            *self.exposure.mapping.locked() = Some(mapping.clone());
            self.keep_controls(&device, &controls, &mapping, software);
            *self.exposure.mapping.locked() = None;
        }
    }

    /// Sets the controls whenever the state changes them, until the device fails or the head
    /// stops.
    fn keep_controls(
        &self,
        device: &Device,
        controls: &[crate::exposure::v4l2::Control],
        mapping: &Mapping,
        software: bool,
    ) {
        // What was set last: the camera's own auto exposure, or a manual setting.
        let mut applied: Option<Option<Setting>> = None;
        let mut read_back = Instant::now();
        while !self.stop.load(Ordering::Relaxed) {
            let s = self.settings().sensor.clone();
            let camera_ae = s.ae && !software && mapping.has_auto();
            let want = (!camera_ae).then_some(Setting {
                exposure_us: s.exposure_us,
                gain: s.gain,
            });
            if applied != Some(want) {
                let values = match want {
                    None => mapping.camera_auto(),
                    Some(setting) => mapping.manual(setting),
                };
                for (id, value) in values {
                    if let Err(e) = device.set(controls, id, value) {
                        error!("{e}");
                        if e.gone() {
                            return;
                        }
                    }
                }
                applied = Some(want);
            }
            if camera_ae && read_back.elapsed() >= Duration::from_secs(1) {
                read_back = Instant::now();
                let value = |c: &Option<crate::exposure::v4l2::Control>| {
                    c.as_ref().and_then(|c| device.get(c.id).ok())
                };
                if let Some(now) = mapping.setting(value(&mapping.exposure), value(&mapping.gain)) {
                    let _ = self.gate.change(|s| {
                        if s.sensor.ae {
                            s.sensor.exposure_us =
                                now.exposure_us.min(s.sensor.longest_exposure_us());
                            s.sensor.gain = now.gain.clamp(1, MAX_GAIN);
                        }
                        Ok::<_, Invalid>(())
                    });
                }
            }
            self.pause(Duration::from_millis(50));
        }
    }

    /// The health line's part: the exposure, gain and the image circle's luma.
    pub(super) fn exposure_summary(&self) -> String {
        let luma = f64::from_bits(self.exposure.luma.load(Ordering::Relaxed));
        if luma.is_nan() {
            return String::new();
        }
        let s = &self.settings().sensor;
        format!(
            ", exposure {:.1} ms gain {:.2}{}, luma {luma:.0}",
            s.exposure_us as f64 / 1000.0,
            s.gain as f64 / UNITY_GAIN as f64,
            if s.ae && self.exposure.software() {
                " (auto)"
            } else {
                ""
            },
        )
    }
}
