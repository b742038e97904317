//! The ONNX detector: a detection model (NanoDet-m by default, or the user's YOLOv8 export)
//! run by ONNX Runtime on square RGB pictures, the scan views the renderer draws at the
//! model's input size. ONNX Runtime is loaded at run time, not linked: from the configured
//! path, `ORT_DYLIB_PATH`, or where `scripts/setup.sh` unpacks it; on a Jetson the same code
//! loads a CUDA or TensorRT build.

pub mod decode;

pub use decode::{COCO, Decoder, PixelBox};

use super::Detection;
#[cfg(doc)]
use super::scan::model_views;
use super::scan::{ScanView, owner, to_world};
use crate::plan::{FramePlan, PlannedView};
use decode::Level;
use glam::DVec2;
use image::imageops::FilterType;
use ort::session::Session;
use ort::value::TensorRef;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[derive(Clone, Debug, thiserror::Error)]
pub enum OnnxError {
    #[error(
        "ONNX Runtime was not found (looked at {looked}): run scripts/setup.sh, which \
         unpacks it from the onnxruntime wheel, or give its libonnxruntime.so with \
         ORT_DYLIB_PATH or [detection] onnxruntime"
    )]
    NoRuntime { looked: String },
    #[error("ONNX Runtime at {path}: {reason}")]
    Runtime { path: String, reason: String },
    #[error("{path}: {reason}")]
    Model { path: String, reason: String },
    #[error("the model did not run: {0}")]
    Run(String),
    #[error("{0}: no such class (give a class name the model knows, or its number)")]
    Class(String),
}

/// How to set up the detector (`[detection]` in the config, or `digiview detect`'s flags).
#[derive(Clone, Debug, PartialEq)]
pub struct OnnxConfig {
    pub model: PathBuf,
    pub decoder: Decoder,
    /// The classes that count (names or numbers); empty, all.
    pub classes: Vec<String>,
    /// ONNX Runtime's library, if not found the usual ways.
    pub runtime: Option<PathBuf>,
    /// Threads ONNX Runtime uses for one picture.
    pub threads: usize,
}

/// The largest model input the scan views are drawn for (each view is this tall, 1.5 times
/// as wide).
const MAX_SIDE: u32 = 1280;

/// A box this close to its view's edge (model pixels) is taken as cut by it.
const EDGE: f64 = 2.0;

/// The model shipped with DigiView, relative to the working directory or the executable's.
pub const DEFAULT_MODEL: &str = "assets/models/nanodet-m.onnx";

/// Where a relative model path is: in the working directory, else beside the executable or
/// up to three directories above it (a build in `target/release` finds the source's
/// `assets`), else under /usr/share/digiview; if none has it, the path as given (and loading
/// says it is missing).
pub fn locate_model(path: &Path) -> PathBuf {
    if path.is_absolute() || path.exists() {
        return path.to_path_buf();
    }
    let exe = std::env::current_exe().ok();
    let beside = exe
        .iter()
        .flat_map(|e| e.ancestors().skip(1).take(4))
        .map(|dir| dir.join(path));
    let shared = std::iter::once(Path::new("/usr/share/digiview").join(path));
    beside
        .chain(shared)
        .find(|p| p.is_file())
        .unwrap_or_else(|| path.to_path_buf())
}

/// Where `scripts/setup.sh` unpacks ONNX Runtime.
pub fn cache_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache")))?;
    Some(base.join("digiview").join("onnxruntime"))
}

/// The ONNX Runtime library to load: the configured one, `ORT_DYLIB_PATH`, or the newest
/// `libonnxruntime.so*` in the cache directory.
fn runtime_library(configured: Option<&Path>) -> Result<PathBuf, OnnxError> {
    if let Some(p) = configured {
        return Ok(p.to_path_buf());
    }
    if let Some(p) = std::env::var_os("ORT_DYLIB_PATH") {
        return Ok(PathBuf::from(p));
    }
    let dir = cache_dir();
    let found = dir.as_ref().and_then(|d| {
        let mut libs: Vec<PathBuf> = std::fs::read_dir(d)
            .ok()?
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("libonnxruntime.so"))
            })
            .collect();
        libs.sort();
        libs.pop()
    });
    found.ok_or_else(|| OnnxError::NoRuntime {
        looked: match dir {
            Some(d) => format!("ORT_DYLIB_PATH, {}", d.display()),
            None => "ORT_DYLIB_PATH".into(),
        },
    })
}

