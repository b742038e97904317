//! Control: the request handling of the DigiView control protocol, the tokio server that
//! carries it over TCP and UDP, and the blocking client behind `digiview ctl`. Sits beside
//! the frame path: it changes the operator's settings (through the one gate,
//! `crate::state::Gate`) that the frame loop snapshots once per frame, reads what the head
//! reports, and never waits on a frame.
//!
//! [`Controller::handle`] turns one received frame into its replies with no I/O, so the
//! server, the fuzzer and the tests all exercise the same code.

pub mod camera;
pub mod checks;
pub mod client;
pub mod detection;
pub mod load;
pub mod server;
pub mod system;

use crate::policy::{Act, Peer, Policy};
use crate::protocol::params::Autopilot;
use crate::protocol::{Body, Message, Param, TextValue, Verdict, split_text};
use crate::state::capture::Capturer;
use crate::state::{Gate, Invalid, MAX_CAMERAS, Refused, Report, State};
use serde::{Deserialize, Serialize};
use std::net::IpAddr;
use std::sync::Arc;

/// `[control]` in the serve configuration: where the control protocol listens, and who may
/// SET, QUIT and delete files, on this and every other control path (`crate::policy`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControlConfig {
    /// Where the control protocol listens, TCP and UDP.
    pub listen: String,
    /// Who may SET: any, none, loopback, or addresses and CIDR ranges, comma-separated.
    pub allow_set: String,
    /// Who may QUIT.
    pub allow_quit: String,
    /// Who may delete files (MAVLink's STORAGE_FORMAT; over MAVLink a signed message only).
    pub allow_delete: String,
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            listen: "0.0.0.0:5010".into(),
            allow_set: "any".into(),
            allow_quit: "loopback".into(),
            allow_delete: "loopback".into(),
        }
    }
}

/// Why a request was refused; the text goes to the server's log.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// DATA_ERROR: the request's values, or what they ask for, are refused.
    #[error("{0}")]
    Data(String),
    /// FORBIDDEN: the client may not do this.
    #[error("{0}")]
    Forbidden(&'static str),
}

impl From<crate::policy::Forbidden> for Refusal {
    fn from(e: crate::policy::Forbidden) -> Self {
        Refusal::Forbidden(e.0)
    }
}

impl From<Invalid> for Refusal {
    fn from(e: Invalid) -> Self {
        Refusal::Data(e.0)
    }
}

impl From<crate::modes::NotAMode> for Refusal {
    fn from(e: crate::modes::NotAMode) -> Self {
        Refusal::Data(e.to_string())
    }
}

impl From<Refused> for Refusal {
    fn from(e: Refused) -> Self {
        match e {
            Refused::Forbidden(f) => f.into(),
            other => Refusal::Data(other.to_string()),
        }
    }
}

impl Refusal {
    pub fn data(e: impl std::fmt::Display) -> Refusal {
        Refusal::Data(e.to_string())
    }
    fn verdict(&self) -> Verdict {
        match self {
            Refusal::Data(_) => Verdict::DataError,
            Refusal::Forbidden(_) => Verdict::Forbidden,
        }
    }
}

/// What one request produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outcome {
    pub replies: Vec<Message>,
    /// A permitted QUIT: stop the process once the replies are sent.
    pub quit: bool,
    /// The frame failed its checksum (a run of these means the stream is misaligned).
    pub bad_checksum: bool,
}

impl Outcome {
    fn one(body: Body) -> Outcome {
        Outcome {
            replies: vec![Message::new(body)],
            ..Outcome::default()
        }
    }
}

/// The autopilot link as AUTOPILOT reports it (the assembly hands over the running link's).
pub trait AutopilotStatus: Send + Sync {
    fn param(&self) -> Autopilot;
}

pub struct Controller {
    /// The one gate every control path changes the settings through (and asks the policy
    /// at), with the settings and what is sensed.
    pub gate: Arc<Gate>,
    /// What the head reports (SYSTEM_STATUS, the last frame).
    pub report: Arc<Report>,
    /// Where CAPTURE's stills and recordings go: the video head's.
    pub capture: Arc<dyn Capturer>,
    /// The autopilot link's state, for AUTOPILOT (None: the link is off).
    pub autopilot: Option<Arc<dyn AutopilotStatus>>,
    /// Whether the head has a thermal sensor (without one, THERMAL and CAM_THERMAL are
    /// refused, saying how to start one).
    pub has_thermal: bool,
}

impl Controller {
    pub fn new(gate: Arc<Gate>, report: Arc<Report>, capture: Arc<dyn Capturer>) -> Controller {
        Controller {
            gate,
            report,
            capture,
            autopilot: None,
            has_thermal: false,
        }
    }

