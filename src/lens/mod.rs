//! Lens models: where a ray in the fisheye lens frame lands in the fisheye image and back.
//!
//! First stop on the data path: every renderer, the protocol's angle queries and the scene
//! synthesiser call [`Lens::project`] and [`Lens::unproject`]. The lens frame is OpenCV's
//! (x right, y down, z along the optical axis) and pixel coordinates are OpenCV's too: the
//! centre of the top-left pixel is (0, 0).
//!
//! A lens is a radial model r(θ) (`models`: one file per model, each with a WGSL twin of the
//! same name in shaders/lens.wgsl, and the registry that names them) followed by a 2×2 affine
//! to pixels: diag(fx, fy) for the classic models, OCam's (c, d, e) matrix for Scaramuzza's.
//! `calfile` reads and writes lens.cal, `import` other tools' calibrations, `calibrate` makes
//! them from pictures of a board, `check` tests an entry, and [`Lenses`] looks a state's lens
//! up. `pair` makes two fisheyes back to back one lens that sees the whole sphere, and
//! `pair_fit` measures how the two sit.

pub mod calfile;
pub mod calibrate;
pub mod check;
pub mod import;
pub mod models;
pub mod pair;
pub mod pair_fit;
pub mod samples;

pub use calfile::{LensCal, LensEntry, LensError, Provenance};
pub use models::{Model, ModelLimits, Radial, RadialModel};
pub use pair::{Pair, PairPose, Side};

use glam::{DMat2, DVec2, DVec3};
use std::ops::Range;

/// Normalized plane → pixels: pixel = matrix · (mx, my) + offset, with (mx, my) along the lens
/// frame's x (right) and y (down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelAffine {
    pub matrix: DMat2,
    pub offset: DVec2,
}

impl PixelAffine {
    pub fn pinhole(fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        PixelAffine {
            matrix: DMat2::from_cols(DVec2::new(fx, 0.0), DVec2::new(0.0, fy)),
            offset: DVec2::new(cx, cy),
        }
    }

    /// OCamCalib's affine: row = c·xp + d·yp + xc, col = e·xp + yp + yc, where xp runs along
    /// rows (our y) and yp along columns (our x).
    pub fn ocam(c: f64, d: f64, e: f64, xc: f64, yc: f64) -> Self {
        // u (col) = 1·mx + e·my + yc ; v (row) = d·mx + c·my + xc
        PixelAffine {
            matrix: DMat2::from_cols(DVec2::new(1.0, d), DVec2::new(e, c)),
            offset: DVec2::new(yc, xc),
        }
    }

    pub fn to_pixel(&self, m: DVec2) -> DVec2 {
        self.matrix * m + self.offset
    }

    pub fn to_normalized(&self, p: DVec2) -> DVec2 {
        self.matrix.inverse() * (p - self.offset)
    }

    /// The same lens seen in a frame scaled by `scale` after cropping `roi_origin` off the
    /// calibration frame; pixel centres stay pixel centres.
    pub fn rescaled(&self, scale: DVec2, roi_origin: DVec2) -> Self {
        let s = DMat2::from_diagonal(scale);
        PixelAffine {
            matrix: s * self.matrix,
            offset: (self.offset - roi_origin + DVec2::splat(0.5)) * scale - DVec2::splat(0.5),
        }
    }

    /// Mean pixels per normalized unit, for sizes and filter footprints.
    pub fn mean_scale(&self) -> f64 {
        self.matrix.determinant().abs().sqrt()
    }
}

/// The bit of [`Lens::shader_model`] that says the lens is a pair (PAIR_BIT in
/// shaders/lens.wgsl).
pub const PAIR_BIT: u32 = 256;

/// How far past the frame's edge (pixels) a position still counts as inside: positions that
/// land exactly on the edge (the debug view's outer rows do) must not depend on rounding, and
/// the GPU computes them in f32.
pub const FRAME_EDGE_SLACK: f64 = 0.001;

/// How far (pixels) around the image circle's bounding box the frame still counts as imaged
/// (see [`Lens::imaged_box`]): the rim's trilinear samples see their real neighbourhood up to
/// mip level 3.
pub const IMAGED_MARGIN: f64 = 16.0;
/// [`Lens::imaged_box`] is rounded out to multiples of this many pixels: whole 4:2:0 blocks,
/// whole 16x4 blocks of the GPU's ingest and whole words of every plane's first mip levels.
pub const IMAGED_ALIGN: u32 = 32;

/// A sensor crop: the part of the calibration frame the camera delivers, in calibration pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roi {
    pub x: f64,
    pub y: f64,
    pub width: f64,
    pub height: f64,
}

