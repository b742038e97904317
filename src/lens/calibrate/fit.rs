//! Fitting a lens to the board's sightings: the intrinsics of Kannala-Brandt (fx, fy, cx, cy
//! and k1..k4, as OpenCV's fisheye module and Kalibr's "equidistant") or of the Double Sphere
//! model (fx, fy, cx, cy, ξ and α, as Basalt and Kalibr's "ds") and each frame's board pose,
//! by Levenberg-Marquardt on the corners' reprojection error (the `levenberg-marquardt`
//! crate). A start comes from an equidistant lens whose focal length is searched, each pose
//! from the homography between the board and the corners' rays; corners far off the fit are
//! dropped and the fit run again.

use super::detect::Sighting;
use crate::lens::models::{DoubleSphere, KannalaBrandt};
use crate::lens::{Lens, Model, PixelAffine};
use glam::{DMat3, DQuat, DVec2, DVec3};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

/// The models a lens can be fitted with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FitModel {
    #[default]
    KannalaBrandt,
    DoubleSphere,
}

/// A model name the fit does not know.
#[derive(Debug, thiserror::Error)]
#[error("`{0}`: the fit knows kannala_brandt and double_sphere")]
pub struct UnknownModel(String);

impl std::str::FromStr for FitModel {
    type Err = UnknownModel;

    fn from_str(text: &str) -> Result<FitModel, UnknownModel> {
        match text.trim().replace('-', "_").as_str() {
            "kannala_brandt" => Ok(FitModel::KannalaBrandt),
            "double_sphere" => Ok(FitModel::DoubleSphere),
            _ => Err(UnknownModel(text.to_string())),
        }
    }
}

impl FitModel {
    /// fx, fy, cx, cy and the model's own coefficients.
    fn intrinsics(self) -> usize {
        match self {
            FitModel::KannalaBrandt => 8,
            FitModel::DoubleSphere => 6,
        }
    }

    /// The model's coefficients that start it as close to an equidistant lens of the same
    /// focal length as it comes: KB's k = 0 is one; Double Sphere with ξ = 0 and α = 2/π
    /// meets it at the axis and at 90°.
    fn start(self) -> Vec<f64> {
        match self {
            FitModel::KannalaBrandt => vec![0.0; 4],
            FitModel::DoubleSphere => vec![0.0, std::f64::consts::FRAC_2_PI],
        }
    }

    /// The lens model with the intrinsics `p`.
    pub fn model(self, p: &[f64]) -> Model {
        match self {
            FitModel::KannalaBrandt => Model::KannalaBrandt(KannalaBrandt {
                k: [p[4], p[5], p[6], p[7]],
            }),
            FitModel::DoubleSphere => Model::DoubleSphere(DoubleSphere {
                xi: p[4],
                alpha: p[5],
            }),
        }
    }

    /// Projection of a lens-frame point with intrinsics `p`: None beyond the model's reach.
    fn project(self, p: &[f64], x: DVec3) -> Option<DVec2> {
        let m = match self {
            FitModel::KannalaBrandt => kannala_brandt(&p[4..8], x)?,
            FitModel::DoubleSphere => double_sphere(p[4], p[5], x)?,
        };
        Some(DVec2::new(p[0] * m.x + p[2], p[1] * m.y + p[3]))
    }
}

/// Kannala-Brandt's normalized image point: r(θ) = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸).
fn kannala_brandt(k: &[f64], x: DVec3) -> Option<DVec2> {
    let rho = x.x.hypot(x.y);
    let theta = rho.atan2(x.z);
    let t2 = theta * theta;
    let r = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
    if !r.is_finite() {
        return None;
    }
    Some(if rho > 1e-12 {
        DVec2::new(x.x, x.y) * (r / rho)
    } else {
        DVec2::ZERO
    })
}

/// Double Sphere's normalized image point (Usenko et al. 2018, eqs. 40-43), None where the
/// model does not project (α outside [0, 1] included).
fn double_sphere(xi: f64, alpha: f64, x: DVec3) -> Option<DVec2> {
    if !(0.0..=1.0).contains(&alpha) {
        return None;
    }
    let d1 = x.length();
    let zx = xi * d1 + x.z;
    let d2 = (x.x * x.x + x.y * x.y + zx * zx).sqrt();
    let w1 = if alpha <= 0.5 {
        alpha / (1.0 - alpha)
    } else {
        (1.0 - alpha) / alpha
    };
    let w2 = (w1 + xi) / (2.0 * w1 * xi + xi * xi + 1.0).sqrt();
    let denom = alpha * d2 + (1.0 - alpha) * zx;
    (x.z > -w2 * d1 && denom > 1e-12).then(|| DVec2::new(x.x, x.y) / denom)
}