    /// Who may do what, and why requests were refused (logged, and the last per address kept
    /// for REFUSAL): shared with every other control path.
    pub fn policy(&self) -> &Policy {
        self.gate.policy()
    }

    /// The state now: the settings with the vehicle and objects as last sensed.
    pub fn state(&self) -> State {
        State::now(self.gate.settings(), self.gate.sensed())
    }

    /// Notes why `peer`'s request was refused, unless the policy refused it (the gate noted
    /// that already).
    fn note(&self, peer: IpAddr, what: &str, r: &Refusal) {
        if let Refusal::Data(why) = r {
            self.policy().refusals.note(Peer::Net(peer), what, why);
        }
    }

    /// Handles one received frame (or datagram) from `peer`.
    pub fn handle(&self, frame: &[u8], peer: IpAddr) -> Outcome {
        let msg = match Message::decode(frame) {
            Ok(m) => m,
            Err(e) => {
                self.policy()
                    .refusals
                    .note(Peer::Net(peer), "a frame", &e.to_string());
                let (verdict, param_type) = e.reply();
                return Outcome {
                    bad_checksum: matches!(e, crate::protocol::DecodeError::Checksum { .. }),
                    ..Outcome::one(Body::Verdict(verdict, param_type))
                };
            }
        };
        let param_type = msg.body.param_type();
        let refused = |r: Refusal| {
            let what = match msg.body {
                Body::Get(p) => format!("GET {}", p.param_type()),
                Body::Set(p) => format!("SET {}", p.param_type()),
                _ => format!("{}", msg.body.message_type()),
            };
            self.note(peer, &what, &r);
            Outcome::one(Body::Verdict(r.verdict(), param_type))
        };
        match msg.body {
            Body::Empty(p) => Outcome::one(Body::Verdict(Verdict::Acknowledgement, p)),
            Body::Quit(p) => match self.gate.permit(Peer::Net(peer), Act::Stop, "QUIT") {
                Ok(()) => Outcome {
                    quit: true,
                    ..Outcome::one(Body::Verdict(Verdict::Acknowledgement, p))
                },
                Err(e) => refused(e.into()),
            },
            Body::Get(Param::RefusalReason(q)) => {
                let reason = self
                    .policy()
                    .refusals
                    .last(Peer::Net(peer))
                    .unwrap_or_default();
                let parts = split_text(&reason, TextValue::MAX);
                // Not noted as a refusal: that would replace the reason being read.
                let Some(text) = parts.get(q.part as usize) else {
                    return Outcome::one(Body::Verdict(Verdict::DataError, param_type));
                };
                Outcome::one(Body::Current(Param::RefusalReason(
                    crate::protocol::params::RefusalReason {
                        part: q.part,
                        parts: parts.len().min(255) as u8,
                        reason: TextValue::new(text),
                    },
                )))
            }
            Body::Get(query) => match self.get(&query) {
                Ok(params) => Outcome {
                    replies: params
                        .into_iter()
                        .map(|p| Message::new(Body::Current(p)))
                        .collect(),
                    ..Outcome::default()
                },
                Err(r) => refused(r),
            },
            Body::Set(param) => match self.set(&param, peer) {
                Ok(()) => Outcome::one(Body::Verdict(Verdict::Acknowledgement, param_type)),
                Err(r) => refused(r),
            },
            Body::Current(_) | Body::Verdict(..) => {
                refused(Refusal::Data("a reply type is not a request".to_string()))
            }
        }
    }

    /// A GET from another entry than the binary protocol (the web API): the same answers,
    /// and a refusal logged alike.
    pub fn get_from(&self, query: &Param, peer: IpAddr) -> Result<Vec<Param>, Refusal> {
        self.get(query)
            .inspect_err(|r| self.note(peer, &format!("GET {}", query.param_type()), r))
    }

    /// A SET from another entry than the binary protocol (the web API): the same checks
    /// and permissions, and a refusal logged alike.
    pub fn set_from(&self, param: &Param, peer: IpAddr) -> Result<(), Refusal> {
        self.set(param, peer)
            .inspect_err(|r| self.note(peer, &format!("SET {}", param.param_type()), r))
    }

