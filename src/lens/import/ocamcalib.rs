//! OCamCalib's `calib_results.txt`: after comment lines, five data lines in order: the direct
//! polynomial (count, coefficients), the inverse polynomial (count, coefficients), the centre
//! (row, column, 0-based), the affine c d e, and the image size (height, width).

use super::{Imported, Unreadable, numbers};
use crate::lens::models::Ocam;
use crate::lens::{Model, PixelAffine};

pub fn parse(text: &str) -> Result<Imported, Unreadable> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
        .collect();
    let row = |i: usize, what: &str| -> Result<Vec<f64>, Unreadable> {
        let (n, l) = lines
            .get(i)
            .ok_or_else(|| format!("missing the {what} line"))?;
        numbers(l).map_err(|e| Unreadable(format!("line {n} ({what}): {e}")))
    };
    let counted = |i: usize, what: &str| -> Result<Vec<f64>, Unreadable> {
        let v = row(i, what)?;
        let n = *v
            .first()
            .ok_or_else(|| format!("the {what} line is empty"))? as usize;
        if v.len() != n + 1 {
            return Err(format!(
                "the {what} line says {n} coefficients but has {}",
                v.len() - 1
            )
            .into());
        }
        Ok(v[1..].to_vec())
    };
    let pol = counted(0, "direct polynomial")?;
    let invpol = counted(1, "inverse polynomial")?;
    let centre = row(2, "centre")?;
    let cde = row(3, "affine")?;
    let size = row(4, "image size")?;
    if centre.len() != 2 || cde.len() != 3 || size.len() != 2 {
        return Err("the centre needs 2 values, the affine 3, the image size 2".into());
    }
    if pol.len() < 2 || pol[0] >= 0.0 {
        return Err("the direct polynomial's first coefficient must be negative".into());
    }
    Ok(Imported {
        model: Model::Ocam(Ocam { pol, invpol }),
        affine: PixelAffine::ocam(cde[0], cde[1], cde[2], centre[0], centre[1]),
        width: size[1] as u32,
        height: size[0] as u32,
        by: String::new(),
        date: String::new(),
        source: "OCamCalib calib_results.txt".into(),
        rms_px: None,
    })
}