/// Per frame: rotation vector (3) and translation (3).
const POSE: usize = 6;
/// A board pose: lens_from_board rotation, and the board's origin in the lens frame.
pub type Pose = (DMat3, DVec3);

/// A corner further than this many times the RMS (and at least [`MIN_OUTLIER`] px) off the
/// first fit is left out of the second.
const OUTLIER_RMS: f64 = 4.0;
const MIN_OUTLIER: f64 = 1.0;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("{0} frames with the board: at least {1} are needed")]
    TooFewFrames(usize, usize),
    #[error("no starting point fits the corners: is the board spec right (tag size, rows, cols)?")]
    NoStart,
    #[error("the fit did not converge: {0}")]
    Diverged(String),
}

/// One frame's corners: board points (metres) and image points (pixels).
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub board: Vec<DVec2>,
    pub image: Vec<DVec2>,
}

impl Frame {
    pub fn from_sightings(sightings: &[Sighting]) -> Frame {
        let mut f = Frame::default();
        for s in sightings {
            f.board.extend(s.board);
            f.image.extend(s.image);
        }
        f
    }
}

/// The fitted lens and how well it fits.
#[derive(Clone, Debug)]
pub struct Fit {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// The model with its fitted coefficients.
    pub model: Model,
    /// Each frame's board pose: lens_from_board rotation and the board origin in the lens frame.
    pub poses: Vec<Pose>,
    /// Reprojection error over the corners kept, pixels: root mean square and worst.
    pub rms: f64,
    pub worst: f64,
    /// Corners kept, and left out as outliers.
    pub kept: usize,
    pub dropped: usize,
}

impl Fit {
    /// The fitted lens in a `width` × `height` frame, valid over `fov`.
    pub fn lens(&self, name: &str, id: u8, size: (u32, u32), fov: f64) -> Lens {
        Lens::new(
            name,
            id,
            self.model.clone(),
            PixelAffine::pinhole(self.fx, self.fy, self.cx, self.cy),
            size,
            fov,
        )
    }
}

fn pose_of(p: &[f64]) -> Pose {
    let rotation = DMat3::from_quat(DQuat::from_scaled_axis(DVec3::new(p[0], p[1], p[2])));
    (rotation, DVec3::new(p[3], p[4], p[5]))
}

/// The least-squares problem: every kept corner of every frame.
struct Problem<'a> {
    model: FitModel,
    frames: &'a [Frame],
    /// Per frame, which corners count.
    keep: Vec<Vec<bool>>,
    params: DVector<f64>,
    /// Each frame's first residual row.
    rows: Vec<usize>,
    total: usize,
}

