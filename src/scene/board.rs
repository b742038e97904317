//! A calibration board in front of the lens, at a known pose: the fisheye frame the lens
//! captures of it, for testing calibration against known truth. The board is the printed
//! AprilGrid (`lens::calibrate::Board`) on a plain grey background.

use crate::lens::Lens;
use crate::lens::calibrate::Board;
use crate::units::{parse_angle, parse_length};
use glam::{DMat3, DVec2, DVec3};
use image::RgbImage;
use std::f64::consts::TAU;

/// The background's shade behind and around the board (0..=1).
const BACKGROUND: f64 = 0.45;

/// A board pose that does not parse: the pose and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error(
    "board pose `{spec}`: {why} (a pose is off=ANGLE,azimuth=ANGLE,distance=LENGTH\
     [,tilt=ANGLE][,turn=ANGLE][,spin=ANGLE], e.g. off=60deg,azimuth=90deg,distance=80cm)"
)]
pub struct PoseError {
    spec: String,
    why: String,
}

/// Where the board is, in the lens frame (x right, y down, z along the axis; metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardPose {
    /// Board axes (x right along the rows, y up the columns, z out of the printed face) in the
    /// lens frame.
    pub lens_from_board: DMat3,
    /// The board's origin (tag 0's lower-left corner) in the lens frame.
    pub origin: DVec3,
}

impl BoardPose {
    /// The board's centre `distance` metres along `direction`, its face turned to the lens,
    /// then tilted by `tilt` (about its own x and y axes) and spun by `spin` about its
    /// normal (radians).
    pub fn facing(
        board: &Board,
        direction: DVec3,
        distance: f64,
        tilt: DVec2,
        spin: f64,
    ) -> BoardPose {
        let forward = direction.normalize();
        let z = -forward;
        let side = if forward.x.abs() < 0.9 {
            DVec3::X
        } else {
            DVec3::Y
        };
        let x = (side - forward * side.dot(forward)).normalize();
        let y = z.cross(x);
        let turn = DMat3::from_rotation_z(spin)
            * DMat3::from_rotation_x(tilt.x)
            * DMat3::from_rotation_y(tilt.y);
        let lens_from_board = DMat3::from_cols(x, y, z) * turn;
        let centre = DVec2::new(board.cols as f64, board.rows as f64) * board.pitch() - board.gap();
        let origin = forward * distance - lens_from_board * (centre / 2.0).extend(0.0);
        BoardPose {
            lens_from_board,
            origin,
        }
    }

    /// A pose written as `off=ANGLE,azimuth=ANGLE,distance=LENGTH[,tilt=ANGLE][,turn=ANGLE]
    /// [,spin=ANGLE]`: the board's centre `off` from the lens axis at `azimuth` (0 the frame's
    /// right, 90° down), `distance` away, facing the lens, then tilted about its own x axis,
    /// turned about its y axis and spun about its normal. Angles in radians or with `deg`.
    pub fn parse(board: &Board, spec: &str) -> Result<BoardPose, PoseError> {
        let fail = |why: String| PoseError {
            spec: spec.to_string(),
            why,
        };
        let (mut off, mut azimuth, mut distance) = (None, None, None);
        let (mut tilt, mut turn, mut spin) = (0.0, 0.0, 0.0);
        for field in spec.split(',').map(str::trim).filter(|f| !f.is_empty()) {
            let (key, value) = field
                .split_once('=')
                .ok_or_else(|| fail(format!("`{field}` is not key=value")))?;
            let angle = || parse_angle(value).map_err(|e| fail(format!("{key}: {e}")));
            match key.trim() {
                "off" => off = Some(angle()?),
                "azimuth" => azimuth = Some(angle()?),
                "distance" => {
                    distance = Some(parse_length(value).map_err(|e| fail(e.to_string()))?)
                }
                "tilt" => tilt = angle()?,
                "turn" => turn = angle()?,
                "spin" => spin = angle()?,
                other => return Err(fail(format!("no field `{other}`"))),
            }
        }
        let (Some(off), Some(azimuth), Some(distance)) = (off, azimuth, distance) else {
            return Err(fail("off, azimuth and distance are needed".into()));
        };
        if !(0.0..=std::f64::consts::PI).contains(&off) {
            return Err(fail(format!(
                "off is 0..=180deg from the axis (got {:.1}°)",
                off.to_degrees()
            )));
        }
        let direction = DVec3::new(
            off.sin() * azimuth.cos(),
            off.sin() * azimuth.sin(),
            off.cos(),
        );
        Ok(BoardPose::facing(
            board,
            direction,
            distance,
            DVec2::new(tilt, turn),
            spin,
        ))
    }

    /// `count` poses spread over a lens's image circle of half field of view `half_fov`: a
    /// twelfth in the middle, the rest on rings at 37%, 63% and 84% of `half_fov` (a quarter,
    /// a third and a third), each tilted, turned and spun differently, at distances that make
    /// the board fill about a sixth of the field.
    pub fn sweep(board: &Board, count: usize, half_fov: f64) -> Vec<BoardPose> {
        let (low, high) = board.extent();
        // The reference board (6 × 6 tags of 60 mm, 0.52 m with its margin) sits 0.6 to 1 m away.
        let scale = (high - low).max_element() / 0.522;
        let middle = count.div_ceil(12).min(count);
        let rest = count - middle;
        let rings = [
            (0.0, middle, 0.6),
            (0.37, rest / 4, 0.7),
            (0.63, (rest - rest / 4) / 2, 0.8),
            (0.84, rest - rest / 4 - (rest - rest / 4) / 2, 1.0),
        ];
        let mut poses = vec![];
        for (ring, (fraction, n, distance)) in rings.into_iter().enumerate() {
            for i in 0..n {
                let azimuth = (i as f64 + 0.5 * ring as f64) * TAU / n as f64;
                let off = fraction * half_fov;
                let direction = DVec3::new(
                    off.sin() * azimuth.cos(),
                    off.sin() * azimuth.sin(),
                    off.cos(),
                );
                let tilt = DVec2::new(0.35 * (i as f64 * 1.7).sin(), 0.35 * (i as f64 * 2.3).cos());
                poses.push(BoardPose::facing(
                    board,
                    direction,
                    distance * scale,
                    tilt,
                    0.4 * i as f64,
                ));
            }
        }
        poses
    }

    /// Board point (metres, on its face) in the lens frame.
    pub fn to_lens(&self, p: DVec2) -> DVec3 {
        self.origin + self.lens_from_board * p.extend(0.0)
    }

    /// Where a lens-frame ray from the lens centre meets the board's plane (board metres), or
    /// None if it does not (parallel, or behind).
    pub fn hit(&self, ray: DVec3) -> Option<DVec2> {
        let board_from_lens = self.lens_from_board.transpose();
        let (d, o) = (board_from_lens * ray, board_from_lens * self.origin);
        if d.z.abs() < 1e-12 {
            return None;
        }
        let s = o.z / d.z;
        (s > 0.0).then(|| (d * s - o).truncate())
    }
}

/// The fisheye frame `lens` captures of `board` at `pose`: grey background, black outside
/// the image circle, each pixel the mean of `samples` × `samples` rays.
pub fn board_fisheye(board: &Board, pose: &BoardPose, lens: &Lens, samples: u32) -> RgbImage {
    super::synth::supersample(lens.width, lens.height, samples.max(1), |p| {
        let ray = lens.unproject(p - DVec2::splat(0.5))?;
        let shade = pose
            .hit(ray)
            .and_then(|q| board.shade(q))
            .unwrap_or(BACKGROUND);
        Some(DVec3::splat(shade * 255.0))
    })
}
