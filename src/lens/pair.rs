//! Two fisheyes back to back as one lens: the full sphere. A pair's [`Lens`] is its first
//! lens (its radial model and pixel mapping) with the second attached here; both images lie in
//! one frame (side by side, as dual-lens cameras stream them), so a pixel position says which
//! lens took it. Every ray is drawn from the lens that sees it best: the one it lies deeper
//! inside, by the margin to that lens's half field of view ([`Pair::project`]). Across the
//! overlap the two are blended (`render::stitch` writes the blend into the frame before
//! either renderer reads it), so the renderers only ever pick one lens per ray.
//!
//! The pair's frame is the first lens's: a ray there turns into the second lens's frame by
//! [`Pair::second_from_first`], the nominal back-to-back pose (a half turn about the image's
//! down axis, so both images stand upright) followed by the calibrated correction. What the
//! airframe hides from one lens is drawn from the other ([`mask`]).

use super::{Lens, PixelAffine, Radial};
use glam::{DQuat, DVec2, DVec3};
pub use mask::Mask;
use std::f64::consts::PI;

pub mod mask;

/// One lens of a pair, in the pair's frame of pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    pub radial: Radial,
    pub affine: PixelAffine,
    pub half_fov: f64,
}

impl Part {
    /// Where a ray in this lens's own frame lands; None outside its field of view.
    pub fn project(&self, ray: DVec3) -> Option<DVec2> {
        project_radial(&self.radial, &self.affine, self.half_fov, ray)
    }

    /// The unit ray in this lens's own frame through a pixel; None outside its field.
    pub fn unproject(&self, pixel: DVec2) -> Option<DVec3> {
        unproject_radial(&self.radial, &self.affine, self.half_fov, pixel)
    }

    /// How far inside this lens's field a ray in its own frame lies, radians (negative
    /// outside).
    pub fn margin(&self, ray: DVec3) -> f64 {
        self.half_fov - ray.x.hypot(ray.y).atan2(ray.z)
    }
}

/// Which lens of a pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    First,
    Second,
}

/// The second lens of a pair and how the two sit.
#[derive(Clone, Debug, PartialEq)]
pub struct Pair {
    pub first: Part,
    pub second: Part,
    /// Rotation of a ray from the first lens's frame into the second's.
    pub second_from_first: DQuat,
    /// The second lens's centre in the first's frame, metres. Not used to render: at the
    /// distances a drone sees, a few centimetres shift nothing by a pixel (docs/sphere.md).
    pub baseline: DVec3,
    /// Width of the blend across the seam, radians of margin difference.
    pub feather: f64,
    /// What the airframe hides, in frame pixels: drawn from the other lens.
    pub masks: Vec<Mask>,
}

/// The nominal back-to-back pose: the second lens looks the other way, turned a half turn
/// about the image's down axis so that both images stand upright.
pub fn back_to_back() -> DQuat {
    DQuat::from_rotation_y(PI)
}

/// The correction to the nominal pose, from three angles (radians): `roll` about the second
/// lens's optical axis (a twist of its image), then `pitch` about its x (right) axis and
/// `yaw` about its y (down) axis.
pub fn correction(roll: f64, pitch: f64, yaw: f64) -> DQuat {
    DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(pitch) * DQuat::from_rotation_z(roll)
}

impl Pair {
    /// The lens that sees a ray (pair frame) best, and by how much: the difference between
    /// the first's and the second's margins (positive where the first sees it deeper).
    pub fn best(&self, ray: DVec3) -> (Side, f64) {
        let d = self.first.margin(ray) - self.second.margin(self.second_from_first * ray);
        (if d >= 0.0 { Side::First } else { Side::Second }, d)
    }

    /// The first lens's share of a ray's colour: 1 deep in its field, 0 deep in the second's,
    /// a smooth step across `feather` around the seam.
    pub fn first_weight(&self, ray: DVec3) -> f64 {
        let (_, d) = self.best(ray);
        weight_of(d, self.feather)
    }

    /// Where a ray (pair frame) lands in the lens `side`; None where that lens does not see
    /// it.
    pub fn project_in(&self, side: Side, ray: DVec3) -> Option<DVec2> {
        match side {
            Side::First => self.first.project(ray),
            Side::Second => self.second.project(self.second_from_first * ray),
        }
    }

    /// Where a ray lands: in the lens that sees it best, else in the other if that sees it.
    pub fn project(&self, ray: DVec3) -> Option<DVec2> {
        let (side, _) = self.best(ray);
        self.project_in(side, ray)
            .or_else(|| self.project_in(other(side), ray))
    }

