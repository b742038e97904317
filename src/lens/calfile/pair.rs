//! One `[[pair]]` table of lens.cal: two of the file's lenses back to back as one source that
//! sees the whole sphere (src/lens/pair.rs). The pair names its lenses, which must share a
//! frame and a model; its pose is the correction to the nominal back-to-back turn, as three
//! angles a user can read and edit (`digiview lens pair-fit` writes them).

use super::fields::{Fields, TomlWriter};
use super::{LensEntry, LensError, Provenance};
use crate::lens::pair::{Mask, PairPose, correction};
use crate::lens::{Lens, Model};
use crate::units::Angle;
use glam::{DVec2, DVec3};

/// The feather a pair blends its seam over where lens.cal says none.
pub const DEFAULT_FEATHER_DEG: f64 = 4.0;
/// The widest feather: past this the blend reaches where one lens no longer sees.
pub const MAX_FEATHER_DEG: f64 = 20.0;

/// A pair as lens.cal declares it: its two lenses (whole entries, as the file has them) and
/// how they sit.
#[derive(Clone, Debug, PartialEq)]
pub struct PairOf {
    pub first: LensEntry,
    pub second: LensEntry,
    /// The correction's roll, pitch and yaw (radians; [`correction`]).
    pub rotation: [f64; 3],
    /// The second lens's centre in the first's frame, metres.
    pub baseline: [f64; 3],
    /// The seam's blend width, radians.
    pub feather: f64,
    /// What the airframe hides: polygons in the frame's pixels, each within one lens's image.
    pub masks: Vec<Mask>,
}

impl PairOf {
    pub fn pose(&self) -> PairPose {
        let [roll, pitch, yaw] = self.rotation;
        PairPose {
            correction: correction(roll, pitch, yaw),
            baseline: DVec3::from_array(self.baseline),
            feather: self.feather,
            masks: self.masks.clone(),
        }
    }

    /// The pair as one lens, at the lenses' calibration frame.
    pub fn lens(&self, name: &str, id: u8) -> Lens {
        Lens::paired(
            &self.first.lens(),
            &self.second.lens(),
            name,
            id,
            self.pose(),
        )
    }

    /// The pair's own fields of a `[[pair]]` table (after its name and id).
    pub fn write(&self, out: &mut TomlWriter) {
        out.line(format!(
            "lenses = [{:?}, {:?}]",
            self.first.name, self.second.name
        ));
        let [r, p, y] = self.rotation.map(f64::to_degrees);
        out.line(format!(
            "rotation = [\"{r:.4}deg\", \"{p:.4}deg\", \"{y:.4}deg\"]"
        ));
        out.list("baseline", &self.baseline);
        out.line(format!("feather = \"{:.2}deg\"", self.feather.to_degrees()));
        if !self.masks.is_empty() {
            let polygon = |m: &Mask| {
                let points: Vec<String> = m
                    .points
                    .iter()
                    .map(|p| format!("[{}, {}]", p.x, p.y))
                    .collect();
                format!("  [{}],", points.join(", "))
            };
            out.line("masks = [".into());
            self.masks.iter().for_each(|m| out.line(polygon(m)));
            out.line("]".into());
        }
    }
}

