//! The payload SDK's profile, a service beside the cameras: on a link of its own (the SDK's
//! UDP port 14566 by default) DigiView shows an app written with Gremsy's PayloadSdk one
//! payload, as its camera does: one camera (component 100) and one gimbal device (154) for
//! the view the operator picks, and the payload component (26) the SDK sends its status,
//! tracking and stream requests to. Nothing else speaks there, so the SDK, which retargets to
//! whichever camera or gimbal spoke last, drives one view. The camera's messages go to the
//! cameras as they are (`crate::cameras`, renamed to and from the chosen view's ids); what is
//! the SDK's own is here: its parameter names (`params`), its status items, tracking boxes and
//! detection packets (`status`), its gimbal modes. Every change is permitted by the one gate
//! and is a view operation, as from every other path; every command or parameter the profile
//! does not take is answered (UNSUPPORTED, FAILED) and logged with the reason.

mod commands;
mod mount;
mod params;
mod report;
mod status;

use crate::autopilot::{Components, Outbox, Rename};
use crate::cameras::{Cameras, device_component};
use crate::policy::Peer;
use crate::state::Gate;
use crate::supervise::Locked;
use mavlink::dialects::common::{MavMessage, MavType};
use mavlink::{MavHeader, Message};
use params::Modes;
use serde::{Deserialize, Serialize};
use status::Streaming;
use std::collections::HashSet;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The payload's components as the SDK knows them.
pub const CAMERA: u8 = 100;
pub const GIMBAL: u8 = 154;
/// MAV_COMP_ID_USER2: the SDK's PAYLOAD_COMPONENT_ID.
pub const PAYLOAD: u8 = 26;

/// How often the components heartbeat, and the gimbal sends its attitude.
const BEAT_EVERY: Duration = Duration::from_secs(1);
const ATTITUDE_EVERY: Duration = Duration::from_millis(100);
/// How often the detection packets go while TRACK_MODE is detection.
const DETECTIONS_EVERY: Duration = Duration::from_millis(200);

/// `[payload]` in the config.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct PayloadConfig {
    /// The payload SDK's link: `udpin:0.0.0.0:14566` (the SDK's own port), any endpoint the
    /// autopilot link takes, or `off`.
    pub endpoint: String,
    /// The view the SDK drives: 0 is the first camera of the layout.
    pub view: usize,
}

impl Default for PayloadConfig {
    fn default() -> Self {
        PayloadConfig {
            endpoint: "off".into(),
            view: 0,
        }
    }
}

/// The profile: the link's [`Components`].
pub struct Payload {
    cameras: Arc<Cameras>,
    gate: Arc<Gate>,
    view: usize,
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    modes: Modes,
    streaming: Streaming,
    beat: Option<Instant>,
    attitude: Option<Instant>,
    detections: Option<Instant>,
    frame_id: u32,
    /// The app last heard, and whether it was told of.
    app: Option<(u8, u8)>,
    /// A box was given to follow and not let go since: following that ends is a lost object.
    tracking: bool,
    /// What was logged once already.
    said: HashSet<String>,
}

impl Payload {
    pub fn new(cameras: Arc<Cameras>, gate: Arc<Gate>, cfg: &PayloadConfig) -> Payload {
        Payload {
            cameras,
            gate,
            view: cfg.view,
            inner: Mutex::default(),
        }
    }

    fn inner(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.locked()
    }

    /// The chosen view's camera and gimbal device speak as the payload's; the payload
    /// component as itself; nothing else here.
    fn rename(&self) -> Rename {
        let (camera, device) = (
            crate::cameras::FIRST_COMPONENT + self.view as u8,
            device_component(self.view),
        );
        Arc::new(move |c| match c {
            c if c == camera => Some(CAMERA),
            c if c == device => Some(GIMBAL),
            PAYLOAD => Some(PAYLOAD),
            _ => None,
        })
    }

    /// Whether the chosen view is in the layout now.
    fn shown(&self) -> bool {
        let s = crate::state::State::now(self.gate.settings(), self.gate.sensed());
        self.view < Cameras::count(&s)
    }

    /// Logs `line` the first time it is said.
    fn say_once(&self, key: &str, line: impl FnOnce() -> String) {
        if self.inner().said.insert(key.to_string()) {
            tracing::info!("payload SDK: {}", line());
        }
    }

