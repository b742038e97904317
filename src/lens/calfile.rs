//! lens.cal: the human-editable TOML file that holds the named, calibrated lenses.
//!
//! Parsing keeps every field's span so that a bad value is reported as `file:line: field:
//! problem`. New entries (from `digiview lens import`) are appended as text, so a user's
//! comments and ordering survive. The format is documented in docs/lens-cal.md.

use super::{Lens, Model, PixelAffine};
use crate::units::Angle;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Debug, thiserror::Error)]
pub enum LensError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {field}: {message}")]
    Invalid {
        path: PathBuf,
        line: usize,
        field: String,
        message: String,
    },
    #[error("{path}: no lens named or numbered `{wanted}` (have: {have})")]
    NotFound {
        path: PathBuf,
        wanted: String,
        have: String,
    },
    #[error("{path}: {message}")]
    Import { path: PathBuf, message: String },
}

/// Who made a calibration and how much to trust it.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// `nominal` (from published figures) or `calibrated` (measured).
    pub kind: String,
    #[serde(default)]
    pub by: String,
    #[serde(default)]
    pub date: String,
    #[serde(default)]
    pub source: String,
    #[serde(default)]
    pub assumption: String,
    #[serde(default)]
    pub rms_px: Option<f64>,
}

/// One `[[lens]]` table as written, every field with its span.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEntry {
    name: Spanned<String>,
    lens_id: Spanned<i64>,
    model: Spanned<String>,
    width: Spanned<i64>,
    height: Spanned<i64>,
    fov: Spanned<Angle>,
    circle_radius: Option<Spanned<f64>>,
    fx: Option<Spanned<f64>>,
    fy: Option<Spanned<f64>>,
    cx: Option<Spanned<f64>>,
    cy: Option<Spanned<f64>>,
    k: Option<Spanned<Vec<f64>>>,
    xi: Option<Spanned<f64>>,
    alpha: Option<Spanned<f64>>,
    pol: Option<Spanned<Vec<f64>>>,
    invpol: Option<Spanned<Vec<f64>>>,
    c: Option<Spanned<f64>>,
    d: Option<Spanned<f64>>,
    e: Option<Spanned<f64>>,
    xc: Option<Spanned<f64>>,
    yc: Option<Spanned<f64>>,
    provenance: Option<Spanned<Provenance>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[serde(default)]
    lens: Vec<Spanned<RawEntry>>,
}

/// A lens as lens.cal declares it, at its calibration frame size.
#[derive(Clone, Debug, PartialEq)]
pub struct LensEntry {
    pub name: String,
    pub lens_id: u8,
    pub model: Model,
    pub affine: PixelAffine,
    pub width: u32,
    pub height: u32,
    pub fov: f64,
    /// The image circle radius the file declares, if any (`lens check` compares it).
    pub circle_radius: Option<f64>,
    pub provenance: Provenance,
    /// 1-based line of the entry's first field, for messages.
    pub line: usize,
}

impl LensEntry {
    pub fn lens(&self) -> Lens {
        Lens::new(
            &self.name,
            self.lens_id,
            self.model.clone(),
            self.affine,
            (self.width, self.height),
            self.fov,
        )
    }

    /// The entry as a `[[lens]]` TOML table, in the form lens.cal documents.
    pub fn to_toml(&self) -> String {
        let mut s = String::from("[[lens]]\n");
        s += &format!(
            "name = {:?}\nlens_id = {}\nmodel = {:?}\n",
            self.name,
            self.lens_id,
            self.model.name()
        );
        s += &format!("width = {}\nheight = {}\n", self.width, self.height);
        s += &format!("fov = \"{:.4}deg\"\n", self.fov.to_degrees());
        let lens = self.lens();
        s += &format!(
            "circle_radius = {:.2}\n",
            self.circle_radius.unwrap_or_else(|| lens.circle_radius())
        );
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        match &self.model {
            Model::Ocam { pol, invpol } => {
                let m = self.affine.matrix;
                // matrix columns: (1, d), (e, c); offset (yc, xc)
                s += &format!("pol = [{}]\ninvpol = [{}]\n", list(pol), list(invpol));
                s += &format!(
                    "c = {}\nd = {}\ne = {}\n",
                    m.y_axis.y, m.x_axis.y, m.y_axis.x
                );
                s += &format!(
                    "xc = {}\nyc = {}\n",
                    self.affine.offset.y, self.affine.offset.x
                );
            }
            model => {
                let (m, o) = (self.affine.matrix, self.affine.offset);
                s += &format!(
                    "fx = {}\nfy = {}\ncx = {}\ncy = {}\n",
                    m.x_axis.x, m.y_axis.y, o.x, o.y
                );
                match model {
                    Model::KannalaBrandt { k } => s += &format!("k = [{}]\n", list(k)),
                    Model::DoubleSphere { xi, alpha } => {
                        s += &format!("xi = {xi}\nalpha = {alpha}\n")
                    }
                    _ => {}
                }
            }
        }
        let p = &self.provenance;
        s += &format!(
            "provenance = {{ kind = {:?}, by = {:?}, date = {:?}, source = {:?}",
            p.kind, p.by, p.date, p.source
        );
        if !p.assumption.is_empty() {
            s += &format!(", assumption = {:?}", p.assumption);
        }
        if let Some(rms) = p.rms_px {
            s += &format!(", rms_px = {rms}");
        }
        s += " }\n";
        s
    }
}

