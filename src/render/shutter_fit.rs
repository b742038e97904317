//! Measuring a camera's readout time: the rolling-shutter readout that makes consecutive
//! frames agree best with the attitude history. For a candidate readout, each textured point
//! of a frame is taken to its world ray with its own row's attitude, then into a frame a
//! little later with that frame's rows' attitudes; where the readout is right, the ground
//! there looks the same (the scene barely moves in a tenth of a second; the vehicle turns).
//! The readout with the least photometric disagreement wins: a coarse sweep, then a golden-
//! section search around its best. Run by the head on frames it collects while the vehicle
//! turns (`head::readout_probe`); needs turning, since a vehicle holding still shows no
//! rolling shutter at all.

use crate::geometry::shutter::{MAX_READOUT_MS, Readout, ShutterTable};
use crate::geometry::{AttitudeTrack, Euler, lens_from_world};
use crate::image_ops::bilinear_luma;
use crate::lens::Lens;
use glam::DVec2;
use image::GrayImage;
use rayon::prelude::*;
use serde::Serialize;

/// Attitudes a frame keeps, every [`ATTITUDE_STEP_US`] from [`ATTITUDE_SPAN_US`] before its
/// capture stamp to as long after: enough for any readout up to [`MAX_READOUT_MS`] and any
/// stamped row.
pub const ATTITUDE_STEP_US: u64 = 1000;
pub const ATTITUDE_SPAN_US: u64 = 110_000;
/// Frames between the two of a pair: far enough apart (0.1 s at 30 fps) that the vehicle
/// has turned, near enough that the scene is the same.
const GAP: usize = 3;
/// At most this many pairs are compared, spread over the frames collected.
const MAX_PAIRS: usize = 80;
/// Grid spacing of the points compared, pixels of the frames given.
const POINT_STEP: u32 = 6;
/// A point takes part where its luma gradient is at least this (code values per pixel):
/// flat ground tells nothing.
const MIN_GRADIENT: f64 = 6.0;
/// Luma differences are clamped here, so a moving object or a glint does not dominate.
const MAX_DIFFERENCE: f64 = 40.0;
/// The longest readout the search tries, ms: the frame time at 15 fps.
pub const SEARCH_MS: f64 = 66.0;
/// The coarse sweep's step and the golden-section search's final bracket, ms.
const SWEEP_MS: f64 = 2.0;
const TOLERANCE_MS: f64 = 0.05;

/// One frame as the estimate needs it: luma, and the attitude around its capture.
#[derive(Clone, Debug)]
pub struct FitFrame {
    pub luma: GrayImage,
    /// The attitude every [`ATTITUDE_STEP_US`] from [`ATTITUDE_SPAN_US`] before the capture
    /// stamp to as long after, timed from the first of them.
    attitudes: AttitudeTrack,
}

impl FitFrame {
    /// Samples `attitude(t_us)` (µs from the capture stamp) as the frame keeps it; None
    /// where the history has none.
    pub fn new(luma: GrayImage, attitude: impl Fn(i64) -> Option<Euler>) -> Option<FitFrame> {
        let n = 2 * ATTITUDE_SPAN_US / ATTITUDE_STEP_US + 1;
        let mut attitudes = AttitudeTrack::new(n as usize);
        for i in 0..n {
            let t = i * ATTITUDE_STEP_US;
            attitudes.push(t, attitude(t as i64 - ATTITUDE_SPAN_US as i64)?);
        }
        Some(FitFrame { luma, attitudes })
    }

    /// The attitude `t_us` from the capture stamp (slerp between the samples kept).
    fn attitude(&self, t_us: f64) -> Euler {
        let t = (t_us + ATTITUDE_SPAN_US as f64).round().max(0.0) as u64;
        self.attitudes.at(t).expect("a frame keeps its samples")
    }
}

/// What the estimate found.
#[derive(Clone, Debug, Serialize)]
pub struct Fit {
    /// The readout, ms.
    pub readout_ms: f64,
    /// Pairs of frames compared, and points per pair on average.
    pub pairs: usize,
    pub points: usize,
    /// The mean luma disagreement (code values) at the readout found and with none: how
    /// much the correction explains.
    pub disagreement: f64,
    pub disagreement_global: f64,
    /// The coarse sweep: (readout ms, mean disagreement).
    pub sweep: Vec<(f64, f64)>,
}

#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error("{0} frames with attitudes; the estimate needs at least {1}")]
    TooFewFrames(usize, usize),
    #[error("the frames show too little texture to compare ({0} points a pair)")]
    NoTexture(usize),
}

/// A pair's points: where they are in the earlier frame and its luma there.
struct Pair {
    from: usize,
    to: usize,
    points: Vec<(DVec2, f64)>,
}

