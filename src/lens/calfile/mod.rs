//! lens.cal: the human-editable TOML file that holds the named, calibrated lenses.
//!
//! Parsing keeps every field's span so that a bad value is reported as `file:line: field:
//! problem`. The fields every lens has are read here; each lens model reads its own
//! (`RadialModel::read`, through `fields`), and a field no one reads is an error. New entries
//! (from `digiview lens import`) are appended as text, so a user's comments and ordering
//! survive. The format is documented in docs/lens-cal.md.

mod fields;
mod pair;

pub use fields::{Fields, TomlWriter};
pub use pair::{DEFAULT_FEATHER_DEG, PairOf};

use super::{Lens, Model, PixelAffine};
use crate::units::{Angle, line_of};
use fields::Table;
use serde::Deserialize;
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
    #[error("lens_id {id} is not in {path}")]
    NoSuchId { path: PathBuf, id: u8 },
    #[error("{path}: {message}")]
    Import { path: PathBuf, message: String },
    #[error(
        "lens {name} sees two images side by side in a {}x{} frame; a {}x{} frame is another \
         shape, which would squeeze them (a frame of the pair's shape is needed)",
        lens.0, lens.1, frame.0, frame.1
    )]
    PairShape {
        name: String,
        lens: (u32, u32),
        frame: (u32, u32),
    },
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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[serde(default)]
    lens: Vec<Spanned<Table>>,
    #[serde(default)]
    pair: Vec<Spanned<Table>>,
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
    /// For a `[[pair]]`: its two lenses and their pose (the fields above are then the first
    /// lens's, but for the name, id, field of view and provenance).
    pub pair: Option<Box<PairOf>>,
}

impl LensEntry {
    pub fn lens(&self) -> Lens {
        if let Some(pair) = &self.pair {
            return pair.lens(&self.name, self.lens_id);
        }
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
        let mut out = TomlWriter::default();
        let table = if self.pair.is_some() { "pair" } else { "lens" };
        out.line(format!("[[{table}]]"));
        out.line(format!("name = {:?}", self.name));
        out.line(format!("lens_id = {}", self.lens_id));
        if let Some(pair) = &self.pair {
            pair.write(&mut out);
            out.line(self.provenance_line());
            return out.text;
        }
        out.line(format!("model = {:?}", self.model.name()));
        out.line(format!("width = {}\nheight = {}", self.width, self.height));
        out.line(format!("fov = \"{:.4}deg\"", self.fov.to_degrees()));
        let radius = self
            .circle_radius
            .unwrap_or_else(|| self.lens().circle_radius());
        out.line(format!("circle_radius = {radius:.2}"));
        self.model.write(&self.affine, &mut out);
        out.line(self.provenance_line());
        out.text
    }

