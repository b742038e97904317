//! What the SDK asks of the payload: commands to its camera (to the cameras, a one-shot
//! capture made explicit), to its gimbal device and to the payload component (the status
//! items' intervals, MAV_CMD_USER_4's tracking), the gimbal's attitude, and the camera's
//! parameters under the SDK's names. Each change is permitted by the one gate first.

use super::params::{self, Refusal, Set};
use super::status::{SDK_HEIGHT, SDK_WIDTH};
use super::{CAMERA, GIMBAL, PAYLOAD, Payload};
use crate::autopilot::Outbox;
use crate::cameras::Answer;
use crate::policy::{Act, Peer};
use mavlink::dialects::common::*;
use mavlink::{MavHeader, MessageData};

/// MAV_CMD_USER_4's first parameter for tracking, and its second for the tracker (not the
/// stream's bitrate, 2).
const USER_4_TRACKING: f32 = 4.0;
/// The box the SDK's tracking defaults to, pixels.
const DEFAULT_BOX: f32 = 128.0;

/// Who sent a message, as the header and the policy know them.
type From<'a> = (&'a MavHeader, Peer);

impl Payload {
    /// A HEARTBEAT: the app, said once when it is first heard.
    pub(super) fn heard(&self, from: &MavHeader) {
        let who = (from.system_id as u8, from.component_id);
        if [CAMERA, GIMBAL, PAYLOAD].contains(&who.1) {
            return;
        }
        let new = self.inner().app.replace(who) != Some(who);
        if new {
            tracing::info!(
                "payload SDK: app {}/{} drives view {} as camera {CAMERA} and gimbal {GIMBAL}",
                who.0,
                who.1,
                self.view
            );
        }
    }

    /// A command to the camera, the gimbal device or the payload component.
    pub(super) fn command(&self, out: &Outbox, (from, peer): From, target: u8, msg: &MavMessage) {
        let cmd = match msg {
            MavMessage::COMMAND_LONG(c) => (
                c.command,
                [
                    c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                ],
            ),
            MavMessage::COMMAND_INT(c) => (
                c.command,
                [
                    c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z,
                ],
            ),
            _ => return,
        };
        match target {
            0 | CAMERA => {
                if !self.shown() {
                    let why = format!("view {} is not in the layout", self.view);
                    return self.answer(out, (from, peer), (CAMERA, cmd.0), Answer::failed(why));
                }
                self.to_camera(out, from, peer, &one_shot(msg));
            }
            GIMBAL => self.gimbal_command(out, (from, peer), cmd),
            PAYLOAD => {
                let answer = self.payload_command(out, (from, peer), cmd);
                self.answer(out, (from, peer), (PAYLOAD, cmd.0), answer);
            }
            _ => {}
        }
    }

    /// COMMAND_ACK from `component`, then what follows; a refusal noted with its reason.
    fn answer(
        &self,
        out: &Outbox,
        (from, peer): From,
        (component, command): (u8, MavCmd),
        a: Answer,
    ) {
        if let Some(why) = &a.why {
            let role = match component {
                CAMERA => "camera",
                GIMBAL => "gimbal",
                _ => "component",
            };
            let what = format!("{command:?} to the payload's {role} {component}");
            self.gate.policy().refusals.note(peer, &what, why);
        }
        a.send(out, (component, command), from);
    }

    /// A command to the gimbal device: its information and attitude are given; calibration,
    /// homing and tuning mean nothing for a view.
    fn gimbal_command(&self, out: &Outbox, from: From, (command, p): (MavCmd, [f32; 7])) {
        let request = command == MavCmd::MAV_CMD_REQUEST_MESSAGE;
        let answer = match p[0] as u32 {
            GIMBAL_DEVICE_INFORMATION_DATA::ID if request => {
                Answer::accepted(vec![self.cameras.device_information(self.view)])
            }
            GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID if request => {
                Answer::accepted(vec![self.attitude()])
            }
            _ => Answer::unsupported(format!(
                "{command:?}: a virtual view's gimbal has no motors to calibrate, home or tune"
            )),
        };
        self.answer(out, from, (GIMBAL, command), answer);
    }