    /// The lens whose image holds a pixel position: the one whose centre is nearer along the
    /// line between the two centres (side by side, the frame's left or right half).
    pub fn side_at(&self, p: DVec2) -> Side {
        let (a, b) = (self.first.affine.offset, self.second.affine.offset);
        if (p - (a + b) * 0.5).dot(b - a) > 0.0 {
            Side::Second
        } else {
            Side::First
        }
    }

    /// The unit ray (pair frame) through a pixel, by the lens whose image holds it.
    pub fn unproject(&self, p: DVec2) -> Option<DVec3> {
        match self.side_at(p) {
            Side::First => self.first.unproject(p),
            Side::Second => Some(self.second_from_first.inverse() * self.second.unproject(p)?),
        }
    }

    /// The pair seen in a frame scaled by `scale` after cropping `origin` off (as
    /// [`PixelAffine::rescaled`]).
    pub fn rescaled(&self, scale: DVec2, origin: DVec2) -> Pair {
        let part = |p: &Part| Part {
            affine: p.affine.rescaled(scale, origin),
            ..p.clone()
        };
        Pair {
            first: part(&self.first),
            second: part(&self.second),
            masks: self
                .masks
                .iter()
                .map(|m| m.rescaled(scale, origin))
                .collect(),
            ..self.clone()
        }
    }

    /// The share of the other lens's colour that frame point `p` (in lens `side`'s image)
    /// takes for the airframe: what its masks say, easing in over the feather's width in that
    /// lens's pixels.
    pub fn masked(&self, side: Side, p: DVec2) -> f64 {
        let part = match side {
            Side::First => &self.first,
            Side::Second => &self.second,
        };
        mask::masked_share(&self.masks, p, self.feather * part.affine.mean_scale())
    }
}

/// The first lens's share at margin difference `d` across a feather of width `feather`: a
/// smooth step from 0 at -feather/2 to 1 at +feather/2 (a hard switch at 0 for no feather).
pub fn weight_of(d: f64, feather: f64) -> f64 {
    if feather <= 0.0 {
        return if d >= 0.0 { 1.0 } else { 0.0 };
    }
    let t = (d / feather + 0.5).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The other lens of a pair.
pub fn other(side: Side) -> Side {
    match side {
        Side::First => Side::Second,
        Side::Second => Side::First,
    }
}

/// [`Lens::project`] for any radial model and pixel mapping.
pub(super) fn project_radial(
    radial: &Radial,
    affine: &PixelAffine,
    half_fov: f64,
    ray: DVec3,
) -> Option<DVec2> {
    let rho = ray.x.hypot(ray.y);
    let theta = rho.atan2(ray.z);
    if theta.is_nan() || theta > half_fov + 1e-9 {
        return None;
    }
    let r = radial.r_of_theta(theta)?;
    let dir = if rho > 0.0 {
        DVec2::new(ray.x, ray.y) / rho
    } else {
        DVec2::ZERO
    };
    Some(affine.to_pixel(dir * r))
}

/// [`Lens::unproject`] for any radial model and pixel mapping.
pub(super) fn unproject_radial(
    radial: &Radial,
    affine: &PixelAffine,
    half_fov: f64,
    pixel: DVec2,
) -> Option<DVec3> {
    let m = affine.to_normalized(pixel);
    let r = m.length();
    let theta = radial.theta_of_r(r)?;
    if theta > half_fov + 1e-9 {
        return None;
    }
    let dir = if r > 0.0 { m / r } else { DVec2::ZERO };
    let (s, c) = theta.sin_cos();
    Some(DVec3::new(dir.x * s, dir.y * s, c))
}

impl Lens {
    /// Two lenses as one: `first`'s model and pixel mapping, `second` attached (both must map
    /// into the same frame). The pair sees the whole sphere.
    pub fn paired(first: &Lens, second: &Lens, name: &str, id: u8, pose: PairPose) -> Lens {
        let part = |l: &Lens| Part {
            radial: l.radial.clone(),
            affine: l.affine,
            half_fov: l.half_fov,
        };
        let pair = Pair {
            first: part(first),
            second: part(second),
            second_from_first: pose.correction * back_to_back(),
            baseline: pose.baseline,
            feather: pose.feather,
            masks: pose.masks,
        };
        Lens {
            name: name.to_string(),
            id,
            half_fov: PI,
            pair: Some(std::sync::Arc::new(pair)),
            ..first.clone()
        }
    }
}

/// How a pair's lenses sit and blend: lens.cal's `[[pair]]` fields.
#[derive(Clone, Debug, PartialEq)]
pub struct PairPose {
    /// The correction after the nominal back-to-back turn ([`correction`]).
    pub correction: DQuat,
    pub baseline: DVec3,
    pub feather: f64,
    pub masks: Vec<Mask>,
}

#[cfg(test)]
mod tests;