/// A calibrated lens as seen in one frame size: what the renderers use.
#[derive(Clone, Debug, PartialEq)]
pub struct Lens {
    pub name: String,
    pub id: u8,
    pub radial: Radial,
    pub affine: PixelAffine,
    /// The frame these pixel coordinates refer to.
    pub width: u32,
    pub height: u32,
    /// Half of the valid field of view: rays further than this from the axis are not imaged
    /// (π for a pair: it sees everything).
    pub half_fov: f64,
    /// For two lenses back to back, the second and how the two sit (`pair`); the fields
    /// above are then the first lens's, but for the name, id and field of view.
    pub pair: Option<std::sync::Arc<Pair>>,
}

impl Lens {
    pub fn new(
        name: &str,
        id: u8,
        model: Model,
        affine: PixelAffine,
        size: (u32, u32),
        fov: f64,
    ) -> Self {
        let radial = Radial::new(model);
        let half_fov = (fov / 2.0).min(radial.limits.theta_max);
        Lens {
            name: name.to_string(),
            id,
            radial,
            affine,
            width: size.0,
            height: size.1,
            half_fov,
            pair: None,
        }
    }

    /// Pixel where a lens-frame ray lands; None outside the valid field of view. A pair
    /// draws each ray from the lens that sees it best ([`Pair::project`]).
    pub fn project(&self, ray: DVec3) -> Option<DVec2> {
        match &self.pair {
            Some(pair) => pair.project(ray),
            None => pair::project_radial(&self.radial, &self.affine, self.half_fov, ray),
        }
    }

    /// Unit lens-frame ray through a pixel; None outside the valid field of view.
    pub fn unproject(&self, pixel: DVec2) -> Option<DVec3> {
        match &self.pair {
            Some(pair) => pair.unproject(pixel),
            None => pair::unproject_radial(&self.radial, &self.affine, self.half_fov, pixel),
        }
    }

    /// The code the GPU's pipelines are built for: the model's (`Model::code`), with
    /// [`PAIR_BIT`] for a pair (whose code the single lenses' pipelines leave out).
    pub fn shader_model(&self) -> u32 {
        self.radial.model.code() | if self.pair.is_some() { PAIR_BIT } else { 0 }
    }

    /// Whether two pixel positions lie in the same lens's image (always, but for a pair).
    pub fn same_image(&self, a: DVec2, b: DVec2) -> bool {
        self.pair
            .as_ref()
            .is_none_or(|p| p.side_at(a) == p.side_at(b))
    }

    /// The horizontal field of view, radians: between the rays through the middles of the
    /// frame's left and right edges (the whole field where those lie outside it).
    pub fn hfov(&self) -> f64 {
        if self.pair.is_some() {
            return 2.0 * std::f64::consts::PI;
        }
        let y = self.height as f64 / 2.0;
        let edge = |x: f64| self.unproject(DVec2::new(x, y));
        match (edge(0.0), edge(self.width as f64)) {
            (Some(a), Some(b)) => a.angle_between(b),
            _ => 2.0 * self.half_fov,
        }
    }

    /// Radius of the image circle in pixels (mean over both axes).
    pub fn circle_radius(&self) -> f64 {
        let half_fov = self
            .pair
            .as_ref()
            .map_or(self.half_fov, |p| p.first.half_fov);
        self.radial.r_of_theta(half_fov).unwrap_or(0.0) * self.affine.mean_scale()
    }

    /// The part of the frame the lens can image: the image circle's bounding box (an ellipse's,
    /// through the affine) widened by [`IMAGED_MARGIN`], rounded out to multiples of
    /// [`IMAGED_ALIGN`] and clipped to the frame, as column and row ranges. Both renderers
    /// take every pixel outside it as black, and the GPU never converts those pixels.
    pub fn imaged_box(&self) -> (Range<u32>, Range<u32>) {
        // A pair's two images fill their frame between them.
        let Some(r) = (self.pair.is_none())
            .then(|| self.radial.r_of_theta(self.half_fov))
            .flatten()
            .filter(|r| r.is_finite())
        else {
            return (0..self.width, 0..self.height);
        };
        let m = self.affine.matrix;
        let half = DVec2::new(m.x_axis.x.hypot(m.y_axis.x), m.x_axis.y.hypot(m.y_axis.y)) * r
            + IMAGED_MARGIN;
        let (lo, hi) = (self.affine.offset - half, self.affine.offset + half);
        let span = |lo: f64, hi: f64, size: u32| {
            let start = (lo.floor().max(0.0) as u32) / IMAGED_ALIGN * IMAGED_ALIGN;
            let end = (hi.ceil().max(0.0) as u32 + 1)
                .next_multiple_of(IMAGED_ALIGN)
                .min(size);
            start.min(end)..end
        };
        (span(lo.x, hi.x, self.width), span(lo.y, hi.y, self.height))
    }

