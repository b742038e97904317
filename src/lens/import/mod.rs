//! `digiview lens import`: turns a calibration a user already has into a lens.cal entry.
//! One file per source format; each returns the same plain description, which becomes a
//! [`LensEntry`] here. Formats: OpenCV fisheye (FileStorage YAML or XML), OCamCalib
//! `calib_results.txt`, Gyroflow lens-profile JSON, Kalibr camchain YAML.

mod gyroflow;
mod kalibr;
mod ocamcalib;
mod opencv;

use super::models::KannalaBrandt;
use super::{LensEntry, LensError, Model, PixelAffine, Provenance, Radial};
use std::path::Path;

/// Why a calibration file could not be read as its format: what is missing or malformed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Unreadable(pub String);

impl From<String> for Unreadable {
    fn from(message: String) -> Self {
        Unreadable(message)
    }
}

impl From<&str> for Unreadable {
    fn from(message: &str) -> Self {
        Unreadable(message.to_string())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    Opencv,
    Ocam,
    Gyroflow,
    Kalibr,
}

/// What every importer extracts.
pub struct Imported {
    pub model: Model,
    pub affine: PixelAffine,
    pub width: u32,
    pub height: u32,
    pub by: String,
    pub date: String,
    pub source: String,
    pub rms_px: Option<f64>,
}

/// Options the file cannot supply.
pub struct ImportOptions<'a> {
    pub name: &'a str,
    pub lens_id: u8,
    /// The valid field of view; by default the widest the frame shows, within the model's range.
    pub fov: Option<f64>,
    /// Which camera of a multi-camera file (Kalibr), by default the first.
    pub camera: Option<&'a str>,
}

/// Guesses the format from the file name and contents.
pub fn detect(path: &Path, text: &str) -> Option<Format> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "json" => Some(Format::Gyroflow),
        "xml" => Some(Format::Opencv),
        "yaml" | "yml" if text.contains("camera_model") => Some(Format::Kalibr),
        "yaml" | "yml" => Some(Format::Opencv),
        "txt" if text.contains("invpol") || text.contains("DIRECT mapping") => Some(Format::Ocam),
        _ => detect_content(text),
    }
}

/// The format from the content alone, for a file whose name says nothing.
fn detect_content(text: &str) -> Option<Format> {
    let t = text.trim_start();
    if t.starts_with('{') {
        Some(Format::Gyroflow)
    } else if t.starts_with("<?xml") || t.starts_with("<opencv_storage") || t.starts_with("%YAML") {
        Some(Format::Opencv)
    } else if text.contains("camera_model") && text.contains("intrinsics") {
        Some(Format::Kalibr)
    } else if text.contains("invpol") || text.contains("DIRECT mapping") {
        Some(Format::Ocam)
    } else {
        None
    }
}

pub fn import(
    path: &Path,
    format: Option<Format>,
    opts: &ImportOptions,
) -> Result<LensEntry, LensError> {
    let err = |message: String| LensError::Import {
        path: path.into(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|source| LensError::Io {
        path: path.into(),
        source,
    })?;
    let format = format.or_else(|| detect(path, &text)).ok_or_else(|| {
        err("cannot tell the calibration format from the name; give --format".into())
    })?;
    let got = match format {
        Format::Opencv => opencv::parse(path, &text),
        Format::Ocam => ocamcalib::parse(&text),
        Format::Gyroflow => gyroflow::parse(&text),
        Format::Kalibr => kalibr::parse(&text, opts.camera),
    }
    .map_err(|e| err(e.0))?;
    if got.width == 0 || got.height == 0 {
        return Err(err("the calibration's image size is zero".into()));
    }
    let radial = Radial::new(got.model.clone());
    let fov = match opts.fov {
        Some(f) => f,
        None => 2.0 * widest_angle(&radial, &got.affine, got.width, got.height),
    };
    let entry = LensEntry {
        name: opts.name.to_string(),
        lens_id: opts.lens_id,
        model: got.model,
        affine: got.affine,
        width: got.width,
        height: got.height,
        fov,
        circle_radius: None,
        provenance: Provenance {
            kind: "calibrated".into(),
            by: got.by,
            date: got.date,
            source: format!(
                "imported from {} ({})",
                path.file_name().and_then(|n| n.to_str()).unwrap_or("?"),
                got.source
            ),
            assumption: String::new(),
            rms_px: got.rms_px,
        },
        line: 0,
        pair: None,
    };
    // Round-trip through the text form so the entry is exactly what lens.cal will hold.
    let cal = super::LensCal::parse(Path::new("(imported)"), &entry.to_toml())?;
    Ok(cal.entries.into_iter().next().expect("one entry"))
}

/// The largest angle from the axis that the frame shows (its farthest border point), within
/// the model's one-to-one range and at most 100° (a 200° field of view).
pub(crate) fn widest_angle(radial: &Radial, affine: &PixelAffine, w: u32, h: u32) -> f64 {
    let (w, h) = (w as f64 - 1.0, h as f64 - 1.0);
    let border = (0..=64).flat_map(|i| {
        let t = i as f64 / 64.0;
        [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)]
    });
    let mut widest: f64 = 0.0;
    for (x, y) in border {
        let r = affine.to_normalized(glam::DVec2::new(x, y)).length();
        widest = widest.max(
            radial
                .theta_of_r(r.min(radial.limits.r_max))
                .unwrap_or(radial.limits.theta_max),
        );
    }
    widest.min(radial.limits.theta_max).min(100f64.to_radians())
}

/// A list of numbers from whitespace- or comma-separated text.
fn numbers(text: &str) -> Result<Vec<f64>, Unreadable> {
    text.split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| Unreadable(format!("`{s}` is not a number")))
        })
        .collect()
}

fn kb4(k: &[f64], what: &str) -> Result<Model, Unreadable> {
    let k: [f64; 4] = k.try_into().map_err(|_| {
        format!(
            "{what} has {} coefficients; a fisheye (Kannala-Brandt) calibration has 4",
            k.len()
        )
    })?;
    Ok(Model::KannalaBrandt(KannalaBrandt { k }))
}

#[cfg(test)]
mod tests;
