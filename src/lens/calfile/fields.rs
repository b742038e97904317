//! One `[[lens]]` table of lens.cal, both ways: [`Fields`] reads its values, each with where
//! it stands so that a bad one is reported as `file:line: field: problem`, and remembers which
//! fields were asked for, so that any other is reported as unknown; [`TomlWriter`] writes a
//! table in the form lens.cal documents. Lens models read and write their own fields through
//! these (`RadialModel::read` and `write`).

use super::LensError;
use crate::lens::PixelAffine;
use crate::units::line_of;
use serde::de::DeserializeOwned;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;
use toml::{Spanned, Value};

/// A table's values by key, each with its span in the file.
pub(super) type Table = BTreeMap<String, Spanned<Value>>;

/// The fields of one `[[lens]]` table.
pub struct Fields<'a> {
    path: &'a Path,
    text: &'a str,
    table: &'a Table,
    /// Where the table starts, for fields it lacks.
    at: usize,
    /// The model the table names ("" before it is read), for "model `m` needs `f`".
    model: RefCell<String>,
    asked: RefCell<Vec<&'static str>>,
}

impl<'a> Fields<'a> {
    pub(super) fn new(path: &'a Path, text: &'a str, table: &'a Table, at: usize) -> Self {
        Fields {
            path,
            text,
            table,
            at,
            model: RefCell::default(),
            asked: RefCell::default(),
        }
    }

    /// A field's value as `T`, with its span; None where the table lacks it.
    pub(super) fn get<T: DeserializeOwned>(
        &self,
        key: &'static str,
    ) -> Result<Option<(T, Range<usize>)>, LensError> {
        self.asked.borrow_mut().push(key);
        let Some(v) = self.table.get(key) else {
            return Ok(None);
        };
        let span = v.span();
        match v.get_ref().clone().try_into::<T>() {
            Ok(t) => Ok(Some((t, span))),
            Err(e) => Err(self.error(span.start, key, e.message().trim().to_string())),
        }
    }

    /// A field the table must have.
    pub(super) fn required<T: DeserializeOwned>(
        &self,
        key: &'static str,
    ) -> Result<(T, Range<usize>), LensError> {
        self.get(key)?
            .ok_or_else(|| self.error(self.at, key, format!("missing field `{key}`")))
    }

    pub(super) fn set_model(&self, name: &str) {
        *self.model.borrow_mut() = name.to_string();
    }

    /// The problem `message` with field `key` (or `key.part` of a table), at the key's line
    /// (the model's line, or the table's, where the table lacks it).
    pub fn invalid(&self, key: &str, message: String) -> LensError {
        let top = key.split('.').next().unwrap_or(key);
        let at = match self.table.get(top).or_else(|| self.table.get("model")) {
            Some(v) => v.span().start,
            None => self.at,
        };
        self.error(at, key, message)
    }

    fn error(&self, offset: usize, field: &str, message: String) -> LensError {
        LensError::Invalid {
            path: self.path.into(),
            line: line_of(self.text, offset),
            field: field.to_string(),
            message,
        }
    }

    /// A finite number the model needs.
    pub fn number(&self, key: &'static str) -> Result<f64, LensError> {
        let Some((v, _)) = self.get::<f64>(key)? else {
            let model = self.model.borrow();
            return Err(self.invalid(key, format!("model `{model}` needs `{key}`")));
        };
        if !v.is_finite() {
            return Err(self.invalid(key, "must be a finite number".into()));
        }
        Ok(v)
    }

    /// A positive number the model needs.
    pub fn positive(&self, key: &'static str) -> Result<f64, LensError> {
        let x = self.number(key)?;
        if x <= 0.0 {
            return Err(self.invalid(key, format!("must be positive (got {x})")));
        }
        Ok(x)
    }

    /// A list of numbers the model needs; `missing` says what to write where it is absent.
    pub fn numbers(&self, key: &'static str, missing: &str) -> Result<Vec<f64>, LensError> {
        self.optional_numbers(key)?
            .ok_or_else(|| self.invalid(key, missing.to_string()))
    }

    /// Exactly `N` finite coefficients under `key`, which model `model` needs.
    pub fn coefficients<const N: usize>(
        &self,
        key: &'static str,
        model: &str,
    ) -> Result<[f64; N], LensError> {
        let names: Vec<String> = (1..=N).map(|i| format!("{key}{i}")).collect();
        let list = names.join(", ");
        let given = self.numbers(key, &format!("model `{model}` needs `{key} = [{list}]`"))?;
        let k: [f64; N] = given.as_slice().try_into().map_err(|_| {
            self.invalid(
                key,
                format!(
                    "needs exactly {N} coefficients, {list} (got {})",
                    given.len()
                ),
            )
        })?;
        if k.iter().any(|x| !x.is_finite()) {
            return Err(self.invalid(key, "coefficients must be finite".into()));
        }
        Ok(k)
    }

    pub fn optional_numbers(&self, key: &'static str) -> Result<Option<Vec<f64>>, LensError> {
        Ok(self.get::<Vec<f64>>(key)?.map(|(v, _)| v))
    }

    /// The classic models' pixel affine: focal lengths `fx`, `fy` and principal point `cx`,
    /// `cy`, in pixels.
    pub fn pinhole(&self) -> Result<PixelAffine, LensError> {
        Ok(PixelAffine::pinhole(
            self.positive("fx")?,
            self.positive("fy")?,
            self.number("cx")?,
            self.number("cy")?,
        ))
    }

    /// Refuses any field no one asked for, naming the fields this table's model has.
    pub(super) fn no_others(&self) -> Result<(), LensError> {
        let asked = self.asked.borrow();
        match self.table.keys().find(|k| !asked.contains(&k.as_str())) {
            None => Ok(()),
            Some(key) => {
                let span = self.table[key].span();
                let model = self.model.borrow();
                Err(self.error(
                    span.start,
                    key,
                    format!(
                        "unknown field `{key}`: a lens of model `{model}` has {}",
                        asked.join(", ")
                    ),
                ))
            }
        }
    }
}

/// A `[[lens]]` table being written, a `key = value` line at a time.
#[derive(Debug, Default)]
pub struct TomlWriter {
    pub(super) text: String,
}

impl TomlWriter {
    /// `key = value`, the value as Rust prints it (the shortest form that reads back the same).
    pub fn number(&mut self, key: &str, v: f64) {
        self.text += &format!("{key} = {v}\n");
    }

    /// `key = [a, b, ...]`, in exponent form.
    pub fn list(&mut self, key: &str, values: &[f64]) {
        let items: Vec<String> = values.iter().map(|x| format!("{x:e}")).collect();
        self.text += &format!("{key} = [{}]\n", items.join(", "));
    }

    /// What [`Fields::pinhole`] reads.
    pub fn pinhole(&mut self, affine: &PixelAffine) {
        let (m, o) = (affine.matrix, affine.offset);
        for (key, v) in [
            ("fx", m.x_axis.x),
            ("fy", m.y_axis.y),
            ("cx", o.x),
            ("cy", o.y),
        ] {
            self.number(key, v);
        }
    }

    /// A line as it is.
    pub(super) fn line(&mut self, line: String) {
        self.text += &line;
        self.text.push('\n');
    }
}