    fn provenance_line(&self) -> String {
        let p = &self.provenance;
        let mut provenance = format!(
            "provenance = {{ kind = {:?}, by = {:?}, date = {:?}, source = {:?}",
            p.kind, p.by, p.date, p.source
        );
        if !p.assumption.is_empty() {
            provenance += &format!(", assumption = {:?}", p.assumption);
        }
        if let Some(rms) = p.rms_px {
            provenance += &format!(", rms_px = {rms}");
        }
        provenance + " }"
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
        let raw: RawFile = toml::from_str(text).map_err(|e| {
            let start = e.span().map_or(0, |s| s.start);
            let field = key_at(text, start);
            LensError::Invalid {
                path: path.into(),
                line: line_of(text, start),
                field: if field.is_empty() {
                    "(file)".into()
                } else {
                    field
                },
                message: e.message().trim().to_string(),
            }
        })?;
        let mut entries: Vec<LensEntry> = Vec::new();
        let tables = raw.lens.iter().map(|t| (t, false));
        for (table, is_pair) in tables.chain(raw.pair.iter().map(|t| (t, true))) {
            let fields = Fields::new(path, text, table.get_ref(), table.span().start);
            let entry = if is_pair {
                pair::read_pair(&fields, &entries)?
            } else {
                read_entry(&fields)?
            };
            if let Some(prev) = entries
                .iter()
                .find(|p| p.name == entry.name || p.lens_id == entry.lens_id)
            {
                let field = if prev.name == entry.name {
                    "name"
                } else {
                    "lens_id"
                };
                return Err(fields.invalid(
                    field,
                    format!("already used by the lens on line {}", prev.line),
                ));
            }
            entries.push(LensEntry {
                line: line_of(text, table.span().start),
                ..entry
            });
        }
        // In the file's order (pairs are read after every lens, whose names they use).
        entries.sort_by_key(|e| e.line);
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

/// The name and lens_id every table of lens.cal has, `[[lens]]` and `[[pair]]`.
fn name_and_id(f: &Fields) -> Result<(String, u8), LensError> {
    let (name, _) = f.required::<String>("name")?;
    let name = name.trim().to_string();
    if name.is_empty() {
        return Err(f.invalid("name", "must not be empty".into()));
    }
    let (lens_id, _) = f.required::<i64>("lens_id")?;
    let lens_id = u8::try_from(lens_id)
        .map_err(|_| f.invalid("lens_id", format!("must be 0..=255 (got {lens_id})")))?;
    Ok((name, lens_id))
}

/// One `[[lens]]` table: the fields every lens has, then its model's own.
fn read_entry(f: &Fields) -> Result<LensEntry, LensError> {
    let (name, lens_id) = name_and_id(f)?;
    let dim = |key: &'static str| -> Result<u32, LensError> {
        let (v, _) = f.required::<i64>(key)?;
        u32::try_from(v)
            .ok()
            .filter(|x| (1..=65535).contains(x))
            .ok_or_else(|| f.invalid(key, format!("must be 1..=65535 pixels (got {v})")))
    };
    let (width, height) = (dim("width")?, dim("height")?);
    let (Angle(fov), _) = f.required::<Angle>("fov")?;
    if !(fov > 0.0 && fov <= 2.0 * std::f64::consts::PI) {
        return Err(f.invalid("fov", format!("must be in (0, 360deg] (got {fov:.3} rad)")));
    }
    let (model_name, _) = f.required::<String>("model")?;
    f.set_model(&model_name);
    let (model, affine) = Model::read(&model_name, f).unwrap_or_else(|| {
        Err(f.invalid(
            "model",
            format!("unknown model `{model_name}` ({})", Model::NAMES.join(", ")),
        ))
    })?;
    let circle_radius = match f.get::<f64>("circle_radius")? {
        Some((r, _)) if !(r > 0.0 && r.is_finite()) => {
            return Err(f.invalid("circle_radius", format!("must be positive (got {r})")));
        }
        r => r.map(|(r, _)| r),
    };
    let Some((provenance, _)) = f.get::<Provenance>("provenance")? else {
        return Err(f.invalid(
            "provenance",
            "every lens needs `provenance = { kind = \"nominal\" | \"calibrated\", ... }`".into(),
        ));
    };
    if provenance.kind != "nominal" && provenance.kind != "calibrated" {
        return Err(f.invalid(
            "provenance.kind",
            format!(
                "must be \"nominal\" or \"calibrated\" (got {:?})",
                provenance.kind
            ),
        ));
    }
    f.no_others()?;
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
        pair: None,
    })
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
            "x/lens.cal:13: k: needs exactly 4 coefficients, k1, k2, k3, k4 (got 2)"
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
    fn every_model_of_the_registry_is_written_and_read_back_through_lens_cal() {
        let lenses = crate::lens::samples::sample_lenses();
        let names: Vec<&str> = lenses.iter().map(|l| l.radial.model.name()).collect();
        assert_eq!(
            names,
            Model::NAMES,
            "one sample lens per model, in code order"
        );
        for lens in lenses {
            let model = &lens.radial.model;
            assert_eq!(Model::NAMES[model.code() as usize], model.name());
            let entry = LensEntry {
                name: lens.name.clone(),
                lens_id: lens.id,
                model: model.clone(),
                affine: lens.affine,
                width: lens.width,
                height: lens.height,
                fov: lens.fov(),
                circle_radius: None,
                provenance: Provenance {
                    kind: "nominal".into(),
                    ..Provenance::default()
                },
                line: 0,
                pair: None,
            };
            let back = LensCal::parse(Path::new("m"), &entry.to_toml()).unwrap();
            let back = &back.entries[0];
            assert_eq!(&back.model, model, "{}", lens.name);
            assert_eq!(back.affine, lens.affine, "{}", lens.name);
        }
    }

    #[test]
    fn a_field_the_model_does_not_read_is_refused_naming_the_fields_it_has() {
        let e = err(&GOOD.replace("model = \"kannala_brandt\"", "model = \"equidistant\""));
        assert!(
            e.starts_with(
                "x/lens.cal:13: k: unknown field `k`: a lens of model `equidistant` has "
            ),
            "{e}"
        );
        assert!(e.contains("fx, fy, cx, cy"), "{e}");
        let e = err(&GOOD.replace("fx = 300.0", "fx = 300.0\nxi = 0.1"));
        assert!(
            e.starts_with("x/lens.cal:10: xi: unknown field `xi`"),
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
