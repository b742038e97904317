//! Lens models: where a ray in the fisheye lens frame lands in the fisheye image and back.
//!
//! First stop on the data path: every renderer, the protocol's angle queries and the scene
//! synthesiser call [`Lens::project`] and [`Lens::unproject`]. The lens frame is OpenCV's
//! (x right, y down, z along the optical axis) and pixel coordinates are OpenCV's too: the
//! centre of the top-left pixel is (0, 0).
//!
//! Every model here is rotationally symmetric about the optical axis in its own normalized
//! plane, so it is written as a radial function r(θ) with θ = atan2(ρ, z) the angle from the
//! axis (valid beyond 90°), followed by a 2×2 affine to pixels: diag(fx, fy) for the classic
//! models, OCam's (c, d, e) matrix for Scaramuzza's. One file per model holds the radial
//! part; `shaders/lens.wgsl` has a twin function of the same name for each.

pub mod calfile;
pub mod check;
pub mod double_sphere;
pub mod equidistant;
pub mod equisolid;
pub mod import;
pub mod kannala_brandt;
pub mod ocam;
pub mod orthographic;
pub mod samples;
pub mod solve;
pub mod stereographic;

pub use calfile::{LensCal, LensEntry, LensError, Provenance};

use glam::{DMat2, DVec2, DVec3};
use std::ops::Range;

/// The radial part of a lens model and its coefficients.
#[derive(Clone, Debug, PartialEq)]
pub enum Model {
    Equidistant,
    Equisolid,
    Stereographic,
    Orthographic,
    /// OpenCV fisheye coefficients k1..k4.
    KannalaBrandt {
        k: [f64; 4],
    },
    DoubleSphere {
        xi: f64,
        alpha: f64,
    },
    /// OCamCalib polynomials, lowest order first, in pixel units of the calibration frame.
    Ocam {
        pol: Vec<f64>,
        invpol: Vec<f64>,
    },
}

impl Model {
    pub fn name(&self) -> &'static str {
        match self {
            Model::Equidistant => "equidistant",
            Model::Equisolid => "equisolid",
            Model::Stereographic => "stereographic",
            Model::Orthographic => "orthographic",
            Model::KannalaBrandt { .. } => "kannala_brandt",
            Model::DoubleSphere { .. } => "double_sphere",
            Model::Ocam { .. } => "ocam",
        }
    }
}

/// Where the model itself stops being one-to-one: θ and the normalized radius there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelLimits {
    pub theta_max: f64,
    pub r_max: f64,
}

/// The radial model with its limits worked out once.
#[derive(Clone, Debug, PartialEq)]
pub struct Radial {
    pub model: Model,
    pub limits: ModelLimits,
}

/// How far out to look for an OCam polynomial's fold, in pixels.
const OCAM_SEARCH_RADIUS: f64 = 20_000.0;

impl Radial {
    pub fn new(model: Model) -> Self {
        let theta_max = match &model {
            Model::Equidistant => equidistant::MAX_THETA,
            Model::Equisolid => equisolid::MAX_THETA,
            Model::Stereographic => stereographic::MAX_THETA,
            Model::Orthographic => orthographic::MAX_THETA,
            Model::KannalaBrandt { k } => kannala_brandt::max_theta(k),
            Model::DoubleSphere { xi, alpha } => double_sphere::max_theta(*xi, *alpha),
            Model::Ocam { pol, .. } => {
                // OCam's limit is found in r; θ follows from it (the fold search runs once).
                let r_max = ocam::max_radius(pol, OCAM_SEARCH_RADIUS);
                let theta_max = ocam::theta_of_r(pol, r_max);
                return Radial {
                    model,
                    limits: ModelLimits { theta_max, r_max },
                };
            }
        };
        let mut radial = Radial {
            model,
            limits: ModelLimits {
                theta_max,
                r_max: f64::INFINITY,
            },
        };
        radial.limits.r_max = radial.r_of_theta(theta_max).unwrap_or(f64::INFINITY);
        radial
    }

