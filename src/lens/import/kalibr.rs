//! Kalibr camchain YAML (`camchain-*.yaml`): `pinhole` + `equidistant` is Kannala-Brandt,
//! `ds` + `none` is Double Sphere. Other Kalibr models (omni, eucm, fov, radtan) have no
//! DigiView equivalent and are refused by name.

use super::{Imported, Unreadable, kb4};
use crate::lens::models::DoubleSphere;
use crate::lens::{Model, PixelAffine};
use yaml_rust2::{Yaml, YamlLoader};

pub fn parse(text: &str, camera: Option<&str>) -> Result<Imported, Unreadable> {
    let docs = YamlLoader::load_from_str(text).map_err(|e| format!("not valid YAML: {e}"))?;
    let root = docs.into_iter().next().ok_or("empty file")?;
    let map = root
        .as_hash()
        .ok_or("the top level is not a mapping of cameras")?;
    let (name, cam) = match camera {
        Some(c) => (
            c.to_string(),
            map.get(&Yaml::String(c.into()))
                .ok_or_else(|| format!("no camera `{c}` in the file"))?,
        ),
        None => {
            let (k, v) = map.iter().next().ok_or("no cameras in the file")?;
            (k.as_str().unwrap_or("cam0").to_string(), v)
        }
    };
    let c = Camera { name: &name, cam };
    let camera_model = c
        .field("camera_model")?
        .as_str()
        .ok_or("camera_model is not text")?;
    let distortion = cam["distortion_model"].as_str().unwrap_or("none");
    let res = c.list("resolution")?;
    if res.len() != 2 {
        return Err(format!("{name}: resolution needs [width, height]").into());
    }
    let (model, f) = c.model(camera_model, distortion)?;
    Ok(Imported {
        model,
        affine: PixelAffine::pinhole(f[0], f[1], f[2], f[3]),
        width: res[0] as u32,
        height: res[1] as u32,
        by: String::new(),
        date: String::new(),
        source: format!("Kalibr camchain {name} ({camera_model}-{distortion})"),
        rms_px: None,
    })
}

/// One camera of the file, by its name.
struct Camera<'a> {
    name: &'a str,
    cam: &'a Yaml,
}

impl Camera<'_> {
    fn field(&self, f: &str) -> Result<&Yaml, Unreadable> {
        let v = &self.cam[f];
        match v.is_badvalue() {
            true => Err(Unreadable(format!("{}: no `{f}`", self.name))),
            false => Ok(v),
        }
    }

    fn list(&self, f: &str) -> Result<Vec<f64>, Unreadable> {
        let name = self.name;
        self.field(f)?
            .as_vec()
            .ok_or_else(|| format!("{name}: `{f}` is not a list"))?
            .iter()
            .map(|x| {
                x.as_f64()
                    .or_else(|| x.as_i64().map(|i| i as f64))
                    .ok_or_else(|| Unreadable(format!("{name}: `{f}` holds a non-number")))
            })
            .collect()
    }

    /// The lens model and the pinhole's fu, fv, pu, pv, by Kalibr's camera and distortion
    /// models.
    fn model(&self, camera_model: &str, distortion: &str) -> Result<(Model, [f64; 4]), Unreadable> {
        let (name, intr) = (self.name, self.list("intrinsics")?);
        match (camera_model, distortion) {
            ("pinhole", "equidistant") => {
                if intr.len() != 4 {
                    return Err(format!("{name}: pinhole intrinsics need [fu, fv, pu, pv]").into());
                }
                let model = kb4(&self.list("distortion_coeffs")?, "distortion_coeffs")?;
                Ok((model, [intr[0], intr[1], intr[2], intr[3]]))
            }
            ("ds", "none") => {
                if intr.len() != 6 {
                    return Err(
                        format!("{name}: ds intrinsics need [xi, alpha, fu, fv, pu, pv]").into(),
                    );
                }
                let model = Model::DoubleSphere(DoubleSphere {
                    xi: intr[0],
                    alpha: intr[1],
                });
                Ok((model, [intr[2], intr[3], intr[4], intr[5]]))
            }
            (m, d) => Err(format!(
                "{name}: Kalibr model {m}-{d} has no DigiView equivalent (pinhole-equidistant or \
                 ds-none)"
            )
            .into()),
        }
    }
}
