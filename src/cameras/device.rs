//! The views as gimbal *devices* (`[cameras] gimbal = "device"`): the role a real gimbal
//! camera plays beside an autopilot, which is then the gimbal manager. View i is the gimbal
//! device component an autopilot's mount i looks for (MAV_COMP_ID_GIMBAL, 154, then
//! MAV_COMP_ID_GIMBAL2.. from 171): it heartbeats as MAV_TYPE_GIMBAL, answers
//! GIMBAL_DEVICE_INFORMATION with the view's limits, takes GIMBAL_DEVICE_SET_ATTITUDE in every
//! form the drivers send (an angle, rates, retract, neutral; NaN leaving an axis alone) as a
//! view operation through the one gate, and sends GIMBAL_DEVICE_ATTITUDE_STATUS at a steady
//! rate whoever listens, which is what keeps the autopilot counting it healthy. Each view's
//! camera names its device (CAMERA_INFORMATION's gimbal_device_id) and no longer speaks as a
//! gimbal manager: the autopilot is one.

use super::gimbal::{Aim, Refused};
use super::{Cameras, Permitted};
use crate::autopilot::Outbox;
use crate::geometry::view::LockFlags;
use crate::policy::Peer;
use crate::state::State;
use crate::state::view::{Op, Pointing};
use mavlink::dialects::common::*;
use mavlink::{MavHeader, MessageData};
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

/// What the views are to the autopilot's gimbal protocol (v2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum GimbalRole {
    /// Each view's camera is the gimbal manager of its view: ground stations point it
    /// directly (no autopilot gimbal needed).
    #[default]
    Manager,
    /// Each view is a gimbal device the autopilot manages (its mount set to a MAVLink
    /// gimbal): RC sticks, missions and ROIs reach the views through the autopilot.
    Device,
}

/// How often each device sends its attitude: well within the second after which ArduPilot
/// counts a gimbal unhealthy, and often enough for a ground station's attitude display.
pub const STATUS_EVERY: Duration = Duration::from_millis(100);

/// The gimbal device component of view `i`: 154 for the first, 171, 172, 173 for the others,
/// the ids ArduPilot's mount instances look for (PX4 takes whichever answers).
pub fn device_component(i: usize) -> u8 {
    match i {
        0 => 154,
        i => 170 + i as u8,
    }
}

/// The view whose gimbal device `component` is, if the layout shows it.
fn device_of(component: u8, state: &State) -> Option<usize> {
    let i = match component {
        154 => 0,
        171..=173 => (component - 170) as usize,
        _ => return None,
    };
    (i < Cameras::count(state)).then_some(i)
}

impl Cameras {
    /// Whether the views are gimbal devices.
    pub(super) fn devices(&self) -> bool {
        self.cfg.gimbal == GimbalRole::Device
    }

    /// The gimbal devices' part of a message: true when it was theirs (a message to one of
    /// them, or GIMBAL_DEVICE_SET_ATTITUDE), false to let the cameras have it.
    pub(super) fn device_message(
        &self,
        out: &Outbox,
        (from, peer, permitted): (&MavHeader, Peer, &Permitted),
        msg: &MavMessage,
        state: &State,
    ) -> bool {
        let ours = |system: u8| system == 0 || system == out.system_id();
        match msg {
            MavMessage::GIMBAL_DEVICE_SET_ATTITUDE(m) if ours(m.target_system) => {
                let views: Vec<usize> = match m.target_component {
                    0 => (0..Cameras::count(state)).collect(),
                    c => device_of(c, state).into_iter().collect(),
                };
                for i in views {
                    // A message the policy refused is dropped (there is nothing to answer
                    // it with); the gate noted the refusal.
                    if permitted.is_ok()
                        && let Err(e) = self.set_attitude(i, m)
                    {
                        let what = format!("GIMBAL_DEVICE_SET_ATTITUDE to gimbal device {i}");
                        self.gate
                            .policy()
                            .refusals
                            .note(peer, &what, &e.to_string());
                    }
                }
                true
            }
            MavMessage::COMMAND_LONG(c) if ours(c.target_system) => {
                let (id, param) = (c.command, c.param1);
                self.device_command(out, from, c.target_component, (id, param), state)
            }
            MavMessage::COMMAND_INT(c) if ours(c.target_system) => {
                let (id, param) = (c.command, c.param1);
                self.device_command(out, from, c.target_component, (id, param), state)
            }
            _ => false,
        }
    }