    /// A command to the payload component: SET_MESSAGE_INTERVAL for a status item (the SDK's
    /// index in param 1), MAV_CMD_USER_4's tracking; anything else is UNSUPPORTED.
    fn payload_command(
        &self,
        out: &Outbox,
        (from, peer): From,
        (command, p): (MavCmd, [f32; 7]),
    ) -> Answer {
        match command {
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => {
                let set = self.inner().streaming.set(p[0], p[1]);
                match set {
                    Ok(_) => {
                        self.read_item(out, from, p[0] as i16);
                        Answer::accepted(vec![])
                    }
                    Err(why) => Answer::unsupported(why),
                }
            }
            MavCmd::MAV_CMD_USER_4 if p[0] == USER_4_TRACKING && p[1] == 0.0 => {
                match self
                    .gate
                    .permit(peer, Act::Change, "MAV_CMD_USER_4 (tracking)")
                {
                    Ok(()) => self.track(from, p),
                    Err(e) => Answer::denied(e),
                }
            }
            MavCmd::MAV_CMD_USER_4 => Answer::unsupported(format!(
                "MAV_CMD_USER_4 {} {}: of the payload's own commands DigiView does tracking \
                 (4, 0); not the stream's bitrate, white balance or a thermal camera's FFC",
                p[0], p[1]
            )),
            c => Answer::unsupported(format!("{c:?} is not a command of the payload component")),
        }
    }

    /// MAV_CMD_USER_4's tracking: param 3 = 1 with a box (centre x, y, width, height in
    /// 1920x1080 pixels: params 4 to 7, the SDK's 128 square where none is given) follows
    /// what is there; param 3 = 0 sets the mode in param 4 (0 stop, 1 ready; 2, the "eagle
    /// eye" that moves the gimbal without tracking, is not DigiView's).
    fn track(&self, from: &MavHeader, p: [f32; 7]) -> Answer {
        let (mode, [x, y, w, h]) = (p[2], [p[3], p[4], p[5], p[6]]);
        if mode == 1.0 {
            let size = |v: f32| {
                if v.is_finite() && v > 0.0 {
                    v
                } else {
                    DEFAULT_BOX
                }
            };
            let (w, h) = (size(w) / SDK_WIDTH as f32, size(h) / SDK_HEIGHT as f32);
            let (x, y) = (x / SDK_WIDTH as f32, y / SDK_HEIGHT as f32);
            let corners =
                [x - w / 2.0, y - h / 2.0, x + w / 2.0, y + h / 2.0].map(|v| v.clamp(0.0, 1.0));
            let answer = self.cameras.follow_box(from, self.view, corners);
            self.inner().tracking = answer.result == MavResult::MAV_RESULT_ACCEPTED;
            return Answer {
                then: vec![],
                ..answer
            };
        }
        match (mode, x) {
            (0.0, 0.0) => {
                self.inner().tracking = false;
                let answer = self.cameras.unfollow(from, self.view);
                Answer {
                    then: vec![],
                    ..answer
                }
            }
            (0.0, 1.0) => Answer::accepted(vec![]),
            _ => Answer::unsupported(format!(
                "tracking mode {mode} {x}: give 1 with a box, 0 with 0 (stop) or 1 (ready)"
            )),
        }
    }

    /// GIMBAL_DEVICE_SET_ATTITUDE from the SDK: an angle or rates, its flags' yaw lock, or
    /// its retract and neutral, as from an autopilot.
    pub(super) fn set_attitude(&self, peer: Peer, m: &GIMBAL_DEVICE_SET_ATTITUDE_DATA) {
        let what = "GIMBAL_DEVICE_SET_ATTITUDE to the payload's gimbal";
        if self.gate.permit(peer, Act::Change, what).is_err() || !self.shown() {
            return;
        }
        if let Err(e) = self.cameras.set_attitude(self.view, m) {
            self.gate.policy().refusals.note(peer, what, &e.to_string());
        }
    }

    /// PARAM_EXT_* to the camera: the SDK's names here, DigiView's own to the cameras.
    pub(super) fn camera_parameter(&self, out: &Outbox, (from, peer): From, msg: &MavMessage) {
        match msg {
            MavMessage::PARAM_EXT_REQUEST_LIST(_) => {
                for (index, name) in self.listed().iter().enumerate() {
                    out.send(CAMERA, &self.param_value(name, index));
                }
            }
            MavMessage::PARAM_EXT_REQUEST_READ(r) => {
                let name = r.param_id.to_str().unwrap_or("").to_string();
                let index = match r.param_index {
                    -1 => self.listed().iter().position(|n| *n == name),
                    n => usize::try_from(n).ok().filter(|&n| n < self.listed().len()),
                };
                match index {
                    Some(i) => {
                        out.send(CAMERA, &self.param_value(self.listed()[i], i));
                    }
                    None => self.to_camera(out, from, peer, msg),
                }
            }
            MavMessage::PARAM_EXT_SET(p) => self.set_parameter(out, (from, peer), p, msg),
            _ => {}
        }
    }

