//! What the autopilot's messages say about the vehicle: which component is the autopilot (the
//! first HEARTBEAT with an autopilot type, or the configured system id; a real autopilot
//! replaces the demo's simulated flight), who else sends attitude, its attitude
//! (ATTITUDE_QUATERNION or AUTOPILOT_STATE_FOR_GIMBAL_DEVICE when they come, else ATTITUDE)
//! at the local time it was measured, its position (GLOBAL_POSITION_INT) and its home
//! altitude (HOME_POSITION, else the position's relative altitude), and TIMESYNC. Pure:
//! messages in, updates out; the link applies them.

use super::clock::BootClock;
use super::driver::Driver;
use crate::geometry::{Euler, GeoPosition, PositionSample};
use glam::{DQuat, EulerRot};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavAutopilot, MavMessage, MavType};

/// After an ATTITUDE_QUATERNION, ATTITUDE is ignored for this long (µs): the quaternion is
/// the better of the two when an autopilot sends both.
const PREFER_QUATERNION_US: u64 = 1_000_000;

/// What one message changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Update {
    /// The autopilot was found (or a real one replaced the demo's simulated flight).
    Found(Driver),
    /// Another component sent attitude: ignored (system, component).
    OtherAttitude(u8, u8),
    /// The attitude measured at local time `t_us`.
    Attitude { t_us: u64, attitude: Euler },
    /// The position measured at local time `t_us`, moving north, east and down (m/s).
    Position(PositionSample),
    /// The autopilot answered our TIMESYNC request stamped `ours_us` (local) at its time
    /// `remote_us`.
    TimeSync { remote_us: u64, ours_us: u64 },
    /// The autopilot asks for our time (TIMESYNC with tc1 0), to be answered with `ts1`.
    TimeSyncRequest { ts1: i64 },
}

#[derive(Debug, Default)]
pub struct Vehicle {
    /// The system id to take the autopilot from (None: the first that says it is one).
    want_system: Option<u8>,
    autopilot: Option<(u8, u8)>,
    /// The autopilot found is the demo's simulated flight.
    simulated: bool,
    pub clock: BootClock,
    quaternion_at: Option<u64>,
    home_alt: Option<f64>,
}

impl Vehicle {
    pub fn new(want_system: Option<u8>) -> Vehicle {
        Vehicle {
            want_system,
            ..Vehicle::default()
        }
    }

    /// The autopilot's system and component id, once found.
    pub fn autopilot(&self) -> Option<(u8, u8)> {
        self.autopilot
    }

    /// One message from `header`'s component, received at local time `now_us`; `simulated`:
    /// it came from the demo's simulated flight.
    pub fn handle(
        &mut self,
        header: &MavHeader,
        msg: &MavMessage,
        now_us: u64,
        simulated: bool,
    ) -> Option<Update> {
        // System ids above 255 (an extension some routers use) are no autopilot of ours.
        let Ok(system) = u8::try_from(header.system_id) else {
            return None;
        };
        let from = (system, header.component_id);
        if let MavMessage::HEARTBEAT(h) = msg {
            return self.heartbeat(from, h, simulated);
        }
        if self.autopilot != Some(from) || self.simulated != simulated {
            let attitude = matches!(
                msg,
                MavMessage::ATTITUDE(_)
                    | MavMessage::ATTITUDE_QUATERNION(_)
                    | MavMessage::AUTOPILOT_STATE_FOR_GIMBAL_DEVICE(_)
            );
            // The demo's flight stepping aside is no second sender, and while it drives a
            // real autopilot's attitude may come before its first HEARTBEAT.
            let other = attitude && self.autopilot.is_some() && !simulated && !self.simulated;
            return other.then_some(Update::OtherAttitude(from.0, from.1));
        }
        match msg {
            MavMessage::ATTITUDE_QUATERNION(a) => {
                let t_us = self.stamp(a.time_boot_ms, now_us)?;
                self.quaternion_at = Some(now_us);
                quaternion(t_us, [a.q1, a.q2, a.q3, a.q4])
            }
            // What an autopilot sends the gimbal devices it manages (ArduPilot at 50 Hz),
            // as good as ATTITUDE_QUATERNION.
            MavMessage::AUTOPILOT_STATE_FOR_GIMBAL_DEVICE(a) => {
                let t_us = self.stamp((a.time_boot_us / 1000) as u32, now_us)?;
                self.quaternion_at = Some(now_us);
                quaternion(t_us, a.q)
            }
            MavMessage::ATTITUDE(a) => {
                let t_us = self.stamp(a.time_boot_ms, now_us)?;
                if self
                    .quaternion_at
                    .is_some_and(|q| now_us.saturating_sub(q) < PREFER_QUATERNION_US)
                {
                    return None;
                }
                let e = Euler::new(a.yaw as f64, a.pitch as f64, a.roll as f64);
                [e.yaw, e.pitch, e.roll]
                    .iter()
                    .all(|v| v.is_finite())
                    .then_some(Update::Attitude { t_us, attitude: e })
            }
            MavMessage::GLOBAL_POSITION_INT(p) => {
                let t_us = self.stamp(p.time_boot_ms, now_us).unwrap_or(now_us);
                let alt = p.alt as f64 / 1000.0;
                let relative = p.relative_alt as f64 / 1000.0;
                let cm_s = |v: i16| v as f64 / 100.0;
                Some(Update::Position(PositionSample {
                    t_us,
                    position: GeoPosition {
                        lat: p.lat as f64 * 1e-7,
                        lon: p.lon as f64 * 1e-7,
                        alt,
                        relative_alt: self.home_alt.map_or(relative, |h| alt - h),
                    },
                    velocity: glam::DVec3::new(cm_s(p.vx), cm_s(p.vy), cm_s(p.vz)),
                }))
            }
            MavMessage::TIMESYNC(t) if t.tc1 == 0 => Some(Update::TimeSyncRequest { ts1: t.ts1 }),
            MavMessage::TIMESYNC(t) => Some(Update::TimeSync {
                remote_us: u64::try_from(t.tc1 / 1000).ok()?,
                ours_us: u64::try_from(t.ts1 / 1000).ok()?,
            }),
            MavMessage::HOME_POSITION(h) => {
                self.home_alt = Some(h.altitude as f64 / 1000.0);
                None
            }
            _ => None,
        }
    }