/// ONNX Runtime's environment: one per process, made on first use (and its failure kept).
fn environment(
    configured: Option<&Path>,
) -> Result<&'static ort::environment::Environment, OnnxError> {
    static ENV: OnceLock<Result<ort::environment::Environment, OnnxError>> = OnceLock::new();
    ENV.get_or_init(|| {
        let path = runtime_library(configured)?;
        let failed = |reason: String| OnnxError::Runtime {
            path: path.display().to_string(),
            reason,
        };
        if !path.is_file() {
            return Err(failed("no such file".into()));
        }
        ort::init_from(&path)
            .map_err(|e| failed(e.to_string()))?
            .with_name("digiview")
            .build()
            .map_err(|e| failed(e.to_string()))
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// A loaded model and how to read it.
pub struct OnnxDetector {
    session: Session,
    input: String,
    side: u32,
    decoder: Decoder,
    /// Per class, whether it counts; empty, all do.
    wanted: Vec<bool>,
    /// The model's input, reused between pictures.
    tensor: Vec<f32>,
}

impl OnnxDetector {
    pub fn load(cfg: &OnnxConfig) -> Result<OnnxDetector, OnnxError> {
        let env = environment(cfg.runtime.as_deref())?;
        let model_error = |reason: String| OnnxError::Model {
            path: cfg.model.display().to_string(),
            reason,
        };
        if !cfg.model.is_file() {
            return Err(model_error("no such model file".into()));
        }
        let session = Session::builder(env)
            .and_then(|b| Ok(b.with_intra_threads(cfg.threads.max(1))?))
            .and_then(|mut b| b.commit_from_file(&cfg.model))
            .map_err(|e| model_error(e.to_string()))?;
        let Some(input) = session.inputs().first() else {
            return Err(model_error("the model has no input".into()));
        };
        // [1, 3, side, side]; a model with a free size gets YOLOv8's usual 640.
        let shape: Vec<i64> = input
            .dtype()
            .tensor_shape()
            .map(|s| s.iter().copied().collect())
            .unwrap_or_default();
        let side = match shape.as_slice() {
            [_, 3, h, w] if h == w && *h > 0 => *h as u32,
            [_, 3, h, w] if *h <= 0 && *w <= 0 => 640,
            _ => {
                return Err(model_error(format!(
                    "its input {} is {shape:?}, not a square RGB picture [1, 3, N, N]",
                    input.name()
                )));
            }
        };
        if !(32..=MAX_SIDE).contains(&side) {
            return Err(model_error(format!(
                "its input is {side}x{side}; scan views are 32 to {MAX_SIDE} pixels tall"
            )));
        }
        let wanted = wanted(&cfg.classes)?;
        Ok(OnnxDetector {
            input: input.name().to_string(),
            session,
            side,
            decoder: cfg.decoder,
            wanted,
            tensor: vec![],
        })
    }

    /// The side of the square picture the model takes.
    pub fn side(&self) -> u32 {
        self.side
    }

    /// Runs the model on one `side` × `side` RGB picture (`stride` bytes a row, `channels`
    /// bytes a pixel, RGB first) and gives its boxes at `threshold` or more, before any
    /// suppression.
    pub fn detect(
        &mut self,
        picture: &[u8],
        stride: usize,
        channels: usize,
        threshold: f32,
    ) -> Result<Vec<PixelBox>, OnnxError> {
        let side = self.side as usize;
        if channels < 3 || picture.len() < (side - 1) * stride + side * channels {
            return Err(OnnxError::Run(format!("the picture is not {side}x{side}")));
        }
        // RGB / 255, planar (NCHW).
        self.tensor.resize(3 * side * side, 0.0);
        for y in 0..side {
            let row = &picture[y * stride..y * stride + side * channels];
            for (x, px) in row.chunks_exact(channels).enumerate() {
                for (c, &v) in px[..3].iter().enumerate() {
                    self.tensor[c * side * side + y * side + x] = v as f32 / 255.0;
                }
            }
        }
        let input = TensorRef::from_array_view(([1usize, 3, side, side], self.tensor.as_slice()))
            .map_err(|e| OnnxError::Run(e.to_string()))?;
        let outputs = self
            .session
            .run(ort::inputs![self.input.as_str() => input])
            .map_err(|e| OnnxError::Run(e.to_string()))?;
        let mut tensors = vec![];
        for i in 0..outputs.len() {
            let (shape, data) = outputs[i]
                .try_extract_tensor::<f32>()
                .map_err(|e| OnnxError::Run(e.to_string()))?;
            tensors.push((shape.iter().copied().collect::<Vec<i64>>(), data));
        }
        let wanted = |c: usize| self.wanted.is_empty() || self.wanted.get(c) == Some(&true);
        match self.decoder {
            Decoder::Nanodet => nanodet(&tensors, self.side, threshold, wanted),
            Decoder::Yolov8 => yolov8(&tensors, threshold, wanted),
        }
    }
}

/// A model's outputs: each tensor's shape and data.
type Outputs<'a> = [(Vec<i64>, &'a [f32])];

