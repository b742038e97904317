//! Calibrating a lens from pictures of a board: the board itself (`board`: its geometry, its
//! picture to print, its shade for the synthetic scene), finding it in frames (`detect`), and
//! fitting a lens to the corners found (`fit`) over a well-spread choice of frames (`select`).
//! Off the frame path: this produces lens.cal entries, which the renderers then use.

pub mod board;
pub mod detect;
pub mod fit;
pub mod select;

pub use board::{Board, BoardError};
pub use detect::{Finder, Sighting};

use crate::lens::import::widest_angle;
use crate::lens::{LensCal, LensEntry, LensError, PixelAffine, Provenance, Radial};
use glam::DVec2;

/// The lens.cal entry for a fit: its model, marked `calibrated` with the date and RMS,
/// valid over `fov` (by default the widest angle the frame shows).
pub fn entry(
    got: &fit::Fit,
    name: &str,
    lens_id: u8,
    (width, height): (u32, u32),
    fov: Option<f64>,
    date: &str,
    source: String,
) -> Result<LensEntry, LensError> {
    let model = got.model.clone();
    let affine = PixelAffine::pinhole(got.fx, got.fy, got.cx, got.cy);
    let fov = fov
        .unwrap_or_else(|| 2.0 * widest_angle(&Radial::new(model.clone()), &affine, width, height));
    let entry = LensEntry {
        name: name.to_string(),
        lens_id,
        model,
        affine,
        width,
        height,
        fov,
        circle_radius: None,
        provenance: Provenance {
            kind: "calibrated".into(),
            by: "digiview lens calibrate".into(),
            date: date.to_string(),
            source,
            assumption: String::new(),
            rms_px: Some((got.rms * 1000.0).round() / 1000.0),
        },
        line: 0,
        pair: None,
    };
    // Through the text form, so the entry is exactly what lens.cal will hold.
    let cal = LensCal::parse(std::path::Path::new("(calibrated)"), &entry.to_toml())?;
    Ok(cal.entries.into_iter().next().expect("one entry"))
}

/// Sectors of the image circle, 45° of azimuth each, in three rings (the inner third, the
/// middle third and the outer third of the valid half field of view).
pub const SECTORS: usize = 8;
pub const RINGS: usize = 3;

/// Which ring × sector cells of the circle the corners fall in, by the fitted lens, and the
/// widest angle from the axis they reach. Cells the frame does not show count as covered.
pub fn coverage(lens: &crate::lens::Lens, corners: &[DVec2]) -> ([[bool; SECTORS]; RINGS], f64) {
    let cell = |theta: f64, phi: f64| {
        let ring = ((theta / lens.half_fov) * RINGS as f64).min(RINGS as f64 - 1.0) as usize;
        let sector = (phi.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU
            * SECTORS as f64) as usize
            % SECTORS;
        (ring, sector)
    };
    let mut covered = [[false; SECTORS]; RINGS];
    // Cells whose middle the frame does not show cannot be covered, and are not asked for.
    for (r, row) in covered.iter_mut().enumerate() {
        for (s, flag) in row.iter_mut().enumerate() {
            let theta = (r as f64 + 0.5) / RINGS as f64 * lens.half_fov;
            let phi = (s as f64 + 0.5) / SECTORS as f64 * std::f64::consts::TAU;
            let ray = glam::DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            *flag = !lens.project(ray).is_some_and(|q| lens.in_frame(q));
        }
    }
    let mut widest: f64 = 0.0;
    for q in corners {
        let Some(ray) = lens.unproject(*q) else {
            continue;
        };
        let theta = ray.truncate().length().atan2(ray.z);
        widest = widest.max(theta);
        let (r, s) = cell(theta, ray.y.atan2(ray.x));
        covered[r][s] = true;
    }
    (covered, widest)
}