    /// The first autopilot's HEARTBEAT (of the configured system, if one is); a real
    /// autopilot's replaces the demo's simulated flight, its clock and home forgotten.
    fn heartbeat(
        &mut self,
        (system, component): (u8, u8),
        h: &mavlink::dialects::common::HEARTBEAT_DATA,
        simulated: bool,
    ) -> Option<Update> {
        let is_autopilot = h.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
            && !matches!(
                h.mavtype,
                MavType::MAV_TYPE_GCS | MavType::MAV_TYPE_ONBOARD_CONTROLLER
            );
        let wanted = is_autopilot && self.want_system.is_none_or(|s| s == system);
        let replaces_demo = self.autopilot.is_some() && self.simulated && !simulated;
        if !wanted || (self.autopilot.is_some() && !replaces_demo) {
            return None;
        }
        if replaces_demo {
            *self = Vehicle::new(self.want_system);
        }
        self.autopilot = Some((system, component));
        self.simulated = simulated;
        Some(Update::Found(Driver {
            system,
            component,
            simulated,
        }))
    }

    /// The local time of the autopilot's `time_boot_ms`, after observing it.
    fn stamp(&mut self, time_boot_ms: u32, now_us: u64) -> Option<u64> {
        let remote = time_boot_ms as u64 * 1000;
        self.clock.observe(remote, now_us);
        self.clock.to_local(remote)
    }
}