impl<'a> Problem<'a> {
    fn new(
        model: FitModel,
        frames: &'a [Frame],
        keep: Vec<Vec<bool>>,
        params: DVector<f64>,
    ) -> Problem<'a> {
        let mut rows = vec![];
        let mut total = 0;
        for k in &keep {
            rows.push(total);
            total += 2 * k.iter().filter(|&&b| b).count();
        }
        Problem {
            model,
            frames,
            keep,
            params,
            rows,
            total,
        }
    }

    /// Frame `i`'s residuals (image minus projection) into `out`, with parameters `p`.
    fn frame_residuals(&self, p: &[f64], i: usize, out: &mut [f64]) {
        let (rotation, t) = pose_of(&p[self.model.intrinsics() + POSE * i..]);
        let f = &self.frames[i];
        let mut row = 0;
        for (j, (b, img)) in f.board.iter().zip(&f.image).enumerate() {
            if !self.keep[i][j] {
                continue;
            }
            let d = match self.model.project(p, rotation * b.extend(0.0) + t) {
                Some(q) => q - *img,
                None => DVec2::splat(1e3),
            };
            out[row] = d.x;
            out[row + 1] = d.y;
            row += 2;
        }
    }

    fn all_residuals(&self, p: &[f64]) -> DVector<f64> {
        let mut r = DVector::zeros(self.total);
        for i in 0..self.frames.len() {
            let (start, end) = (self.rows[i], self.end(i));
            self.frame_residuals(p, i, &mut r.as_mut_slice()[start..end]);
        }
        r
    }

    fn end(&self, i: usize) -> usize {
        self.rows.get(i + 1).copied().unwrap_or(self.total)
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.params.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(self.all_residuals(self.params.as_slice()))
    }

    /// Central differences; a pose moves only its own frame's rows.
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let n = self.params.len();
        let intrinsics = self.model.intrinsics();
        let mut jac = DMatrix::zeros(self.total, n);
        let mut p = self.params.as_slice().to_vec();
        for col in 0..n {
            let h = 1e-6 * p[col].abs().max(1e-2);
            let frames = if col < intrinsics {
                0..self.frames.len()
            } else {
                let i = (col - intrinsics) / POSE;
                i..i + 1
            };
            for i in frames {
                let (start, end) = (self.rows[i], self.end(i));
                let mut plus = vec![0.0; end - start];
                let mut minus = vec![0.0; end - start];
                let keep = p[col];
                p[col] = keep + h;
                self.frame_residuals(&p, i, &mut plus);
                p[col] = keep - h;
                self.frame_residuals(&p, i, &mut minus);
                p[col] = keep;
                for (row, (a, b)) in plus.iter().zip(&minus).enumerate() {
                    jac[(start + row, col)] = (a - b) / (2.0 * h);
                }
            }
        }
        Some(jac)
    }
}

/// The ray an equidistant lens of focal length `f` centred at `c` sees at pixel `q`.
fn equidistant_ray(q: DVec2, f: f64, c: DVec2) -> DVec3 {
    let m = (q - c) / f;
    let theta = m.length();
    if theta < 1e-12 {
        return DVec3::Z;
    }
    (m / theta * theta.sin()).extend(theta.cos())
}

/// A board pose from its points' rays: the homography board plane → rays (u × H·p = 0, by
/// the smallest eigenvector of AᵀA), split into rotation and translation.
fn pose_from_rays(board: &[DVec2], rays: &[DVec3]) -> Option<Pose> {
    if board.len() < 4 {
        return None;
    }
    let mut ata = DMatrix::<f64>::zeros(9, 9);
    for (b, u) in board.iter().zip(rays) {
        let p = [b.x, b.y, 1.0];
        let mut r1 = [0.0; 9];
        let mut r2 = [0.0; 9];
        for k in 0..3 {
            // u_y (h3·p) − u_z (h2·p) and u_z (h1·p) − u_x (h3·p)
            r1[6 + k] = u.y * p[k];
            r1[3 + k] = -u.z * p[k];
            r2[k] = u.z * p[k];
            r2[6 + k] = -u.x * p[k];
        }
        for row in [r1, r2] {
            for i in 0..9 {
                for j in 0..9 {
                    ata[(i, j)] += row[i] * row[j];
                }
            }
        }
    }
    let eigen = ata.symmetric_eigen();
    let (smallest, _) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let h = eigen.eigenvectors.column(smallest);
    let col = |k: usize| DVec3::new(h[k], h[3 + k], h[6 + k]);
    let (mut h1, mut h2, mut h3) = (col(0), col(1), col(2));
    let scale = 2.0 / (h1.length() + h2.length());
    // The rays point at the board: the first point's H·p along its ray.
    let first = h1 * board[0].x + h2 * board[0].y + h3;
    let sign = if first.dot(rays[0]) < 0.0 { -1.0 } else { 1.0 };
    (h1, h2, h3) = (h1 * scale * sign, h2 * scale * sign, h3 * scale * sign);
    let r1 = h1.try_normalize()?;
    let r2 = (h2 - r1 * r1.dot(h2)).try_normalize()?;
    Some((DMat3::from_cols(r1, r2, r1.cross(r2)), h3))
}