/// NanoDet's boxes from its outputs: levels are told apart by their cell counts; of a
/// level's two outputs the distances are 4 × bins wide, and where both are (80 classes, 44
/// distances), the narrower.
fn nanodet(
    tensors: &Outputs,
    side: u32,
    threshold: f32,
    wanted: impl Fn(usize) -> bool,
) -> Result<Vec<PixelBox>, OnnxError> {
    let not_nanodet = |what: &str| {
        OnnxError::Run(format!(
            "its outputs are not NanoDet's (class scores and box distances per {what}); is \
             the decoder right?"
        ))
    };
    let cells = |stride: u32| (side.div_ceil(stride) as i64).pow(2);
    let widths: Vec<i64> = tensors
        .iter()
        .filter(|(s, _)| s.len() == 3)
        .map(|(s, _)| s[2])
        .collect();
    let spread = widths.iter().filter(|&&w| w % 4 == 0).min().copied();
    let classes = widths.iter().copied().find(|&w| Some(w) != spread);
    let (Some(spread), Some(classes)) = (spread, classes) else {
        return Err(not_nanodet("stride"));
    };
    let levels: Vec<Level> = [8, 16, 32, 64]
        .into_iter()
        .filter_map(|stride| {
            let of = |scores: bool| {
                tensors.iter().find(|(s, _)| {
                    s.len() == 3
                        && s[1] == cells(stride)
                        && s[2] == if scores { classes } else { spread }
                })
            };
            Some(Level {
                stride,
                scores: of(true)?.1,
                distances: of(false)?.1,
            })
        })
        .collect();
    if levels.is_empty() {
        return Err(not_nanodet("stride 8, 16, 32"));
    }
    Ok(decode::nanodet(
        &levels,
        side,
        classes as usize,
        threshold,
        wanted,
    ))
}

/// YOLOv8's boxes from its one output, [1, 4 + classes, anchors]: fewer rows than anchors
/// (84 × 8400 for COCO).
fn yolov8(
    tensors: &Outputs,
    threshold: f32,
    wanted: impl Fn(usize) -> bool,
) -> Result<Vec<PixelBox>, OnnxError> {
    let Some((shape, data)) = tensors.first() else {
        return Err(OnnxError::Run("the model gave no output".into()));
    };
    let anchors = match shape.as_slice() {
        [1, rows, anchors] if *rows > 4 && rows < anchors => *anchors as usize,
        _ => {
            return Err(OnnxError::Run(format!(
                "its output is {shape:?}, not YOLOv8's [1, 4 + classes, anchors]; is the \
                 decoder right?"
            )));
        }
    };
    Ok(decode::yolov8(data, anchors, threshold, wanted))
}