/// An attitude sample from a quaternion (w, x, y, z), if it is one.
fn quaternion(t_us: u64, [w, x, y, z]: [f32; 4]) -> Option<Update> {
    let q = DQuat::from_xyzw(x as f64, y as f64, z as f64, w as f64);
    if !q.is_finite() || q.length() < 0.5 {
        return None;
    }
    let (yaw, pitch, roll) = q.normalize().to_euler(EulerRot::ZYX);
    Some(Update::Attitude {
        t_us,
        attitude: Euler::new(yaw, pitch, roll),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::common::*;

    fn header(system_id: u8, component_id: u8) -> MavHeader {
        MavHeader {
            system_id: system_id.into(),
            component_id,
            sequence: 0,
        }
    }

    fn found(system: u8, component: u8) -> Driver {
        Driver {
            system,
            component,
            simulated: false,
        }
    }

    fn heartbeat(autopilot: MavAutopilot, mavtype: MavType) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            autopilot,
            mavtype,
            ..Default::default()
        })
    }

    #[test]
    fn the_autopilot_is_the_first_heartbeat_with_an_autopilot_type_and_only_it_counts() {
        let mut v = Vehicle::new(None);
        let att = MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 1000,
            yaw: 0.5,
            ..Default::default()
        });
        assert_eq!(
            v.handle(&header(1, 1), &att, 5_000_000, false),
            None,
            "not yet found"
        );
        let gcs = heartbeat(MavAutopilot::MAV_AUTOPILOT_INVALID, MavType::MAV_TYPE_GCS);
        assert_eq!(v.handle(&header(255, 190), &gcs, 5_000_000, false), None);
        let ap = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            MavType::MAV_TYPE_QUADROTOR,
        );
        assert_eq!(
            v.handle(&header(1, 1), &ap, 5_000_000, false),
            Some(Update::Found(found(1, 1)))
        );
        assert_eq!(
            v.handle(&header(2, 1), &ap, 5_000_000, false),
            None,
            "a second one"
        );
        assert_eq!(
            v.handle(&header(2, 1), &att, 5_000_000, false),
            Some(Update::OtherAttitude(2, 1)),
            "from another system: ignored, and said"
        );
        match v.handle(&header(1, 1), &att, 5_010_000, false) {
            Some(Update::Attitude { t_us, attitude }) => {
                assert_eq!(t_us, 5_010_000, "the first message maps to its arrival");
                assert_eq!(attitude.yaw, 0.5);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_configured_system_id_is_waited_for_and_the_quaternion_is_preferred() {
        let mut v = Vehicle::new(Some(7));
        let ap = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_FIXED_WING,
        );
        assert_eq!(v.handle(&header(1, 1), &ap, 0, false), None);
        assert_eq!(
            v.handle(&header(7, 1), &ap, 0, false),
            Some(Update::Found(found(7, 1)))
        );
        // A quarter turn about the vertical (yaw 90°): w = cos 45°, z = sin 45°.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let q = MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: 10,
            q1: s,
            q4: s,
            ..Default::default()
        });
        match v.handle(&header(7, 1), &q, 100_000, false) {
            Some(Update::Attitude { attitude, .. }) => {
                assert!((attitude.yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
                assert!(attitude.pitch.abs() < 1e-6 && attitude.roll.abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
        let att = MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 20,
            ..Default::default()
        });
        assert_eq!(
            v.handle(&header(7, 1), &att, 110_000, false),
            None,
            "ATTITUDE after a quaternion"
        );
        let bad = MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: 30,
            q1: f32::NAN,
            ..Default::default()
        });
        assert_eq!(
            v.handle(&header(7, 1), &bad, 120_000, false),
            None,
            "NaN is not an attitude"
        );
    }

    /// ArduPilot sends its gimbal devices AUTOPILOT_STATE_FOR_GIMBAL_DEVICE at 50 Hz once it
    /// manages them: its quaternion is an attitude sample, stamped by its boot time in µs,
    /// and ATTITUDE gives way to it; from another component it counts for nothing.
    #[test]
    fn the_state_an_autopilot_sends_its_gimbal_devices_is_an_attitude() {
        let mut v = Vehicle::new(None);
        let ap = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            MavType::MAV_TYPE_QUADROTOR,
        );
        v.handle(&header(1, 1), &ap, 0, false);
        // Pitched up 30°: w = cos 15°, y = sin 15°.
        let half = 15f32.to_radians();
        let state = |t_us: u64| {
            MavMessage::AUTOPILOT_STATE_FOR_GIMBAL_DEVICE(AUTOPILOT_STATE_FOR_GIMBAL_DEVICE_DATA {
                time_boot_us: t_us,
                q: [half.cos(), 0.0, half.sin(), 0.0],
                target_system: 1,
                target_component: 154,
                ..Default::default()
            })
        };
        match v.handle(&header(1, 1), &state(2_000_000), 50_000, false) {
            Some(Update::Attitude { attitude, .. }) => {
                assert!(
                    (attitude.pitch - 30f64.to_radians()).abs() < 1e-6,
                    "{attitude:?}"
                );
                assert!(attitude.yaw.abs() < 1e-6 && attitude.roll.abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
        let att = MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 2010,
            ..Default::default()
        });
        assert_eq!(v.handle(&header(1, 1), &att, 60_000, false), None);
        assert_eq!(
            v.handle(&header(1, 2), &state(2_020_000), 70_000, false),
            Some(Update::OtherAttitude(1, 2))
        );
    }

    /// The demo's flight and ArduPilot are both system 1, component 1: the demo drives until
    /// the autopilot's HEARTBEAT, which replaces it with a clock of its own; what the demo
    /// still sends then is neither taken nor another sender.
    #[test]
    fn a_real_autopilot_replaces_the_demos_flight_and_its_clock() {
        let mut v = Vehicle::new(None);
        let ap = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_GENERIC,
            MavType::MAV_TYPE_QUADROTOR,
        );
        let demo = Driver {
            simulated: true,
            ..found(1, 1)
        };
        assert_eq!(
            v.handle(&header(1, 1), &ap, 0, true),
            Some(Update::Found(demo))
        );
        let att = |ms: u32, yaw: f32| {
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                yaw,
                ..Default::default()
            })
        };
        assert!(matches!(
            v.handle(&header(1, 1), &att(1000, 0.1), 1_000_000, true),
            Some(Update::Attitude { .. })
        ));
        let real = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            MavType::MAV_TYPE_QUADROTOR,
        );
        assert_eq!(
            v.handle(&header(1, 1), &real, 2_000_000, false),
            Some(Update::Found(found(1, 1)))
        );
        assert_eq!(
            v.handle(&header(1, 1), &att(1100, 0.1), 2_000_000, true),
            None
        );
        assert_eq!(v.handle(&header(1, 1), &ap, 2_000_000, true), None);
        // The autopilot booted 500 s ago: its stamps map from its own first message.
        match v.handle(&header(1, 1), &att(500_000, 0.7), 2_010_000, false) {
            Some(Update::Attitude { t_us, attitude }) => {
                assert_eq!(t_us, 2_010_000);
                assert!((attitude.yaw - 0.7).abs() < 1e-6);
            }
            other => panic!("{other:?}"),
        }
    }
}
