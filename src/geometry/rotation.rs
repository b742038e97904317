//! ZYX Tait-Bryan angles and the fixed frame changes between body, mount and lens.

use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Yaw, pitch, roll in radians; the rotation is Rz(yaw)·Ry(pitch)·Rx(roll).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Euler {
    pub yaw: f64,
    pub pitch: f64,
    pub roll: f64,
}

impl Euler {
    pub const fn new(yaw: f64, pitch: f64, roll: f64) -> Self {
        Euler { yaw, pitch, roll }
    }

    pub fn matrix(&self) -> DMat3 {
        DMat3::from_rotation_z(self.yaw)
            * DMat3::from_rotation_y(self.pitch)
            * DMat3::from_rotation_x(self.roll)
    }

    pub fn quat(&self) -> DQuat {
        DQuat::from_mat3(&self.matrix())
    }

    /// The ZYX angles of a rotation matrix; yaw wrapped to (-π, π], pitch in [-π/2, π/2].
    pub fn from_matrix(m: &DMat3) -> Euler {
        // m.col(j).i is the element in row i, column j.
        let pitch = (-m.x_axis.z).clamp(-1.0, 1.0).asin();
        if m.x_axis.z.abs() < 1.0 - 1e-12 {
            Euler {
                yaw: wrap_pi(m.x_axis.y.atan2(m.x_axis.x)),
                pitch,
                roll: m.y_axis.z.atan2(m.z_axis.z),
            }
        } else {
            // Gimbal lock: only yaw - roll (or yaw + roll) is defined; put it all in yaw.
            Euler {
                yaw: wrap_pi((-m.y_axis.x).atan2(m.y_axis.y)),
                pitch,
                roll: 0.0,
            }
        }
    }

    pub fn from_quat(q: DQuat) -> Euler {
        Euler::from_matrix(&DMat3::from_quat(q))
    }
}

/// Wraps an angle to (-π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI { w + 2.0 * PI } else { w }
}

/// Lens frame (x right, y down, z forward) → mount frame (forward, right, down).
pub const MOUNT_FROM_LENS: DMat3 = DMat3::from_cols(
    DVec3::new(0.0, 1.0, 0.0), // lens x (right) is mount y
    DVec3::new(0.0, 0.0, 1.0), // lens y (down) is mount z
    DVec3::new(1.0, 0.0, 0.0), // lens z (forward) is mount x
);

/// A direction in a camera's image axes (x right, y down, z forward) from its FRD frame.
pub fn image_axes(frd: DVec3) -> DVec3 {
    MOUNT_FROM_LENS.transpose() * frd
}

/// Yaw (about down) and pitch (up from the x-y plane) of an FRD/NED direction.
pub fn yaw_pitch(d: DVec3) -> (f64, f64) {
    (d.y.atan2(d.x), (-d.z).atan2(d.x.hypot(d.y)))
}

/// Unit FRD/NED direction with the given yaw and pitch.
pub fn direction(yaw: f64, pitch: f64) -> DVec3 {
    let (sy, cy) = yaw.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    DVec3::new(cp * cy, cp * sy, -sp)
}
