//! OpenCV fisheye calibrations saved with cv::FileStorage, as YAML (`%YAML:1.0`, matrices
//! tagged `!!opencv-matrix`) or XML (`<opencv_storage>`). The camera matrix and the four
//! fisheye coefficients go by several names in the wild; all the common ones are accepted.

use super::{Imported, Unreadable, kb4, numbers};
use crate::lens::PixelAffine;
use std::path::Path;
use yaml_rust2::{Yaml, YamlLoader};

const K_NAMES: [&str; 4] = ["camera_matrix", "K", "cameraMatrix", "intrinsic_matrix"];
const D_NAMES: [&str; 5] = [
    "distortion_coefficients",
    "D",
    "dist_coeffs",
    "distCoeffs",
    "distortion_coeffs",
];

pub fn parse(path: &Path, text: &str) -> Result<Imported, Unreadable> {
    let fields = if text.trim_start().starts_with("<?xml") || text.contains("<opencv_storage>") {
        xml_fields(text)?
    } else {
        yaml_fields(text)?
    };
    // A field found but not numbers (`.nan`, text) is said as such, not as missing.
    let found = |names: &[&str]| {
        names
            .iter()
            .find_map(|n| fields.iter().find(|(k, _)| k == n))
            .map(|(name, v)| match v {
                Ok(v) if v.iter().all(|x| x.is_finite()) => Ok(v.clone()),
                Ok(_) => Err(Unreadable(format!(
                    "{name} holds a value that is not a finite number"
                ))),
                Err(e) => Err(Unreadable(format!("{name}: {}", e.0))),
            })
    };
    let get = |names: &[&str]| found(names).and_then(Result::ok);
    let k = found(&K_NAMES).ok_or("no camera matrix (camera_matrix or K)")??;
    let d =
        found(&D_NAMES).ok_or("no distortion coefficients (distortion_coefficients or D)")??;
    if k.len() != 9 {
        return Err(format!("the camera matrix has {} values, not 9", k.len()).into());
    }
    if k[1].abs() > 1e-9 {
        return Err("the camera matrix has skew; DigiView's lens models have none".into());
    }
    let (width, height) = match (
        get(&["image_width"]),
        get(&["image_height"]),
        get(&["image_size", "imageSize"]),
    ) {
        (Some(w), Some(h), _) if w.len() == 1 && h.len() == 1 => (w[0], h[0]),
        (_, _, Some(s)) if s.len() == 2 => (s[0], s[1]),
        _ => return Err("no image size (image_width and image_height, or image_size)".into()),
    };
    if !(k[0] > 0.0 && k[4] > 0.0) {
        return Err("the camera matrix's focal lengths must be positive".into());
    }
    let rms = get(&["rms", "avg_reprojection_error", "reprojection_error"])
        .and_then(|v| v.first().copied());
    Ok(Imported {
        model: kb4(&d, "the distortion vector")?,
        affine: PixelAffine::pinhole(k[0], k[4], k[2], k[5]),
        width: width as u32,
        height: height as u32,
        by: String::new(),
        date: get(&["calibration_time"])
            .map(|_| String::new())
            .unwrap_or_default(),
        source: format!(
            "OpenCV fisheye, {}",
            path.extension().and_then(|e| e.to_str()).unwrap_or("yaml")
        ),
        rms_px: rms,
    })
}

/// A file's top-level names and their numbers, or why a name's value is not numbers.
type Fields = Vec<(String, Result<Vec<f64>, Unreadable>)>;

/// Top-level name → numbers, for YAML FileStorage.
fn yaml_fields(text: &str) -> Result<Fields, Unreadable> {
    // FileStorage writes `%YAML:1.0`, which is not a YAML 1.x directive; drop it.
    let cleaned: String = text
        .lines()
        .filter(|l| !l.starts_with("%YAML"))
        .collect::<Vec<_>>()
        .join("\n");
    let docs = YamlLoader::load_from_str(&cleaned).map_err(|e| format!("not valid YAML: {e}"))?;
    let root = docs.into_iter().next().ok_or("empty file")?;
    let map = root.as_hash().ok_or("the top level is not a mapping")?;
    let mut out = vec![];
    for (k, v) in map {
        let Some(name) = k.as_str() else { continue };
        let values = match v {
            Yaml::Hash(m) => m.get(&Yaml::String("data".into())).map(yaml_numbers),
            other => Some(yaml_numbers(other)),
        };
        if let Some(values) = values {
            out.push((name.to_string(), values));
        }
    }
    Ok(out)
}

fn yaml_numbers(v: &Yaml) -> Result<Vec<f64>, Unreadable> {
    match v {
        Yaml::Real(s) => s
            .parse()
            .map(|x| vec![x])
            .map_err(|_| Unreadable(format!("`{s}` is not a number"))),
        Yaml::Integer(i) => Ok(vec![*i as f64]),
        Yaml::Array(a) => a
            .iter()
            .map(|x| yaml_numbers(x).and_then(|v| v.first().copied().ok_or_else(|| "empty".into())))
            .collect(),
        _ => Err("not numeric".into()),
    }
}

/// Top-level element name → numbers, for XML FileStorage.
fn xml_fields(text: &str) -> Result<Fields, Unreadable> {
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("not valid XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "opencv_storage" {
        return Err(format!(
            "the root element is <{}>, not <opencv_storage>",
            root.tag_name().name()
        )
        .into());
    }
    let mut out = vec![];
    for node in root.children().filter(|n| n.is_element()) {
        let body = match node.children().find(|c| c.has_tag_name("data")) {
            Some(data) => data.text().unwrap_or(""),
            None => node.text().unwrap_or(""),
        };
        out.push((node.tag_name().name().to_string(), numbers(body)));
    }
    Ok(out)
}
