//! Gyroflow lens profiles (JSON). Only the `opencv_fisheye` model maps onto DigiView's
//! models. When `asymmetrical` is false, Gyroflow itself ignores the stored principal point
//! and uses the frame centre; so do we. A `crop` factor divides the focal lengths, as in Gyroflow.

use super::{Imported, Unreadable, kb4};
use crate::lens::PixelAffine;
use serde::Deserialize;

#[derive(Deserialize)]
struct Dim {
    w: u32,
    h: u32,
}

#[derive(Deserialize)]
#[allow(non_snake_case)]
struct Params {
    camera_matrix: Vec<[f64; 3]>,
    distortion_coeffs: Vec<f64>,
    #[serde(default)]
    RMS_error: Option<f64>,
}

#[derive(Deserialize)]
struct Profile {
    calib_dimension: Dim,
    fisheye_params: Params,
    #[serde(default)]
    asymmetrical: bool,
    #[serde(default)]
    distortion_model: Option<String>,
    #[serde(default)]
    crop: Option<f64>,
    #[serde(default)]
    input_horizontal_stretch: Option<f64>,
    #[serde(default)]
    input_vertical_stretch: Option<f64>,
    #[serde(default)]
    calibrated_by: String,
    #[serde(default)]
    camera_brand: String,
    #[serde(default)]
    camera_model: String,
    #[serde(default)]
    lens_model: String,
    #[serde(default)]
    date: String,
}

pub fn parse(text: &str) -> Result<Imported, Unreadable> {
    let p: Profile =
        serde_json::from_str(text).map_err(|e| format!("not a Gyroflow lens profile: {e}"))?;
    if let Some(m) = p
        .distortion_model
        .as_deref()
        .filter(|m| *m != "opencv_fisheye")
    {
        return Err(
            format!("distortion_model `{m}` is not supported (only opencv_fisheye)").into(),
        );
    }
    for s in [p.input_horizontal_stretch, p.input_vertical_stretch]
        .into_iter()
        .flatten()
    {
        if (s - 1.0).abs() > 1e-6 && s > 0.01 {
            return Err(
                format!("anamorphic profiles (input stretch {s}) are not supported").into(),
            );
        }
    }
    let k = &p.fisheye_params.camera_matrix;
    if k.len() != 3 {
        return Err(format!("camera_matrix has {} rows, not 3", k.len()).into());
    }
    let crop = p.crop.filter(|c| *c > 0.0).unwrap_or(1.0);
    let (fx, fy) = (k[0][0] / crop, k[1][1] / crop);
    let (cx, cy) = if p.asymmetrical {
        (k[0][2], k[1][2])
    } else {
        (
            p.calib_dimension.w as f64 / 2.0,
            p.calib_dimension.h as f64 / 2.0,
        )
    };
    if !(fx > 0.0 && fy > 0.0) {
        return Err("camera_matrix's focal lengths must be positive".into());
    }
    let what = [p.camera_brand.as_str(), &p.camera_model, &p.lens_model]
        .iter()
        .filter(|s| !s.is_empty())
        .cloned()
        .collect::<Vec<_>>()
        .join(" ");
    Ok(Imported {
        model: kb4(&p.fisheye_params.distortion_coeffs, "distortion_coeffs")?,
        affine: PixelAffine::pinhole(fx, fy, cx, cy),
        width: p.calib_dimension.w,
        height: p.calib_dimension.h,
        by: p.calibrated_by,
        date: p.date,
        source: format!("Gyroflow profile {what}, asymmetrical = {}", p.asymmetrical),
        rms_px: p.fisheye_params.RMS_error,
    })
}