    /// Normalized radius for a ray at angle θ from the axis; None beyond the model's limit.
    pub fn r_of_theta(&self, theta: f64) -> Option<f64> {
        if !(0.0..=self.limits.theta_max + 1e-12).contains(&theta) {
            return None;
        }
        match &self.model {
            Model::Equidistant => Some(equidistant::r_of_theta(theta)),
            Model::Equisolid => Some(equisolid::r_of_theta(theta)),
            Model::Stereographic => Some(stereographic::r_of_theta(theta)),
            Model::Orthographic => Some(orthographic::r_of_theta(theta)),
            Model::KannalaBrandt { k } => Some(kannala_brandt::r_of_theta(k, theta)),
            Model::DoubleSphere { xi, alpha } => double_sphere::r_of_theta(*xi, *alpha, theta),
            Model::Ocam { pol, invpol } => ocam::r_of_theta(pol, invpol, self.limits.r_max, theta),
        }
    }

    /// Angle from the axis for a normalized radius; None beyond the model's limit.
    pub fn theta_of_r(&self, r: f64) -> Option<f64> {
        if !(0.0..=self.limits.r_max * (1.0 + 1e-12)).contains(&r) {
            return None;
        }
        match &self.model {
            Model::Equidistant => equidistant::theta_of_r(r),
            Model::Equisolid => equisolid::theta_of_r(r),
            Model::Stereographic => stereographic::theta_of_r(r),
            Model::Orthographic => orthographic::theta_of_r(r),
            Model::KannalaBrandt { k } => kannala_brandt::theta_of_r(k, self.limits.theta_max, r),
            Model::DoubleSphere { xi, alpha } => double_sphere::theta_of_r(*xi, *alpha, r),
            Model::Ocam { pol, .. } => Some(ocam::theta_of_r(pol, r)),
        }
    }
}

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
    /// Half of the valid field of view: rays further than this from the axis are not imaged.
    pub half_fov: f64,
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
        }
    }

    /// Pixel where a lens-frame ray lands; None outside the valid field of view.
    pub fn project(&self, ray: DVec3) -> Option<DVec2> {
        let rho = ray.x.hypot(ray.y);
        let theta = rho.atan2(ray.z);
        if theta.is_nan() || theta > self.half_fov + 1e-9 {
            return None;
        }
        let r = self.radial.r_of_theta(theta)?;
        let dir = if rho > 0.0 {
            DVec2::new(ray.x, ray.y) / rho
        } else {
            DVec2::ZERO
        };
        Some(self.affine.to_pixel(dir * r))
    }

    /// Unit lens-frame ray through a pixel; None outside the valid field of view.
    pub fn unproject(&self, pixel: DVec2) -> Option<DVec3> {
        let m = self.affine.to_normalized(pixel);
        let r = m.length();
        let theta = self.radial.theta_of_r(r)?;
        if theta > self.half_fov + 1e-9 {
            return None;
        }
        let dir = if r > 0.0 { m / r } else { DVec2::ZERO };
        let (s, c) = theta.sin_cos();
        Some(DVec3::new(dir.x * s, dir.y * s, c))
    }

    /// Radius of the image circle in pixels (mean over both axes).
    pub fn circle_radius(&self) -> f64 {
        self.radial.r_of_theta(self.half_fov).unwrap_or(0.0) * self.affine.mean_scale()
    }

    /// The part of the frame the lens can image: the image circle's bounding box (an ellipse's,
    /// through the affine) widened by [`IMAGED_MARGIN`], rounded out to multiples of
    /// [`IMAGED_ALIGN`] and clipped to the frame, as column and row ranges. Both renderers
    /// take every pixel outside it as black, and the GPU never converts those pixels.
    pub fn imaged_box(&self) -> (Range<u32>, Range<u32>) {
        let Some(r) = self
            .radial
            .r_of_theta(self.half_fov)
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
        Lens {
            affine: self.affine.rescaled(scale, DVec2::new(roi.x, roi.y)),
            width,
            height,
            ..self.clone()
        }
    }
}

#[cfg(test)]
mod tests;