/// Reads a `[[pair]]` table, whose lenses are among `lenses` (the file's `[[lens]]` entries).
pub(super) fn read_pair(f: &Fields, lenses: &[LensEntry]) -> Result<LensEntry, LensError> {
    let (name, lens_id) = super::name_and_id(f)?;
    let (names, _) = f.required::<Vec<String>>("lenses")?;
    let [first, second] = names.as_slice() else {
        return Err(f.invalid(
            "lenses",
            format!("must name two lenses (got {})", names.len()),
        ));
    };
    let find = |wanted: &str| {
        lenses
            .iter()
            .find(|e| e.name == wanted && e.pair.is_none())
            .cloned()
            .ok_or_else(|| {
                f.invalid(
                    "lenses",
                    format!("no `[[lens]]` named `{wanted}` in the file"),
                )
            })
    };
    let (first, second) = (find(first)?, find(second)?);
    check_lenses(f, &first, &second)?;
    let rotation = match f.get::<[Angle; 3]>("rotation")? {
        Some((angles, _)) => angles.map(|a| a.0),
        None => [0.0; 3],
    };
    if rotation.iter().any(|a| a.is_nan() || a.abs() > 0.5) {
        return Err(f.invalid(
            "rotation",
            "each angle must be within 28deg of the back-to-back pose (roll, pitch, yaw)".into(),
        ));
    }
    let baseline = f.get::<[f64; 3]>("baseline")?.map_or([0.0; 3], |b| b.0);
    if baseline.iter().any(|b| b.is_nan() || b.abs() > 1.0) {
        return Err(f.invalid(
            "baseline",
            "must be metres, each within 1 m (x, y, z)".into(),
        ));
    }
    let feather = f
        .get::<Angle>("feather")?
        .map_or(DEFAULT_FEATHER_DEG.to_radians(), |a| a.0.0);
    if !(0.0..=MAX_FEATHER_DEG.to_radians()).contains(&feather) {
        return Err(f.invalid("feather", format!("must be 0 to {MAX_FEATHER_DEG}deg")));
    }
    let masks = read_masks(f, &first, &second)?;
    let provenance = f
        .get::<Provenance>("provenance")?
        .map(|p| p.0)
        .unwrap_or_default();
    f.no_others()?;
    Ok(LensEntry {
        name,
        lens_id,
        fov: 2.0 * std::f64::consts::PI,
        circle_radius: None,
        provenance,
        line: 0,
        pair: Some(Box::new(PairOf {
            rotation,
            baseline,
            feather,
            masks,
            first: first.clone(),
            second,
        })),
        ..first
    })
}

/// The pair's `masks`: polygons of at least three points, each inside the lenses' frame and
/// within one lens's image (on one side of the line halfway between their centres, as
/// `Pair::side_at` tells them apart).
fn read_masks(f: &Fields, first: &LensEntry, second: &LensEntry) -> Result<Vec<Mask>, LensError> {
    let Some((polygons, _)) = f.get::<Vec<Vec<[f64; 2]>>>("masks")? else {
        return Ok(vec![]);
    };
    let (w, h) = (first.width as f64, first.height as f64);
    let (a, b) = (first.lens().affine.offset, second.lens().affine.offset);
    polygons
        .into_iter()
        .enumerate()
        .map(|(i, points)| {
            let bad = |why: &str| f.invalid("masks", format!("polygon {}: {why}", i + 1));
            if points.len() < 3 {
                return Err(bad("needs at least three points [x, y]"));
            }
            let points: Vec<DVec2> = points.into_iter().map(DVec2::from_array).collect();
            let outside =
                |p: &DVec2| !(p.is_finite() && p.x >= 0.0 && p.y >= 0.0 && p.x <= w && p.y <= h);
            if points.iter().any(outside) {
                return Err(bad(&format!("every point must lie in the {w}x{h} frame")));
            }
            let first_side = |p: &DVec2| (*p - (a + b) * 0.5).dot(b - a) <= 0.0;
            let on_first = points.iter().filter(|p| first_side(p)).count();
            if on_first != 0 && on_first != points.len() {
                return Err(bad(
                    "must lie within one lens's image (one half of the frame)",
                ));
            }
            Ok(Mask { points })
        })
        .collect()
}

/// The two lenses must share a frame (the pair's) and a model (the GPU draws one model a
/// frame), and between them see every direction.
fn check_lenses(f: &Fields, a: &LensEntry, b: &LensEntry) -> Result<(), LensError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(f.invalid(
            "lenses",
            format!(
                "`{}` is {}x{} and `{}` {}x{}: a pair's lenses map into one frame",
                a.name, a.width, a.height, b.name, b.width, b.height
            ),
        ));
    }
    if a.model.name() != b.model.name() || matches!(a.model, Model::Ocam(_)) {
        return Err(f.invalid(
            "lenses",
            format!(
                "`{}` is {} and `{}` {}: a pair's lenses share one model, any but ocam",
                a.name,
                a.model.name(),
                b.name,
                b.model.name()
            ),
        ));
    }
    if a.fov + b.fov < 2.0 * std::f64::consts::PI {
        return Err(f.invalid(
            "lenses",
            format!(
                "their fields of view add up to {:.1}deg: a pair must cover 360deg",
                (a.fov + b.fov).to_degrees()
            ),
        ));
    }
    Ok(())
}