/// The readout (direction and stamped row as `like` says) that makes `frames` agree best,
/// `lens` at their size and `mount` the camera's; `progress(done, of)` after each candidate.
pub fn estimate(
    frames: &[FitFrame],
    lens: &Lens,
    mount: Euler,
    like: Readout,
    progress: impl Fn(usize, usize),
) -> Result<Fit, FitError> {
    let least = GAP + 2;
    if frames.len() < least {
        return Err(FitError::TooFewFrames(frames.len(), least));
    }
    let count = frames.len() - GAP;
    let stride = count.div_ceil(MAX_PAIRS).max(1);
    let pairs: Vec<Pair> = (0..count)
        .step_by(stride)
        .map(|from| Pair {
            from,
            to: from + GAP,
            points: textured(&frames[from].luma, lens),
        })
        .collect();
    let points = pairs.iter().map(|p| p.points.len()).sum::<usize>() / pairs.len();
    if points < 50 {
        return Err(FitError::NoTexture(points));
    }
    let cost = |ms: f64| {
        disagreement(
            frames,
            &pairs,
            lens,
            mount,
            Readout {
                time_ms: ms,
                ..like
            },
        )
    };
    let steps = (SEARCH_MS.min(MAX_READOUT_MS) / SWEEP_MS) as usize;
    let total = steps + 1 + golden_steps();
    let sweep: Vec<(f64, f64)> = (0..=steps)
        .map(|i| {
            let ms = i as f64 * SWEEP_MS;
            let c = cost(ms);
            progress(i + 1, total);
            (ms, c)
        })
        .collect();
    let best = sweep
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0.0, |b| b.0);
    let (lo, hi) = ((best - SWEEP_MS).max(0.0), best + SWEEP_MS);
    let readout_ms = golden(lo, hi, &cost, |i| progress(steps + 2 + i, total));
    Ok(Fit {
        readout_ms,
        pairs: pairs.len(),
        points,
        disagreement: cost(readout_ms),
        disagreement_global: sweep[0].1,
        sweep,
    })
}

/// Golden-section steps from a bracket of 2 × [`SWEEP_MS`] down to [`TOLERANCE_MS`].
fn golden_steps() -> usize {
    ((TOLERANCE_MS / (2.0 * SWEEP_MS)).ln() / 0.618_033_988_75f64.ln()).ceil() as usize
}

/// The minimum of `f` in [lo, hi] by golden-section search.
fn golden(mut lo: f64, mut hi: f64, f: &impl Fn(f64) -> f64, step: impl Fn(usize)) -> f64 {
    let r = 0.618_033_988_75;
    let (mut a, mut b) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut fa, mut fb) = (f(a), f(b));
    for i in 0..golden_steps() {
        if fa < fb {
            (hi, b, fb) = (b, a, fa);
            a = hi - r * (hi - lo);
            fa = f(a);
        } else {
            (lo, a, fa) = (a, b, fb);
            b = lo + r * (hi - lo);
            fb = f(b);
        }
        step(i);
    }
    (lo + hi) / 2.0
}

/// The grid points of `luma` well inside the lens's image circle where it has texture.
fn textured(luma: &GrayImage, lens: &Lens) -> Vec<(DVec2, f64)> {
    let at = |x: u32, y: u32| luma.get_pixel(x, y)[0] as f64;
    let (w, h) = luma.dimensions();
    let mut out = vec![];
    for y in (POINT_STEP..h.saturating_sub(POINT_STEP)).step_by(POINT_STEP as usize) {
        for x in (POINT_STEP..w.saturating_sub(POINT_STEP)).step_by(POINT_STEP as usize) {
            let q = DVec2::new(x as f64, y as f64);
            let inside = lens
                .unproject(q)
                .is_some_and(|r| r.z.acos() < 0.9 * lens.half_fov);
            let gradient = (at(x + 1, y) - at(x - 1, y)).hypot(at(x, y + 1) - at(x, y - 1)) / 2.0;
            if inside && gradient >= MIN_GRADIENT {
                out.push((q, at(x, y)));
            }
        }
    }
    out
}

/// The mean clamped luma difference over every pair's points for `readout`.
fn disagreement(
    frames: &[FitFrame],
    pairs: &[Pair],
    lens: &Lens,
    mount: Euler,
    readout: Readout,
) -> f64 {
    let size = (lens.width, lens.height);
    let middle = readout.middle_after_stamp_us();
    // Each frame's lens orientation at its middle row and its shutter table.
    let pose = |f: &FitFrame| {
        let at = |dt: f64| lens_from_world(f.attitude(middle + dt), mount);
        (at(0.0), ShutterTable::new(&readout, size, at))
    };
    let (sum, n) = pairs
        .par_iter()
        .map(|pair| {
            let (from, to) = (&frames[pair.from], &frames[pair.to]);
            let ((a, ta), (b, tb)) = (pose(from), pose(to));
            let mut sum = 0.0;
            let mut n = 0usize;
            for &(q, value) in &pair.points {
                let Some(ray) = lens.unproject(q) else {
                    continue;
                };
                let ray = match &ta {
                    Some(t) => t.at(q).conjugate() * ray,
                    None => ray,
                };
                let ray = b * a.transpose() * ray;
                let there = match &tb {
                    Some(t) => t.project(ray, |r| lens.project(r)),
                    None => lens.project(ray),
                };
                let Some(there) = there.filter(|&p| lens.in_frame(p)) else {
                    continue;
                };
                let d = (bilinear_luma(&to.luma, there) - value).abs();
                sum += d.min(MAX_DIFFERENCE);
                n += 1;
            }
            (sum, n)
        })
        .reduce(|| (0.0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
    sum / n.max(1) as f64
}