/// A parsed lens.cal.
#[derive(Clone, Debug)]
pub struct LensCal {
    pub path: PathBuf,
    pub entries: Vec<LensEntry>,
}

impl LensCal {
    pub fn load(path: &Path) -> Result<LensCal, LensError> {
        let text = std::fs::read_to_string(path).map_err(|source| LensError::Io {
            path: path.into(),
            source,
        })?;
        LensCal::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<LensCal, LensError> {
        let invalid = |span: Option<Range<usize>>, field: &str, message: String| {
            let start = span.map(|s| s.start).unwrap_or(0);
            LensError::Invalid {
                path: path.into(),
                line: line_of(text, start),
                field: field.to_string(),
                message,
            }
        };
        let raw: RawFile = toml::from_str(text).map_err(|e| {
            let field = e.span().map(|s| key_at(text, s.start)).unwrap_or_default();
            let message = e.message().trim().to_string();
            invalid(
                e.span(),
                if field.is_empty() { "(file)" } else { &field },
                message,
            )
        })?;
        let mut entries = Vec::new();
        for table in raw.lens {
            let entry = build_entry(table.get_ref(), &|span, field, msg| {
                invalid(Some(span), field, msg)
            })?;
            if let Some(prev) = entries
                .iter()
                .find(|p: &&LensEntry| p.name == entry.name || p.lens_id == entry.lens_id)
            {
                let (field, span) = if prev.name == entry.name {
                    ("name", table.get_ref().name.span())
                } else {
                    ("lens_id", table.get_ref().lens_id.span())
                };
                return Err(invalid(
                    Some(span),
                    field,
                    format!("already used by the lens on line {}", prev.line),
                ));
            }
            entries.push(LensEntry {
                line: line_of(text, table.span().start),
                ..entry
            });
        }
        Ok(LensCal {
            path: path.into(),
            entries,
        })
    }

    /// Finds a lens by name (case-insensitive) or by lens_id written as a number.
    pub fn find(&self, wanted: &str) -> Result<&LensEntry, LensError> {
        let by_id = wanted.trim().parse::<u8>().ok();
        self.entries
            .iter()
            .find(|e| e.name.eq_ignore_ascii_case(wanted.trim()) || Some(e.lens_id) == by_id)
            .ok_or_else(|| LensError::NotFound {
                path: self.path.clone(),
                wanted: wanted.to_string(),
                have: self
                    .entries
                    .iter()
                    .map(|e| format!("{} ({})", e.name, e.lens_id))
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    pub fn by_id(&self, id: u8) -> Option<&LensEntry> {
        self.entries.iter().find(|e| e.lens_id == id)
    }
}

type Invalid<'a> = &'a dyn Fn(Range<usize>, &str, String) -> LensError;

fn build_entry(raw: &RawEntry, invalid: Invalid) -> Result<LensEntry, LensError> {
    let need = |v: &Option<Spanned<f64>>, field: &str, model: &str| -> Result<f64, LensError> {
        let v = v.as_ref().ok_or_else(|| {
            invalid(
                raw.model.span(),
                field,
                format!("model `{model}` needs `{field}`"),
            )
        })?;
        if !v.get_ref().is_finite() {
            return Err(invalid(v.span(), field, "must be a finite number".into()));
        }
        Ok(*v.get_ref())
    };
    let positive = |v: &Option<Spanned<f64>>, field: &str, model: &str| -> Result<f64, LensError> {
        let x = need(v, field, model)?;
        if x <= 0.0 {
            return Err(invalid(
                v.as_ref().unwrap().span(),
                field,
                format!("must be positive (got {x})"),
            ));
        }
        Ok(x)
    };
    let name = raw.name.get_ref().trim().to_string();
    if name.is_empty() {
        return Err(invalid(raw.name.span(), "name", "must not be empty".into()));
    }
    let lens_id = u8::try_from(*raw.lens_id.get_ref()).map_err(|_| {
        invalid(
            raw.lens_id.span(),
            "lens_id",
            format!("must be 0..=255 (got {})", raw.lens_id.get_ref()),
        )
    })?;
    let dim = |v: &Spanned<i64>, field: &str| {
        u32::try_from(*v.get_ref())
            .ok()
            .filter(|x| (1..=65535).contains(x))
            .ok_or_else(|| {
                invalid(
                    v.span(),
                    field,
                    format!("must be 1..=65535 pixels (got {})", v.get_ref()),
                )
            })
    };
    let (width, height) = (dim(&raw.width, "width")?, dim(&raw.height, "height")?);
    let fov = raw.fov.get_ref().0;
    if !(fov > 0.0 && fov <= 2.0 * std::f64::consts::PI) {
        return Err(invalid(
            raw.fov.span(),
            "fov",
            format!("must be in (0, 360deg] (got {:.3} rad)", fov),
        ));
    }
    let model_name = raw.model.get_ref().as_str();
    let model = match model_name {
        "equidistant" => Model::Equidistant,
        "equisolid" => Model::Equisolid,
        "stereographic" => Model::Stereographic,
        "orthographic" => Model::Orthographic,
        "kannala_brandt" => {
            let k = raw.k.as_ref().ok_or_else(|| {
                invalid(
                    raw.model.span(),
                    "k",
                    "model `kannala_brandt` needs `k = [k1, k2, k3, k4]`".into(),
                )
            })?;
            let arr: [f64; 4] = k.get_ref().as_slice().try_into().map_err(|_| {
                invalid(
                    k.span(),
                    "k",
                    format!(
                        "needs exactly four coefficients (got {})",
                        k.get_ref().len()
                    ),
                )
            })?;
            if arr.iter().any(|x| !x.is_finite()) {
                return Err(invalid(k.span(), "k", "coefficients must be finite".into()));
            }
            Model::KannalaBrandt { k: arr }
        }
        "double_sphere" => {
            let xi = need(&raw.xi, "xi", model_name)?;
            let alpha = need(&raw.alpha, "alpha", model_name)?;
            if !(0.0..=1.0).contains(&alpha) {
                return Err(invalid(
                    raw.alpha.as_ref().unwrap().span(),
                    "alpha",
                    format!("must be in [0, 1] (got {alpha})"),
                ));
            }
            Model::DoubleSphere { xi, alpha }
        }
        "ocam" => {
            let pol = raw.pol.as_ref().ok_or_else(|| {
                invalid(raw.model.span(), "pol", "model `ocam` needs `pol`".into())
            })?;
            if pol.get_ref().len() < 2
                || pol.get_ref()[0] >= 0.0
                || pol.get_ref().iter().any(|x| !x.is_finite())
            {
                return Err(invalid(
                    pol.span(),
                    "pol",
                    "needs at least two finite coefficients, the first negative (OCamCalib's a0)"
                        .into(),
                ));
            }
            let invpol = raw
                .invpol
                .as_ref()
                .map(|v| v.get_ref().clone())
                .unwrap_or_default();
            if invpol.iter().any(|x| !x.is_finite()) {
                return Err(invalid(
                    raw.invpol.as_ref().unwrap().span(),
                    "invpol",
                    "coefficients must be finite".into(),
                ));
            }
            Model::Ocam {
                pol: pol.get_ref().clone(),
                invpol,
            }
        }
        other => {
            return Err(invalid(
                raw.model.span(),
                "model",
                format!(
                    "unknown model `{other}` (equidistant, equisolid, stereographic, orthographic, kannala_brandt, double_sphere, ocam)"
                ),
            ));
        }
    };
    let affine = if let Model::Ocam { .. } = model {
        let (c, d, e) = (
            need(&raw.c, "c", "ocam")?,
            need(&raw.d, "d", "ocam")?,
            need(&raw.e, "e", "ocam")?,
        );
        if (c - d * e).abs() < 1e-9 {
            return Err(invalid(
                raw.c.as_ref().unwrap().span(),
                "c",
                "the affine [c d; e 1] is singular".into(),
            ));
        }
        PixelAffine::ocam(
            c,
            d,
            e,
            need(&raw.xc, "xc", "ocam")?,
            need(&raw.yc, "yc", "ocam")?,
        )
    } else {
        PixelAffine::pinhole(
            positive(&raw.fx, "fx", model_name)?,
            positive(&raw.fy, "fy", model_name)?,
            need(&raw.cx, "cx", model_name)?,
            need(&raw.cy, "cy", model_name)?,
        )
    };
    let circle_radius = match &raw.circle_radius {
        Some(r) if !(*r.get_ref() > 0.0 && r.get_ref().is_finite()) => {
            return Err(invalid(
                r.span(),
                "circle_radius",
                format!("must be positive (got {})", r.get_ref()),
            ));
        }
        r => r.as_ref().map(|r| *r.get_ref()),
    };
    let provenance = raw
        .provenance
        .as_ref()
        .map(|p| p.get_ref().clone())
        .ok_or_else(|| {
            invalid(
                raw.name.span(),
                "provenance",
                "every lens needs `provenance = { kind = \"nominal\" | \"calibrated\", ... }`"
                    .into(),
            )
        })?;
    if provenance.kind != "nominal" && provenance.kind != "calibrated" {
        let span = raw.provenance.as_ref().unwrap().span();
        return Err(invalid(
            span,
            "provenance.kind",
            format!(
                "must be \"nominal\" or \"calibrated\" (got {:?})",
                provenance.kind
            ),
        ));
    }
    Ok(LensEntry {
        name,
        lens_id,
        model,
        affine,
        width,
        height,
        fov,
        circle_radius,
        provenance,
        line: 0,
    })
}

/// 1-based line number of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// The key written on the line that holds `offset` (`fx` for `fx = -3`), or "".
fn key_at(text: &str, offset: usize) -> String {
    let start = text[..offset.min(text.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("");
    match line.split_once('=') {
        Some((key, _)) if !key.trim_start().starts_with('[') => key.trim().to_string(),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[[lens]]
name = "T1"
lens_id = 7
model = "kannala_brandt"
width = 1280
height = 960
fov = "190deg"
fx = 300.0
fy = 300.0
cx = 639.5
cy = 479.5
k = [0.01, 0.0, 0.0, 0.0]
provenance = { kind = "calibrated", by = "test", date = "2026-11-21" }
"#;

    fn err(text: &str) -> String {
        LensCal::parse(Path::new("x/lens.cal"), text)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn a_good_entry_parses_and_finds_by_name_or_id() {
        let cal = LensCal::parse(Path::new("lens.cal"), GOOD).unwrap();
        assert_eq!(cal.find("t1").unwrap().lens_id, 7);
        assert_eq!(cal.find("7").unwrap().name, "T1");
        assert!(cal.find("nope").unwrap_err().to_string().contains("T1 (7)"));
    }

    #[test]
    fn a_bad_value_is_reported_with_file_line_and_field() {
        let e = err(&GOOD.replace("fx = 300.0", "fx = -300.0"));
        assert_eq!(e, "x/lens.cal:9: fx: must be positive (got -300)");
        let e = err(&GOOD.replace("fy = 300.0", "fy = \"wide\""));
        assert!(e.starts_with("x/lens.cal:10: fy: "), "{e}");
        let e = err(&GOOD.replace("k = [0.01, 0.0, 0.0, 0.0]", "k = [0.01, 0.0]"));
        assert_eq!(
            e,
            "x/lens.cal:13: k: needs exactly four coefficients (got 2)"
        );
        let e = err(&GOOD.replace("fov = \"190deg\"", "fov = \"190 degrees\""));
        assert!(e.starts_with("x/lens.cal:8: fov: "), "{e}");
        let e = err(&GOOD.replace("model = \"kannala_brandt\"", "model = \"fancy\""));
        assert!(
            e.starts_with("x/lens.cal:5: model: unknown model `fancy`"),
            "{e}"
        );
        let e = err(&GOOD.replace("cx = 639.5\n", ""));
        assert!(e.contains("model `kannala_brandt` needs `cx`"), "{e}");
        let e = err(&GOOD.replace("width = 1280", "width = 1280\nwidht = 3"));
        assert!(e.starts_with("x/lens.cal:7: widht: unknown field"), "{e}");
        let e = err("[[lens]\nname=1");
        assert!(e.starts_with("x/lens.cal:1: "), "{e}");
    }

    #[test]
    fn duplicate_names_and_ids_are_refused() {
        let e = err(&format!(
            "{GOOD}{}",
            GOOD.replace("lens_id = 7", "lens_id = 8")
        ));
        assert!(
            e.contains(": name: already used by the lens on line 2"),
            "{e}"
        );
    }

    #[test]
    fn an_entry_written_back_as_toml_parses_to_the_same_lens() {
        let entry = LensCal::parse(Path::new("a"), GOOD).unwrap().entries[0].clone();
        let again = LensCal::parse(Path::new("b"), &entry.to_toml())
            .unwrap()
            .entries[0]
            .clone();
        assert_eq!(entry.model, again.model);
        assert_eq!(entry.affine, again.affine);
        assert!((entry.fov - again.fov).abs() < 1e-6);
    }
}
