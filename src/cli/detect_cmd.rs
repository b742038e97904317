//! `digiview detect`: runs the ONNX detector on one photograph, as the model sees any picture
//! (resized plainly to its input), and prints what it finds. Beside the video path: for
//! trying a model, its classes and a threshold before serving with it.

use crate::detect::onnx::{DEFAULT_MODEL, Decoder, OnnxConfig, OnnxDetector, PixelBox, class_name};
use anyhow::{Context, Result};
use clap::Args;
use glam::DVec2;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct DetectArgs {
    /// The photograph (PNG, JPEG).
    #[arg(long)]
    image: PathBuf,
    /// The model (default: the NanoDet-m DigiView ships).
    #[arg(long, default_value = DEFAULT_MODEL)]
    model: PathBuf,
    /// How the model's outputs are laid out.
    #[arg(long, value_enum, default_value = "nanodet")]
    decoder: Decoder,
    /// The classes that count, COCO names or numbers, comma-separated (default: all).
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// The least confidence kept (DETECTION's var_confidence_threshold, 0.3 by default).
    #[arg(long, default_value_t = 0.3)]
    threshold: f32,
    /// Boxes overlapping a better one by more than this are dropped (var_box_overlap).
    #[arg(long, default_value_t = 0.5)]
    overlap: f32,
    /// ONNX Runtime's library (default: ORT_DYLIB_PATH, or where scripts/setup.sh puts it).
    #[arg(long)]
    onnxruntime: Option<PathBuf>,
    /// One JSON object per box instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn detect(args: DetectArgs) -> Result<()> {
    for (name, v) in [("--threshold", args.threshold), ("--overlap", args.overlap)] {
        if !(0.0..1.0).contains(&v) {
            anyhow::bail!("{name} {v} is outside 0..1");
        }
    }
    let photo = image::open(&args.image)
        .with_context(|| format!("reading {}", args.image.display()))?
        .to_rgb8();
    let mut detector = OnnxDetector::load(&OnnxConfig {
        model: crate::detect::onnx::locate_model(&args.model),
        decoder: args.decoder,
        classes: args.classes.clone(),
        runtime: args.onnxruntime.clone(),
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
    })?;
    let side = detector.side();
    let input = image::imageops::resize(&photo, side, side, image::imageops::FilterType::Triangle);
    let found = detector.detect(input.as_raw(), side as usize * 3, 3, args.threshold)?;
    let scale = DVec2::new(photo.width() as f64, photo.height() as f64) / side as f64;
    let boxes: Vec<PixelBox> = suppress(found, args.overlap)
        .into_iter()
        .map(|b| PixelBox {
            low: b.low * scale,
            high: b.high * scale,
            ..b
        })
        .collect();
    for b in &boxes {
        let c = (b.low + b.high) / 2.0;
        if args.json {
            println!(
                "{}",
                serde_json::json!({
                    "class": class_name(b.class), "class_id": b.class,
                    "confidence": b.confidence,
                    "x0": b.low.x, "y0": b.low.y, "x1": b.high.x, "y1": b.high.y,
                })
            );
        } else {
            println!(
                "{:<14} {:.2}  centre {:.0},{:.0}  box {:.0},{:.0} – {:.0},{:.0}",
                class_name(b.class),
                b.confidence,
                c.x,
                c.y,
                b.low.x,
                b.low.y,
                b.high.x,
                b.high.y
            );
        }
    }
    if !args.json {
        eprintln!(
            "{}: {} found at {} or more ({}x{} resized to {side}x{side})",
            args.image.display(),
            boxes.len(),
            args.threshold,
            photo.width(),
            photo.height()
        );
    }
    Ok(())
}

/// Non-maximum suppression in the picture: best first, each box dropped when it overlaps one
/// kept (intersection over union) by more than `max_overlap`.
fn suppress(mut found: Vec<PixelBox>, max_overlap: f32) -> Vec<PixelBox> {
    found.sort_by(|a, b| b.confidence.total_cmp(&a.confidence));
    let area = |b: &PixelBox| (b.high - b.low).max(DVec2::ZERO).element_product();
    let mut kept: Vec<PixelBox> = vec![];
    for b in found {
        let overlaps = kept.iter().any(|k| {
            let inter = (k.high.min(b.high) - k.low.max(b.low))
                .max(DVec2::ZERO)
                .element_product();
            let union = area(k) + area(&b) - inter;
            union > 0.0 && inter / union > max_overlap as f64
        });
        if !overlaps {
            kept.push(b);
        }
    }
    kept
}