    /// PARAM_EXT_SET of one of the SDK's names: its value a little-endian uint32 (what the
    /// SDK writes), answered with PARAM_EXT_ACK and the value now.
    fn set_parameter(
        &self,
        out: &Outbox,
        (from, peer): From,
        p: &PARAM_EXT_SET_DATA,
        msg: &MavMessage,
    ) {
        let name = p.param_id.to_str().unwrap_or("").to_string();
        // DigiView's own parameters are the cameras' (which ask the policy themselves).
        if crate::cameras::is_setting(&name) {
            return self.to_camera(out, from, peer, msg);
        }
        let raw = &p.param_value;
        let v = u32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]);
        let what = format!("PARAM_EXT_SET {name} of the payload's camera");
        let result = match self.gate.permit(peer, Act::Change, &what) {
            Err(_) => Err(ParamAck::PARAM_ACK_FAILED),
            Ok(()) => {
                let (_, widest) = self.cameras.view_fov(self.view);
                let thermal = self.cameras.has_thermal();
                let set = params::set(&mut self.inner().modes, &name, v, (widest, thermal));
                match set {
                    Ok(set) => self.apply(set).map_err(|why| {
                        self.gate.policy().refusals.note(peer, &what, &why);
                        ParamAck::PARAM_ACK_FAILED
                    }),
                    Err(r) => {
                        let (ack, why) = match r {
                            Refusal::Unknown(w) => (ParamAck::PARAM_ACK_FAILED, w),
                            Refusal::Value(w) => (ParamAck::PARAM_ACK_VALUE_UNSUPPORTED, w),
                        };
                        self.gate.policy().refusals.note(peer, &what, &why);
                        Err(ack)
                    }
                }
            }
        };
        let shown = self.listed().iter().position(|n| *n == name);
        let value = shown.map_or(v, |i| self.param_u32(self.listed()[i]));
        let ack = MavMessage::PARAM_EXT_ACK(PARAM_EXT_ACK_DATA {
            param_id: p.param_id,
            param_value: encode(value),
            param_type: MavParamExtType::MAV_PARAM_EXT_TYPE_UINT32,
            param_result: result.err().unwrap_or(ParamAck::PARAM_ACK_ACCEPTED),
        });
        out.send(CAMERA, &ack);
    }

    /// What a parameter asks, done: a rest through the gimbal device, the rest through the
    /// gate.
    fn apply(&self, set: Set) -> Result<(), String> {
        if let Set::Rest { neutral } = set {
            let flags = match neutral {
                true => GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_NEUTRAL,
                false => GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_RETRACT,
            };
            let m = GIMBAL_DEVICE_SET_ATTITUDE_DATA {
                flags,
                ..Default::default()
            };
            return self
                .cameras
                .set_attitude(self.view, &m)
                .map_err(|e| e.to_string());
        }
        params::apply(&self.gate, self.view, set)
    }

    /// The SDK's parameters this head lists (C_T_PALETTE only with a thermal sensor).
    fn listed(&self) -> &'static [&'static str] {
        params::listed(self.cameras.has_thermal())
    }

    /// Parameter `name`'s value now.
    pub(super) fn param_u32(&self, name: &str) -> u32 {
        let fov = self.cameras.view_fov(self.view);
        let settings = self.gate.settings().snapshot();
        params::value(&self.inner().modes, name, fov, (&settings, self.view))
    }

    /// PARAM_EXT_VALUE of parameter `name`, listed at `index`.
    fn param_value(&self, name: &str, index: usize) -> MavMessage {
        MavMessage::PARAM_EXT_VALUE(PARAM_EXT_VALUE_DATA {
            param_count: self.listed().len() as u16,
            param_index: index as u16,
            param_id: name.into(),
            param_value: encode(self.param_u32(name)),
            param_type: MavParamExtType::MAV_PARAM_EXT_TYPE_UINT32,
        })
    }
}

/// IMAGE_START_CAPTURE with interval 0 and count 0, as the SDK asks for one photo, made one
/// image (count 1); every other message as it is.
fn one_shot(msg: &MavMessage) -> MavMessage {
    let mut msg = msg.clone();
    let capture = MavCmd::MAV_CMD_IMAGE_START_CAPTURE;
    let (p2, p3) = match &mut msg {
        MavMessage::COMMAND_LONG(c) if c.command == capture => (c.param2, &mut c.param3),
        MavMessage::COMMAND_INT(c) if c.command == capture => (c.param2, &mut c.param3),
        _ => return msg,
    };
    if p2 == 0.0 && *p3 == 0.0 {
        *p3 = 1.0;
    }
    msg
}

/// A uint32 as PARAM_EXT carries it: its little-endian bytes first.
fn encode(v: u32) -> mavlink::types::CharArray<128> {
    let mut bytes = [0u8; 128];
    bytes[..4].copy_from_slice(&v.to_le_bytes());
    bytes.into()
}
