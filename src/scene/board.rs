//! A calibration board in front of the lens, at a known pose: the fisheye frame the lens
//! captures of it, for testing calibration against known truth. The board is the printed
//! AprilGrid (`lens::calibrate::Board`) on a plain grey background.

use crate::lens::Lens;
use crate::lens::calibrate::Board;
use glam::{DMat3, DVec2, DVec3};
use image::RgbImage;

/// The background's shade behind and around the board (0..=1).
const BACKGROUND: f64 = 0.45;

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
