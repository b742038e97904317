//! Any bytes as MAVLink messages on DigiView's link, for the fuzz target (`fuzz/`) and the
//! test that replays its corpus. The bytes are a run of messages, each `[length, message,
//! system, component, payload…]` with the message one of those DigiView reads (by its place
//! in [`READ`]); each goes where the receiving thread sends a frame that passed its checks:
//! what the vehicle says to the telemetry and what is sensed, every message to the
//! components (the cameras and gimbals), on a link that is not open, so what would be
//! answered goes nowhere. Nothing panics.

use super::receive::deliver;
use super::vehicle::Vehicle;
use super::{Components, Kind, MavlinkConfig, Outbox, Profile, Shared};
use crate::policy::Policy;
use crate::state::{Report, Sensed};
use crate::telemetry::Telemetry;
use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion, Message};
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;

/// The messages DigiView reads: the autopilot's, a ground station's commands, parameters and
/// files, a gimbal manager's.
pub const READ: [u32; 20] = [
    0, 2, 20, 21, 23, 30, 31, 33, 75, 76, 110, 111, 280, 281, 282, 284, 286, 287, 320, 323,
];

/// A link's receiving side, fed by hand.
pub struct Bench {
    out: Outbox,
    vehicle: Vehicle,
}

impl Bench {
    /// The autopilot's link with `components` on it, reporting to `sensed` and `report`.
    pub fn new(sensing: (Arc<Sensed>, Arc<Report>), components: Arc<dyn Components>) -> Bench {
        let cfg = MavlinkConfig::default();
        let kind = Kind {
            profile: Profile::Autopilot,
            ids: None,
        };
        let shared = Shared::new(
            ("udpin:127.0.0.1:0".into(), &cfg, kind),
            sensing,
            Arc::new(Telemetry::new(cfg.attitude_sample)),
            Arc::new(Policy::default()),
            Some(components),
        );
        Bench {
            out: Outbox::new(Arc::new(shared)),
            vehicle: Vehicle::new(None),
        }
    }

    /// Every message in `data` that parses, as from 127.0.0.1, then one tick of the
    /// components.
    pub fn feed(&mut self, mut data: &[u8]) {
        let from = (Some(IpAddr::V4(Ipv4Addr::LOCALHOST)), false);
        while let [len, pick, system, component, rest @ ..] = data {
            let (payload, next) = rest.split_at(usize::from(*len).min(rest.len()));
            data = next;
            let id = READ[usize::from(*pick) % READ.len()];
            let Ok(msg) = MavMessage::parse(MavlinkVersion::V2, id, payload) else {
                continue;
            };
            let header = MavHeader {
                system_id: u32::from(*system),
                component_id: *component,
                sequence: 0,
            };
            deliver(
                &self.out.shared,
                (&self.out, &mut self.vehicle),
                (&header, &msg),
                from,
            );
        }
        if let Some(c) = &self.out.shared.components {
            c.tick(&self.out);
        }
    }
}