    /// Where the optical axis meets the image.
    pub fn centre(&self) -> DVec2 {
        self.affine.offset
    }

    pub fn fov(&self) -> f64 {
        2.0 * self.half_fov
    }

    /// Pixels per radian at angle θ from the axis, radially: how fine the fisheye samples there.
    pub fn pixels_per_radian(&self, theta: f64) -> f64 {
        let h = 1e-5;
        let (a, b) = (
            (theta - h).max(0.0),
            (theta + h).min(self.radial.limits.theta_max),
        );
        match (self.radial.r_of_theta(a), self.radial.r_of_theta(b)) {
            (Some(ra), Some(rb)) if b > a => (rb - ra) / (b - a) * self.affine.mean_scale(),
            _ => self.affine.mean_scale(),
        }
    }

    /// Whether a pixel position lies inside the frame (pixel centres 0..w-1 plus half a pixel,
    /// plus [`FRAME_EDGE_SLACK`]).
    pub fn in_frame(&self, p: DVec2) -> bool {
        let (lo, hi) = (-0.5 - FRAME_EDGE_SLACK, -0.5 + FRAME_EDGE_SLACK);
        p.x >= lo && p.y >= lo && p.x <= self.width as f64 + hi && p.y <= self.height as f64 + hi
    }

    /// Whether a `width` × `height` frame, after the sensor crop `roi`, can be seen through
    /// this lens: any, but for a pair, whose two images come side by side in a frame of its own
    /// shape (within a pixel), unless a crop says which part of the frame that is.
    pub fn fits(&self, width: u32, height: u32, roi: Option<Roi>) -> Result<(), LensError> {
        let (w, h) = (width as u64, height as u64);
        let (lw, lh) = (self.width as u64, self.height as u64);
        if self.pair.is_some() && roi.is_none() && (w * lh).abs_diff(h * lw) > lh {
            return Err(LensError::PairShape {
                name: self.name.clone(),
                lens: (self.width, self.height),
                frame: (width, height),
            });
        }
        Ok(())
    }

    /// The same lens for a frame of another size, optionally after a sensor crop (ROI given in
    /// pixels of this lens's frame). The field of view is unchanged: only the pixel mapping moves.
    pub fn for_frame(&self, width: u32, height: u32, roi: Option<Roi>) -> Lens {
        let roi = roi.unwrap_or(Roi {
            x: 0.0,
            y: 0.0,
            width: self.width as f64,
            height: self.height as f64,
        });
        let scale = DVec2::new(width as f64 / roi.width, height as f64 / roi.height);
        let origin = DVec2::new(roi.x, roi.y);
        Lens {
            affine: self.affine.rescaled(scale, origin),
            width,
            height,
            pair: self
                .pair
                .as_ref()
                .map(|p| std::sync::Arc::new(p.rescaled(scale, origin))),
            ..self.clone()
        }
    }
}

/// Every lens of a lens.cal, at its calibration frame, by lens_id: the one place a state's
/// `lens` is looked up.
#[derive(Clone, Debug)]
pub struct Lenses {
    path: std::path::PathBuf,
    lenses: Vec<Lens>,
}

impl Lenses {
    pub fn new(cal: &LensCal) -> Lenses {
        Lenses {
            path: cal.path.clone(),
            lenses: cal.entries.iter().map(LensEntry::lens).collect(),
        }
    }

    /// The lens `id` at its calibration frame.
    pub fn get(&self, id: u8) -> Option<&Lens> {
        self.lenses.iter().find(|l| l.id == id)
    }

    /// The lens called `name` at its calibration frame.
    pub fn named(&self, name: &str) -> Option<&Lens> {
        self.lenses.iter().find(|l| l.name == name)
    }

    /// Every lens's id and name, in lens.cal's order.
    pub fn names(&self) -> Vec<(u8, String)> {
        self.lenses.iter().map(|l| (l.id, l.name.clone())).collect()
    }

    /// Every lens, in lens.cal's order.
    pub fn all(&self) -> impl Iterator<Item = &Lens> {
        self.lenses.iter()
    }

    /// The lens `id` as a `width` × `height` frame (a source's actual size) sees it, after
    /// the sensor crop `roi`.
    pub fn for_frame(
        &self,
        id: u8,
        (width, height): (u32, u32),
        roi: Option<Roi>,
    ) -> Result<Lens, LensError> {
        let lens = self.get(id).ok_or_else(|| LensError::NoSuchId {
            path: self.path.clone(),
            id,
        })?;
        lens.fits(width, height, roi)?;
        Ok(lens.for_frame(width, height, roi))
    }
}

#[cfg(test)]
mod tests;
