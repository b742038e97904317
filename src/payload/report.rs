//! What the payload reports of its view: the gimbal's attitude with the SDK's mode in its
//! flags, the status items the SDK asked for, and the detection packets.

use super::params::GimbalMode;
use super::status::{self, TRACK_IDLE, TRACK_LOST, TRACK_TRACKED};
use super::{PAYLOAD, Payload};
use crate::autopilot::Outbox;
use mavlink::MavHeader;
use mavlink::dialects::common::{GimbalDeviceFlags, MavMessage};
use std::time::Instant;

/// The flag the SDK reads as "mapping" in the gimbal's status (not the protocol's).
const MAPPING_FLAG: u16 = 0x4000;

impl Payload {
    /// The gimbal device's attitude: the view's, its flags saying the SDK's mode (yaw lock:
    /// lock, retract: off, 0x4000: mapping, none of them: follow).
    pub(super) fn attitude(&self) -> MavMessage {
        let mut m = self.cameras.view_attitude(self.view);
        let mode = self.inner().modes.gimbal;
        // Lock and follow are the view's own locks, which the status's flags say already.
        if let MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(a) = &mut m {
            let mut bits = a.flags.bits();
            match mode {
                GimbalMode::Off => bits |= GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_RETRACT.bits(),
                GimbalMode::Mapping => bits |= MAPPING_FLAG,
                _ => {}
            }
            a.flags = GimbalDeviceFlags::from_bits_retain(bits);
        }
        m
    }

    /// The status items due now, each a PARAM_VALUE of the payload component.
    pub(super) fn stream_items(&self, out: &Outbox, now: Instant) {
        let due = self.inner().streaming.due(now);
        for index in due {
            out.send(PAYLOAD, &self.item_message(index));
        }
    }

    /// PARAM_REQUEST_READ of a status item (or one whose interval was just set): its value.
    pub(super) fn read_item(&self, out: &Outbox, _from: &MavHeader, index: i16) {
        if let Ok(index) = usize::try_from(index)
            && index < status::ITEMS.len()
        {
            out.send(PAYLOAD, &self.item_message(index));
        }
    }

    fn item_message(&self, index: usize) -> MavMessage {
        MavMessage::PARAM_VALUE(status::item(index, self.item(index)))
    }

    /// Status item `index` now (NaN for one DigiView has no sensor for).
    fn item(&self, index: usize) -> f32 {
        let version = |k: usize| {
            let v = env!("CARGO_PKG_VERSION").split('.').nth(k);
            v.and_then(|v| v.parse::<f32>().ok()).unwrap_or(0.0)
        };
        // Each item computes only what it reads (several are streamed, each at its interval).
        let followed = || {
            let b = self.cameras.followed_box(self.view);
            b.map(|b| status::sdk_box(&b))
        };
        let target = || self.cameras.view_target(self.view);
        match index {
            0 => {
                let (fov, widest) = self.cameras.view_fov(self.view);
                (widest / fov) as f32
            }
            3..=6 => followed().map_or(0.0, |b| b[index - 3] as f32),
            7 => self.track_status(followed().is_some()),
            10 => target().0.map_or(f32::NAN, |t| t.lon as f32),
            11 => target().0.map_or(f32::NAN, |t| t.lat as f32),
            12 => target().0.map_or(f32::NAN, |t| t.alt as f32),
            13 => target().1.lon as f32,
            14 => target().1.lat as f32,
            15 => target().1.alt as f32,
            16..=18 => version(index - 16),
            19 => self.param_u32("C_SOURCE") as f32,
            20 => self.param_u32("C_V_REC") as f32,
            24 => self.param_u32("GB_MODE") as f32,
            _ => f32::NAN,
        }
    }

    /// TRK_STATUS: tracked while the view follows what it was given, lost once that ends
    /// without being let go, idle otherwise.
    fn track_status(&self, following: bool) -> f32 {
        match (following, self.inner().tracking) {
            (true, _) => TRACK_TRACKED,
            (false, true) => TRACK_LOST,
            (false, false) => TRACK_IDLE,
        }
    }

    /// The tracked objects in the view's picture, as a detection packet to the app.
    pub(super) fn send_detections(&self, out: &Outbox) {
        let objects = self.cameras.objects_in_picture(self.view);
        let (frame_id, to) = {
            let mut p = self.inner();
            p.frame_id = p.frame_id.wrapping_add(1);
            (p.frame_id, p.app.unwrap_or((0, 0)))
        };
        let m = status::detections(frame_id, &objects, to);
        out.send(PAYLOAD, &MavMessage::V2_EXTENSION(m));
    }
}
