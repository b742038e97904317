//! MOUNT_ORIENTATION (265), ArduPilot's dialect's gimbal attitude, which DigiView's MAVLink
//! library (the common set) does not have: the SDK's examples print the gimbal's angles only
//! from it (`_handle_msg_mount_orientation`), so the payload's gimbal sends it beside
//! GIMBAL_DEVICE_ATTITUDE_STATUS. Encoded here as the dialect defines it: time_boot_ms
//! (uint32), roll, pitch, yaw from the nose and yaw from north (floats, degrees).

use crate::geometry::rotation::yaw_pitch;
use glam::{DQuat, DVec3, EulerRot};
use mavlink::dialects::common::GIMBAL_DEVICE_ATTITUDE_STATUS_DATA;
use mavlink::error::ParserError;
use mavlink::{MavlinkVersion, Message};

/// MOUNT_ORIENTATION's id and CRC extra byte (ardupilotmega.xml).
const ID: u32 = 265;
const EXTRA_CRC: u8 = 26;

/// MOUNT_ORIENTATION of the gimbal whose status is `a` (earth frame, its yaw from the nose
/// beside): roll and pitch from the horizon, yaw from the nose and from north, degrees.
pub fn orientation(a: &GIMBAL_DEVICE_ATTITUDE_STATUS_DATA) -> MountOrientation {
    let [w, x, y, z] = a.q.map(f64::from);
    let q = DQuat::from_xyzw(x, y, z, w);
    let (yaw, pitch) = yaw_pitch(q * DVec3::X);
    let (_, _, roll) = q.to_euler(EulerRot::ZYX);
    let from_nose = match a.delta_yaw.is_finite() {
        true => a.delta_yaw as f64,
        false => yaw,
    };
    MountOrientation {
        time_boot_ms: a.time_boot_ms,
        roll: roll.to_degrees() as f32,
        pitch: pitch.to_degrees() as f32,
        yaw: from_nose.to_degrees() as f32,
        yaw_absolute: yaw.to_degrees() as f32,
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MountOrientation {
    pub time_boot_ms: u32,
    pub roll: f32,
    pub pitch: f32,
    pub yaw: f32,
    pub yaw_absolute: f32,
}

impl Message for MountOrientation {
    fn message_id(&self) -> u32 {
        ID
    }
    fn message_name(&self) -> &'static str {
        "MOUNT_ORIENTATION"
    }
    fn target_system_id(&self) -> Option<u8> {
        None
    }
    fn target_component_id(&self) -> Option<u8> {
        None
    }
    fn target_system_id_mut(&mut self) -> Option<&mut u8> {
        None
    }
    fn target_component_id_mut(&mut self) -> Option<&mut u8> {
        None
    }
    fn ser(&self, _version: MavlinkVersion, bytes: &mut [u8]) -> usize {
        bytes[..4].copy_from_slice(&self.time_boot_ms.to_le_bytes());
        let angles = [self.roll, self.pitch, self.yaw, self.yaw_absolute];
        for (k, a) in angles.iter().enumerate() {
            bytes[4 + 4 * k..8 + 4 * k].copy_from_slice(&a.to_le_bytes());
        }
        20
    }
    fn parse(_version: MavlinkVersion, msgid: u32, payload: &[u8]) -> Result<Self, ParserError> {
        if msgid != ID {
            return Err(ParserError::UnknownMessage { id: msgid });
        }
        let mut p = [0u8; 20];
        let n = payload.len().min(20);
        p[..n].copy_from_slice(&payload[..n]);
        let f = |k: usize| f32::from_le_bytes([p[k], p[k + 1], p[k + 2], p[k + 3]]);
        Ok(MountOrientation {
            time_boot_ms: u32::from_le_bytes([p[0], p[1], p[2], p[3]]),
            roll: f(4),
            pitch: f(8),
            yaw: f(12),
            yaw_absolute: f(16),
        })
    }
    fn message_id_from_name(name: &str) -> Option<u32> {
        (name == "MOUNT_ORIENTATION").then_some(ID)
    }
    fn default_message_from_id(id: u32) -> Option<Self> {
        (id == ID).then(MountOrientation::default)
    }
    fn extra_crc(id: u32) -> u8 {
        if id == ID { EXTRA_CRC } else { 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_reads_back_what_it_writes_with_the_dialects_layout() {
        let m = MountOrientation {
            time_boot_ms: 7,
            roll: 1.0,
            pitch: -30.0,
            yaw: 20.0,
            yaw_absolute: 80.0,
        };
        let mut bytes = [0u8; 255];
        assert_eq!(m.ser(MavlinkVersion::V2, &mut bytes), 20);
        assert_eq!(&bytes[..4], &7u32.to_le_bytes());
        assert_eq!(
            MountOrientation::parse(MavlinkVersion::V2, ID, &bytes[..20]).ok(),
            Some(m)
        );
    }
}