    /// A GET's answer, nothing logged (what a page polls).
    pub fn get(&self, query: &Param) -> Result<Vec<Param>, Refusal> {
        let cam = checked_cam(query)?;
        let s = self.state();
        let c = &s.settings.cameras[cam];
        let id = cam as u8;
        let one = |p: Param| Ok(vec![p]);
        match query {
            Param::SystemStatus(_) => one(Param::SystemStatus(system::system_status(&self.report))),
            Param::VideoOutput(_) => one(Param::VideoOutput(system::video_output(&s.settings)?)),
            Param::Capture(_) => one(Param::Capture(system::capture(self.capture.as_ref()))),
            Param::Detection(_) => one(Param::Detection(s.settings.detection.param())),
            Param::DetectedRoi(q) => Ok(detection::detected_roi(&s, q.index)?
                .into_iter()
                .map(Param::DetectedRoi)
                .collect()),
            Param::Lens(_) => one(Param::Lens(system::lens(&s.settings))),
            Param::CamEuler(_) => one(Param::CamEuler(camera::euler(c, id))),
            Param::CamZoom(_) => one(Param::CamZoom(camera::zoom(c, id))),
            Param::CamLockFlags(_) => one(Param::CamLockFlags(camera::lock_flags(c, id))),
            Param::CamControlMode(_) => one(Param::CamControlMode(camera::control_mode(c, id))),
            Param::CamCropMode(_) => one(Param::CamCropMode(camera::crop_mode(c, id))),
            Param::CamOffset(q) => one(Param::CamOffset(camera::offset(self, &s, q)?)),
            Param::CamFov(_) => one(Param::CamFov(camera::fov(c, id))),
            Param::CamTarget(q) => one(Param::CamTarget(camera::target(self, &s, q)?)),
            Param::CamSensor(_) => one(Param::CamSensor(system::sensor(&s.settings))),
            Param::GeneralSettings(_) => one(Param::GeneralSettings(system::general(&s.settings))),
            Param::Thermal(_) => one(Param::Thermal(system::thermal(&s.settings))),
            Param::CamThermal(_) => one(Param::CamThermal(camera::thermal(c, id))),
            // Answered per peer in `handle`; elsewhere each refusal carries its reason.
            Param::RefusalReason(_) => Err(Refusal::Data(
                "REFUSAL is read over the control protocol; here each refusal says why".into(),
            )),
            Param::Autopilot(_) => one(Param::Autopilot(
                self.autopilot
                    .as_ref()
                    .map_or_else(Default::default, |a| a.param()),
            )),
        }
    }

    /// A SET from `peer`: permitted once, at the gate, then a view operation, a change of the
    /// settings or a capture.
    fn set(&self, param: &Param, peer: IpAddr) -> Result<(), Refusal> {
        let kind = param.param_type();
        self.gate
            .permit(Peer::Net(peer), Act::Change, &format!("SET {kind}"))?;
        if !kind.settable() {
            return Err(Refusal::Data(format!("{kind} can only be read")));
        }
        let cam = checked_cam(param)?;
        if let Param::Capture(p) = param {
            return system::set_capture(self.capture.as_ref(), p);
        }
        if !self.has_thermal && thermal_asked(param) {
            return Err(Refusal::Data(format!(
                "{kind}: no thermal sensor; start serve with --thermal SOURCE (docs/thermal.md)"
            )));
        }
        let s = self.state();
        if let Some(op) = camera::operation(self, &s, param)? {
            return Ok(self.gate.steer(cam, op)?);
        }
        let (lenses, report) = (self.gate.settings().lenses(), &self.report);
        self.gate.change(|s| match param {
            Param::VideoOutput(p) => system::set_video_output(s, p),
            Param::Detection(p) => {
                s.detection.set(p);
                Ok(())
            }
            Param::Lens(p) => system::set_lens(lenses, s, p),
            Param::CamSensor(p) => system::set_sensor(report, s, p),
            Param::GeneralSettings(p) => system::set_general(lenses, s, p),
            Param::Thermal(p) => system::set_thermal(s, p),
            other => Err(Refusal::Data(format!(
                "{} is not set here",
                other.param_type()
            ))),
        })
    }
}

/// Whether a SET asks for a thermal sensor: THERMAL, and CAM_THERMAL showing it (showing it
/// nowhere is taken without one).
fn thermal_asked(p: &Param) -> bool {
    match p {
        Param::Thermal(_) => true,
        Param::CamThermal(c) => c.show != 0,
        _ => false,
    }
}

/// The camera a per-camera message names, refused outside 0..=3; 0 for the other types.
fn checked_cam(p: &Param) -> Result<usize, Refusal> {
    match p.cam_id() {
        Some(id) if id as usize >= MAX_CAMERAS => {
            Err(Refusal::Data(format!("cam_id {id} is outside 0..=3")))
        }
        Some(id) => Ok(id as usize),
        None => Ok(0),
    }
}