    /// A command to a gimbal device: REQUEST_MESSAGE of its information or attitude is
    /// answered, anything else is UNSUPPORTED. Sent to every component, only the request of
    /// GIMBAL_DEVICE_INFORMATION is theirs, answered by the last device first: PX4 drives
    /// the device that answered last, which is then the first view's (154), as ArduPilot's
    /// first mount.
    fn device_command(
        &self,
        out: &Outbox,
        from: &MavHeader,
        component: u8,
        (command, param1): (MavCmd, f32),
        state: &State,
    ) -> bool {
        let request = command == MavCmd::MAV_CMD_REQUEST_MESSAGE;
        let info = request && param1 == GIMBAL_DEVICE_INFORMATION_DATA::ID as f32;
        let devices: Vec<usize> = match component {
            0 if info => (0..Cameras::count(state)).rev().collect(),
            0 => return false,
            c => match device_of(c, state) {
                Some(i) => vec![i],
                None => return false,
            },
        };
        for i in devices {
            let answer = match (request, param1 as u32) {
                (true, GIMBAL_DEVICE_INFORMATION_DATA::ID) => Some(self.device_information(i)),
                (true, GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID) => {
                    Some(self.device_attitude(state, i))
                }
                _ => None,
            };
            let answer = super::Answer {
                result: match answer {
                    Some(_) => MavResult::MAV_RESULT_ACCEPTED,
                    None => MavResult::MAV_RESULT_UNSUPPORTED,
                },
                then: answer.into_iter().collect(),
                why: None,
            };
            answer.send(out, (device_component(i), command), from);
        }
        true
    }

    /// GIMBAL_DEVICE_SET_ATTITUDE to view `i`'s device: retract (the view as a camera fixed
    /// to the airframe: ahead, level with the vehicle, following it), neutral (ahead and
    /// level, roll and pitch held to the horizon), else the angle its quaternion gives
    /// (none: rates only), its flags' locks and yaw frame, as a gimbal manager's command.
    pub(crate) fn set_attitude(
        &self,
        i: usize,
        m: &GIMBAL_DEVICE_SET_ATTITUDE_DATA,
    ) -> Result<(), Refused> {
        use GimbalDeviceFlags as F;
        let rest = |locks: u8| {
            let pointing = Pointing {
                yaw: Some(0.0),
                pitch: Some(0.0),
                roll: Some(0.0),
                earth: false,
                locks: LockFlags(locks),
            };
            self.gate.steer(i, Op::Point(pointing))?;
            self.periodic().cameras[i].rates = None;
            Ok(())
        };
        if m.flags.contains(F::GIMBAL_DEVICE_FLAGS_RETRACT) {
            return rest(0);
        }
        if m.flags.contains(F::GIMBAL_DEVICE_FLAGS_NEUTRAL) {
            return rest(LockFlags::ROLL | LockFlags::PITCH);
        }
        let aim = Aim::quaternion(m.q, m.angular_velocity_y, m.angular_velocity_z);
        let flags = GimbalManagerFlags::from_bits_truncate(m.flags.bits() as u32);
        self.point(i, flags, aim)
    }

    /// The devices' heartbeats (each `beat`) and attitudes (every [`STATUS_EVERY`]), to
    /// whoever listens: the autopilot counts a device healthy only while they come.
    pub(super) fn device_tick(&self, out: &Outbox, state: &State, n: usize, beat: bool) {
        let now = Instant::now();
        let due = {
            let mut p = self.periodic();
            let due = p.device_status.is_none_or(|t| now - t >= STATUS_EVERY);
            if due {
                p.device_status = Some(now);
            }
            due
        };
        for i in 0..n {
            if beat {
                out.send(
                    device_component(i),
                    &super::heartbeat(MavType::MAV_TYPE_GIMBAL),
                );
            }
            if due {
                out.send(device_component(i), &self.device_attitude(state, i));
            }
        }
    }

    /// The gimbal device id a view's camera names: its device component as a device, else
    /// the gimbal its camera manages itself.
    pub(super) fn gimbal_device_id(&self, i: usize) -> u8 {
        match self.devices() {
            true => device_component(i),
            false => super::info::GIMBAL_DEVICE_ID,
        }
    }

    /// The gimbal device id the gimbal's own messages carry: 0 from a device component of
    /// its own (as the protocol asks), the id of the gimbal within the camera's component
    /// otherwise.
    pub(super) fn own_device_id(&self) -> u8 {
        match self.devices() {
            true => 0,
            false => super::info::GIMBAL_DEVICE_ID,
        }
    }
}