impl OnnxDetector {
    /// Runs the model on each scan view of an RGBA mosaic (`stride` bytes a row; views of
    /// [`model_views`], each resized plainly to the model's square) and gives their boxes as
    /// directions in the world. Views overlap: a box cut by its view's edge counts only if no
    /// other view shows the object clear of its edges (the tracker's suppression merges the
    /// whole ones).
    pub fn scan(
        &mut self,
        views: &[ScanView],
        plan: &FramePlan,
        rgba: &[u8],
        stride: usize,
        threshold: f32,
    ) -> Result<Vec<Detection>, OnnxError> {
        let mut found = vec![];
        for (view, planned) in views.iter().zip(&plan.views) {
            for (d, whole) in self.view(view, planned, rgba, stride, threshold)? {
                if whole
                    || owner(views, plan, d.bbox.centre, d.bbox.size(), EDGE) == Some(view.index)
                {
                    found.push(d);
                }
            }
        }
        Ok(found)
    }

    /// Runs the model on one view of an RGBA mosaic (a crop around a tracked object, for the
    /// track step): its boxes as directions in the world, those cut by its edge included.
    pub fn crop(
        &mut self,
        view: &ScanView,
        planned: &PlannedView,
        rgba: &[u8],
        stride: usize,
        threshold: f32,
    ) -> Result<Vec<Detection>, OnnxError> {
        let found = self.view(view, planned, rgba, stride, threshold)?;
        Ok(found.into_iter().map(|(d, _)| d).collect())
    }

    /// The boxes the model finds in one view of a mosaic, each with whether it is clear of
    /// the view's edges.
    fn view(
        &mut self,
        view: &ScanView,
        planned: &PlannedView,
        rgba: &[u8],
        stride: usize,
        threshold: f32,
    ) -> Result<Vec<(Detection, bool)>, OnnxError> {
        let r = planned.rect;
        let rows = rgba
            .get(r.y as usize * stride..(r.y + r.h) as usize * stride)
            .ok_or_else(|| OnnxError::Run("a scan view lies outside its mosaic".into()))?;
        let picture: image::RgbaImage = image::ImageBuffer::from_fn(r.w, r.h, |x, y| {
            let i = y as usize * stride + (r.x + x) as usize * 4;
            image::Rgba([rows[i], rows[i + 1], rows[i + 2], 255])
        });
        let side = self.side;
        let input = image::imageops::resize(&picture, side, side, FilterType::Triangle);
        let back = DVec2::new(r.w as f64, r.h as f64) / side as f64;
        let mut found = vec![];
        for b in self.detect(input.as_raw(), side as usize * 4, 4, threshold)? {
            let Some(bbox) = to_world(view, planned, b.low * back, b.high * back) else {
                continue;
            };
            let whole = b.low.min_element() > EDGE
                && b.high.x < side as f64 - EDGE
                && b.high.y < side as f64 - EDGE;
            let d = Detection {
                bbox,
                confidence: b.confidence as f64,
                class: b.class,
                velocity: None,
            };
            found.push((d, whole));
        }
        Ok(found)
    }
}

/// The name of class `class`.
pub fn class_name(class: u16) -> String {
    COCO.get(class as usize)
        .map_or_else(|| format!("class {class}"), |s| s.to_string())
}

/// Which classes count, from COCO names or numbers.
pub fn wanted(classes: &[String]) -> Result<Vec<bool>, OnnxError> {
    let mut wanted = vec![];
    for c in classes {
        let index = match c.trim().parse::<usize>() {
            Ok(n) if n < 1000 => n,
            _ => COCO
                .iter()
                .position(|l| l.eq_ignore_ascii_case(c.trim()))
                .ok_or_else(|| OnnxError::Class(c.clone()))?,
        };
        if wanted.len() <= index {
            wanted.resize(index + 1, false);
        }
        wanted[index] = true;
    }
    Ok(wanted)
}