    /// A message for the chosen view's camera, its ids made the view's, to the cameras.
    fn to_camera(&self, out: &Outbox, from: &MavHeader, peer: Peer, msg: &MavMessage) {
        let mut msg = msg.clone();
        if let Some(t) = msg.target_component_id_mut()
            && (*t == CAMERA || *t == 0)
        {
            *t = crate::cameras::FIRST_COMPONENT + self.view as u8;
        }
        self.cameras
            .handle(&out.renamed(self.rename()), from, peer, &msg);
    }
}

impl Components for Payload {
    fn handle(&self, out: &Outbox, from: &MavHeader, peer: Peer, msg: &MavMessage) {
        let ours = |system: u8| system == 0 || system == out.system_id();
        let target = (msg.target_system_id(), msg.target_component_id());
        if let (Some(system), _) = target
            && !ours(system)
        {
            return;
        }
        match (msg, target.1) {
            (MavMessage::HEARTBEAT(_), _) => self.heard(from),
            (MavMessage::COMMAND_LONG(_) | MavMessage::COMMAND_INT(_), Some(c)) => {
                self.command(out, (from, peer), c, msg)
            }
            (MavMessage::GIMBAL_DEVICE_SET_ATTITUDE(m), Some(0 | GIMBAL)) => {
                self.set_attitude(peer, m)
            }
            (
                MavMessage::PARAM_EXT_SET(_)
                | MavMessage::PARAM_EXT_REQUEST_READ(_)
                | MavMessage::PARAM_EXT_REQUEST_LIST(_),
                Some(0 | CAMERA),
            ) => self.camera_parameter(out, (from, peer), msg),
            (MavMessage::FILE_TRANSFER_PROTOCOL(_), Some(CAMERA)) => {
                self.to_camera(out, from, peer, msg)
            }
            (MavMessage::PARAM_REQUEST_READ(r), Some(PAYLOAD)) => {
                self.read_item(out, from, r.param_index)
            }
            (
                MavMessage::PARAM_REQUEST_LIST(_)
                | MavMessage::PARAM_REQUEST_READ(_)
                | MavMessage::PARAM_SET(_),
                Some(GIMBAL),
            ) => self.say_once("gimbal parameters", || {
                "the gimbal's parameters (stiffness, filters, limits) mean nothing for a \
                 virtual view: none are listed or set"
                    .into()
            }),
            (
                MavMessage::GLOBAL_POSITION_INT(_)
                | MavMessage::GPS_RAW_INT(_)
                | MavMessage::SYSTEM_TIME(_),
                _,
            ) => self.say_once(msg.message_name(), || {
                format!(
                    "{} from the app is not used: the views take the vehicle's position and \
                     time from the autopilot link",
                    msg.message_name()
                )
            }),
            _ => {}
        }
    }

    fn tick(&self, out: &Outbox) {
        let now = Instant::now();
        self.cameras.keep_moving();
        let (beat, attitude, detections) = {
            let mut p = self.inner();
            let due = |last: &mut Option<Instant>, every: Duration| {
                let due = last.is_none_or(|t| now - t >= every);
                if due {
                    *last = Some(now);
                }
                due
            };
            (
                due(&mut p.beat, BEAT_EVERY),
                due(&mut p.attitude, ATTITUDE_EVERY),
                p.modes.track == 1 && due(&mut p.detections, DETECTIONS_EVERY),
            )
        };
        if beat {
            for (component, kind) in [
                (CAMERA, MavType::MAV_TYPE_CAMERA),
                (GIMBAL, MavType::MAV_TYPE_GIMBAL),
                (PAYLOAD, MavType::MAV_TYPE_ONBOARD_CONTROLLER),
            ] {
                out.send(component, &crate::cameras::heartbeat(kind));
            }
        }
        if !self.shown() {
            return;
        }
        if attitude {
            let status = self.attitude();
            out.send(GIMBAL, &status);
            if let MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(a) = &status {
                out.send_any(GIMBAL, &mount::orientation(a));
            }
        }
        self.stream_items(out, now);
        if detections {
            self.send_detections(out);
        }
    }
}