/// Equidistant start: the focal length (searched over a range) whose per-frame poses fit
/// the corners best, and those poses, with `model`'s coefficients nearest equidistant.
fn start(model: FitModel, frames: &[Frame], size: (u32, u32)) -> Option<(DVector<f64>, f64)> {
    let c = DVec2::new(size.0 as f64 - 1.0, size.1 as f64 - 1.0) / 2.0;
    // A 180° circle as wide as the frame's short side, and from half to four times that.
    let nominal = size.0.min(size.1) as f64 / 2.0 / std::f64::consts::FRAC_PI_2;
    let mut best: Option<(f64, f64, Vec<Pose>)> = None;
    for step in 0..=40 {
        let f = nominal * 0.5 * 8f64.powf(step as f64 / 40.0);
        let p = [f, f, c.x, c.y, 0.0, 0.0, 0.0, 0.0];
        let mut errors = vec![];
        let mut poses = vec![];
        for frame in frames {
            let rays: Vec<DVec3> = frame
                .image
                .iter()
                .map(|q| equidistant_ray(*q, f, c))
                .collect();
            let Some((r, t)) = pose_from_rays(&frame.board, &rays) else {
                errors.push(f64::INFINITY);
                poses.push((DMat3::IDENTITY, DVec3::Z));
                continue;
            };
            let e: f64 = frame
                .board
                .iter()
                .zip(&frame.image)
                .map(|(b, q)| {
                    FitModel::KannalaBrandt
                        .project(&p, r * b.extend(0.0) + t)
                        .map_or(1e3, |x| x.distance(*q))
                })
                .sum::<f64>()
                / frame.board.len() as f64;
            errors.push(e);
            poses.push((r, t));
        }
        errors.sort_by(f64::total_cmp);
        let median = errors[errors.len() / 2];
        if median.is_finite() && best.as_ref().is_none_or(|b| median < b.0) {
            best = Some((median, f, poses));
        }
    }
    let (median, f, poses) = best?;
    let mut params = vec![f, f, c.x, c.y];
    params.extend(model.start());
    for (r, t) in poses {
        params.extend(DQuat::from_mat3(&r).to_scaled_axis().to_array());
        params.extend(t.to_array());
    }
    Some((DVector::from_vec(params), median))
}

/// Fits the lens to the frames' corners (each frame its own board pose). `progress` is told
/// each stage as it starts.
pub fn fit(
    model: FitModel,
    frames: &[Frame],
    size: (u32, u32),
    mut progress: impl FnMut(&str),
) -> Result<Fit, FitError> {
    const LEAST: usize = 3;
    if frames.len() < LEAST {
        return Err(FitError::TooFewFrames(frames.len(), LEAST));
    }
    progress("starting point");
    let (params, _) = start(model, frames, size).ok_or(FitError::NoStart)?;
    let mut keep: Vec<Vec<bool>> = frames.iter().map(|f| vec![true; f.board.len()]).collect();
    let mut params = params;
    let mut dropped = 0;
    for round in 0..2 {
        progress(if round == 0 {
            "fitting"
        } else {
            "fitting without outliers"
        });
        let problem = Problem::new(model, frames, keep.clone(), params.clone());
        let (solved, report) = LevenbergMarquardt::new()
            .with_patience(200)
            .minimize(problem);
        if !report.termination.was_successful() && report.objective_function.is_nan() {
            return Err(FitError::Diverged(format!("{:?}", report.termination)));
        }
        params = solved.params.clone();
        let r = solved.all_residuals(params.as_slice());
        let errors: Vec<f64> = r.as_slice().chunks(2).map(|d| d[0].hypot(d[1])).collect();
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        if round == 1 {
            let worst = errors.iter().copied().fold(0.0, f64::max);
            let p = params.as_slice();
            let poses = (0..frames.len())
                .map(|i| pose_of(&p[model.intrinsics() + POSE * i..]))
                .collect();
            return Ok(Fit {
                fx: p[0],
                fy: p[1],
                cx: p[2],
                cy: p[3],
                model: model.model(p),
                poses,
                rms,
                worst,
                kept: errors.len(),
                dropped,
            });
        }
        // Drop the corners far off this fit.
        let limit = (OUTLIER_RMS * rms).max(MIN_OUTLIER);
        let mut e = errors.iter();
        for k in keep.iter_mut() {
            for flag in k.iter_mut().filter(|f| **f) {
                if *e.next().expect("one error per kept corner") > limit {
                    *flag = false;
                    dropped += 1;
                }
            }
        }
    }
    unreachable!("the second round returns")
}
