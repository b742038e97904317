//! The views as MAVLink cameras and gimbals, beside the frame path. Each user camera of the
//! current layout is a camera component (MAV_COMP_ID_CAMERA + i, under the autopilot's system
//! id) that a ground station discovers by its HEARTBEAT, asks what it is (`info`), zooms,
//! takes pictures and video with (`commands`) and points as the gimbal manager of its own
//! view (`gimbal`). Each message is permitted once, here, at the one gate every control
//! path shares (`crate::state::Gate`), and what it asks of a view is a view operation the
//! gate applies, as for the DigiView protocol; what the cameras report is read from the same
//! settings, so each side sees the other at once. This module routes the link's messages to
//! the cameras they address and runs what is periodic: heartbeats, the gimbals' attitude,
//! angular rates and continuous zoom, click to track's statuses (`tracking`), and interval
//! shooting.

mod commands;
mod device;
mod for_payload;
mod ftp;
mod gimbal;
mod host;
mod images;
mod info;
mod settings;
pub mod thermal;
mod tracking;

pub use commands::Answer;
pub use device::{GimbalRole, device_component};
pub use for_payload::{InPicture, PictureBox};
pub use host::public_host;
pub use settings::is_setting;

use crate::autopilot::{Components, Outbox};
use crate::clock::clock_us;
use crate::layout::Slot;
use crate::policy::{Act, Forbidden, Peer};
use crate::state::capture::{CaptureError, ViewShooter, Written};
use crate::state::view::{Op, Zoom};
use crate::state::{Gate, MAX_CAMERAS, State};
use crate::supervise::Locked;
use mavlink::dialects::common::{
    CAMERA_IMAGE_CAPTURED_DATA, FILE_TRANSFER_PROTOCOL_DATA, HEARTBEAT_DATA, MavAutopilot,
    MavMessage, MavModeFlag, MavState, MavType,
};
use mavlink::{MavHeader, Message};
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Camera i is component 100 + i (MAV_COMP_ID_CAMERA .. MAV_COMP_ID_CAMERA4).
pub const FIRST_COMPONENT: u8 = 100;
/// How often each camera's gimbal attitude is sent, and how soon after the last when the
/// view is steered.
const ATTITUDE_EVERY: Duration = Duration::from_millis(200);
const ATTITUDE_SOONEST: Duration = Duration::from_millis(50);
/// How often the heartbeats and the gimbal managers' status go out.
const BEAT_EVERY: Duration = Duration::from_secs(1);
/// The gimbals' status streams while a ground station was heard this recently.
const LISTENER_SILENCE: Duration = Duration::from_secs(5);
/// Captured images remembered per camera for ground stations that ask again by index.
const IMAGES_KEPT: usize = 10_000;

/// `[cameras]` in the config: the views as MAVLink cameras, and their own streams.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CamerasConfig {
    /// Each user camera a MAVLink camera and gimbal on the autopilot link.
    pub enabled: bool,
    /// A view's own stream and stills: its picture's size.
    pub width: u32,
    pub height: u32,
    /// The host put in the stream URLs given to ground stations (default: the RTSP
    /// server's address, or this machine's first network address when that is 0.0.0.0).
    pub public_host: Option<String>,
    /// Each view its own gimbal manager, or a gimbal device the autopilot manages.
    pub gimbal: GimbalRole,
}

impl Default for CamerasConfig {
    fn default() -> Self {
        CamerasConfig {
            enabled: true,
            width: 1280,
            height: 720,
            public_host: None,
            gimbal: GimbalRole::Manager,
        }
    }
}

/// Where the streams are served, once the RTSP server runs.
#[derive(Clone, Debug, Default)]
pub struct Streams {
    /// `rtsp://HOST:PORT/PATH` of the composed frame; a view's is this plus `/camN`.
    pub base: String,
    pub bitrate_kbps: u32,
    /// The streams' coding (VIDEO_STREAM_INFORMATION's `encoding`).
    pub codec: crate::stream::Codec,
    /// Where the HTTP server serves the captures (a capture's URL is this plus its file
    /// name), once it serves.
    pub captures: Option<String>,
}

/// The views as cameras: the link's [`Components`].
pub struct Cameras {
    /// The one gate: the settings, what is sensed, and who may change what.
    gate: Arc<Gate>,
    cfg: CamerasConfig,
    shooter: Option<Arc<dyn ViewShooter>>,
    streams: Mutex<Streams>,
    state: Mutex<Periodic>,
    /// Stills written since the last tick: camera, sequence, the file or why not.
    shots: Arc<Mutex<Vec<Shot>>>,
    /// When each camera's running recording started, as first seen.
    recording_since: Mutex<[Option<Instant>; MAX_CAMERAS]>,
    /// The thermal sensor's reader, once the head runs one (`thermal`).
    thermal: std::sync::OnceLock<Arc<dyn thermal::ThermalReader>>,
}

struct Shot {
    camera: usize,
    taken: Taken,
    file: Result<Written, CaptureError>,
}

/// The view and vehicle when a still was asked for (what CAMERA_IMAGE_CAPTURED reports).
#[derive(Clone, Copy)]
struct Taken {
    time_utc_us: u64,
    time_boot_ms: u32,
    state_q: [f32; 4],
    position: crate::geometry::GeoPosition,
}

/// What each camera does over time.
#[derive(Default)]
struct Periodic {
    beat: Option<Instant>,
    /// When a ground station's HEARTBEAT came last.
    ground_station: Option<Instant>,
    /// When the gimbal devices last sent their attitude.
    device_status: Option<Instant>,
    /// The last tick: rates and continuous zoom advance by the time since.
    ticked: Option<Instant>,
    cameras: [PerCamera; MAX_CAMERAS],
}

#[derive(Default)]
struct PerCamera {
    /// The camera mode a ground station chose (SET_CAMERA_MODE, CAM_MODE): video rather than
    /// photo. Both take stills and record alike; a recording shows as video whatever it is.
    video_mode: bool,
    /// Yaw and pitch rates (rad/s) being applied, from a gimbal command.
    rates: Option<(f64, f64)>,
    /// Continuous zoom: -1 out, 0 stop, 1 in.
    zooming: f64,
    /// The gimbal's controllers (DO_GIMBAL_MANAGER_CONFIGURE): primary, secondary.
    control: gimbal::Control,
    /// When the attitude was last reported, and the view's steering then (bits).
    reported: Option<(Instant, Vec<u64>)>,
    shooting: Option<Shooting>,
    /// The last single image asked for with a sequence number (IMAGE_START_CAPTURE's param
    /// 4): who asked (system, component), the number and when. The same again soon after is
    /// a resend.
    last_single: Option<(Numbered, Instant)>,
    /// CAMERA_IMAGE_CAPTURED of every image taken, by index.
    images: Vec<CAMERA_IMAGE_CAPTURED_DATA>,
    /// Images asked for and not written yet.
    pending: u32,
    /// When the tracking statuses went out last, and whether the camera followed something
    /// then (one idle status follows the last).
    tracking_sent: Option<Instant>,
    was_following: bool,
}

/// A single image asked for by a component (system, component) with its sequence number.
type Numbered = ((u8, u8), u32);

/// Interval shooting: every `interval`, `left` more (None: until stopped).
struct Shooting {
    interval: Duration,
    left: Option<u32>,
    next: Instant,
}

impl Cameras {
    pub fn new(
        gate: Arc<Gate>,
        cfg: CamerasConfig,
        shooter: Option<Arc<dyn ViewShooter>>,
    ) -> Cameras {
        Cameras {
            gate,
            cfg,
            shooter,
            streams: Mutex::default(),
            state: Mutex::default(),
            shots: Arc::default(),
            recording_since: Mutex::default(),
            thermal: std::sync::OnceLock::new(),
        }
    }

    /// Where the streams are, once the RTSP server serves.
    pub fn set_streams(&self, base: String, bitrate_kbps: u32, codec: crate::stream::Codec) {
        let mut s = self.streams.locked();
        (s.base, s.bitrate_kbps, s.codec) = (base, bitrate_kbps, codec);
    }

    /// Where the HTTP server serves the captures (a capture's URL is `captures` plus its
    /// file name), once it serves. The camera definition goes over MAVLink FTP (`ftp`).
    pub fn set_captures_url(&self, captures: String) {
        self.streams.locked().captures = Some(captures);
    }

    fn streams(&self) -> Streams {
        self.streams.locked().clone()
    }

    /// Whether camera `i` records its view.
    fn recording(&self, i: usize) -> bool {
        self.shooter.as_ref().is_some_and(|s| s.recording(i))
    }

    /// Whether camera `i` is in video mode: chosen so, or recording.
    fn video_mode(&self, i: usize) -> bool {
        self.recording(i) || self.periodic().cameras[i].video_mode
    }

    fn periodic(&self) -> std::sync::MutexGuard<'_, Periodic> {
        self.state.locked()
    }

    /// The state now: the settings with the vehicle and objects as last sensed.
    fn state(&self) -> State {
        State::now(self.gate.settings(), self.gate.sensed())
    }

    /// Continuous zoom and gimbal rates, advanced by `dt` seconds: the view operations the
    /// commands that started them, permitted then, go on making.
    fn apply_motion(&self, n: usize, dt: f64) {
        type Motion = (usize, f64, Option<(f64, f64)>);
        let moving: Vec<Motion> = {
            let p = self.periodic();
            (0..n)
                .map(|i| (i, p.cameras[i].zooming, p.cameras[i].rates))
                .filter(|(_, z, r)| *z != 0.0 || r.is_some())
                .collect()
        };
        for (i, zooming, rates) in moving {
            if zooming != 0.0 {
                let _ = self
                    .gate
                    .steer(i, Op::Zoom(Zoom::Scale(2f64.powf(-zooming * dt))));
            }
            if let Some((yaw_rate, pitch_rate)) = rates {
                let _ = self
                    .gate
                    .steer(i, gimbal::turn(yaw_rate * dt, pitch_rate * dt));
            }
        }
    }

    /// The cameras a ground station sees now: the user cameras of the current layout.
    pub fn count(state: &State) -> usize {
        state
            .settings
            .output
            .layout()
            .map(|l| l.views.iter().filter(|v| v.1 != Slot::Debug).count())
            .unwrap_or(0)
    }

    /// The camera a component id names, if the layout shows it.
    fn camera_of(component: u8, state: &State) -> Option<usize> {
        let i = component.checked_sub(FIRST_COMPONENT)? as usize;
        (i < Cameras::count(state)).then_some(i)
    }

    /// The cameras a message for `(system, component)` addresses: one, all (component 0),
    /// or none (another system or component).
    fn addressed(&self, out: &Outbox, system: u8, component: u8, state: &State) -> Vec<usize> {
        if system != 0 && system != out.system_id() {
            return vec![];
        }
        match component {
            0 => (0..Cameras::count(state)).collect(),
            c => Cameras::camera_of(c, state).into_iter().collect(),
        }
    }

    /// Camera `i`'s answer to a MAVLink FTP request for its definition file (reading it asks
    /// nothing of the policy: it changes nothing).
    fn definition_part(
        &self,
        out: &Outbox,
        from: &MavHeader,
        i: usize,
        m: &FILE_TRANSFER_PROTOCOL_DATA,
    ) {
        let file = self.definition().0;
        for payload in ftp::answer(&m.payload, i, file.as_bytes()) {
            let reply = MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
                target_network: 0,
                target_system: u8::try_from(from.system_id).unwrap_or(0),
                target_component: from.component_id,
                payload,
            });
            out.send(FIRST_COMPONENT + i as u8, &reply);
        }
    }
}

/// What a message would do, as the policy judges it, and how the refusal log names it: None
/// for what only reads (the information requests, streaming, the definition).
fn act_of(msg: &MavMessage) -> Option<(Act, String)> {
    let to = |component: u8| match component {
        0 => "every camera".to_string(),
        c => format!("component {c}"),
    };
    match msg {
        MavMessage::COMMAND_LONG(c) => commands::act_of(c.command).map(|act| {
            (
                act,
                format!("{:?} to {}", c.command, to(c.target_component)),
            )
        }),
        MavMessage::COMMAND_INT(c) => commands::act_of(c.command).map(|act| {
            (
                act,
                format!("{:?} to {}", c.command, to(c.target_component)),
            )
        }),
        MavMessage::PARAM_EXT_SET(p) => Some((
            Act::Change,
            format!(
                "PARAM_EXT_SET {} of {}",
                p.param_id.to_str().unwrap_or("?"),
                to(p.target_component)
            ),
        )),
        MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(_) => {
            Some((Act::Change, "GIMBAL_MANAGER_SET_PITCHYAW".into()))
        }
        MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(_) => {
            Some((Act::Change, "GIMBAL_MANAGER_SET_ATTITUDE".into()))
        }
        MavMessage::GIMBAL_DEVICE_SET_ATTITUDE(_) => {
            Some((Act::Change, "GIMBAL_DEVICE_SET_ATTITUDE".into()))
        }
        _ => None,
    }
}

/// Whether a message was permitted (the policy's refusal where not).
type Permitted = Result<(), Forbidden>;

impl Components for Cameras {
    fn handle(&self, out: &Outbox, from: &MavHeader, peer: Peer, msg: &MavMessage) {
        // The one place this path asks the policy, once a message, whichever cameras it
        // addresses. A gimbal message that is not permitted is dropped (it has no answer to
        // deny with); a command is DENIED, a parameter FAILED.
        let permitted = match act_of(msg) {
            Some((act, what)) => self.gate.permit(peer, act, &what),
            None => Ok(()),
        };
        let state = self.state();
        if self.devices() && self.device_message(out, (from, peer, &permitted), msg, &state) {
            return;
        }
        let from = (from, permitted);
        match msg {
            MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS => {
                self.periodic().ground_station = Some(Instant::now());
            }
            MavMessage::FILE_TRANSFER_PROTOCOL(m) if m.target_component != 0 => {
                for i in self.addressed(out, m.target_system, m.target_component, &state) {
                    self.definition_part(out, from.0, i, m);
                }
            }
            MavMessage::COMMAND_LONG(c) => {
                let command = commands::Command::long(c);
                for i in self.addressed(out, c.target_system, c.target_component, &state) {
                    self.command(
                        out,
                        (from.0, peer, from.1),
                        i,
                        &command,
                        c.target_component == 0,
                    );
                }
            }
            MavMessage::COMMAND_INT(c) => {
                let command = commands::Command::int(c);
                for i in self.addressed(out, c.target_system, c.target_component, &state) {
                    self.command(
                        out,
                        (from.0, peer, from.1),
                        i,
                        &command,
                        c.target_component == 0,
                    );
                }
            }
            MavMessage::PARAM_EXT_REQUEST_LIST(_)
            | MavMessage::PARAM_EXT_REQUEST_READ(_)
            | MavMessage::PARAM_EXT_SET(_) => {
                let system = msg.target_system_id().unwrap_or(0);
                let component = msg.target_component_id().unwrap_or(0);
                for i in self.addressed(out, system, component, &state) {
                    self.parameter(out, (peer, from.1), i, msg);
                }
            }
            MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(m) if from.1.is_ok() => {
                for i in self.addressed(out, m.target_system, m.target_component, &state) {
                    if gimbal::for_this_gimbal(m.gimbal_device_id) {
                        let aim = gimbal::Aim::pitch_yaw(m.pitch, m.yaw, m.pitch_rate, m.yaw_rate);
                        let _ = self.aim(from.0, i, m.flags, aim);
                    }
                }
            }
            MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(m) if from.1.is_ok() => {
                for i in self.addressed(out, m.target_system, m.target_component, &state) {
                    if gimbal::for_this_gimbal(m.gimbal_device_id) {
                        let _ = self.aim(from.0, i, m.flags, gimbal::Aim::attitude(m));
                    }
                }
            }
            _ => {}
        }
    }

    fn tick(&self, out: &Outbox) {
        let state = self.state();
        let n = Cameras::count(&state);
        let now = Instant::now();
        self.keep_moving();
        self.deliver_shots(out);
        self.shoot_due(n, now);
        let (beat, listened) = {
            let mut p = self.periodic();
            let due = p.beat.is_none_or(|b| now - b >= BEAT_EVERY);
            if due {
                p.beat = Some(now);
            }
            let heard = p.ground_station.is_some_and(|t| now - t < LISTENER_SILENCE);
            (due, heard)
        };
        // Heartbeats always, so a ground station finds the cameras; the gimbal managers'
        // status only while one listens, so an autopilot link carries nothing no one reads.
        // Gimbal devices report to the autopilot that manages them, always.
        let managers = !self.devices();
        if !managers {
            self.device_tick(out, &state, n, beat);
        }
        for i in 0..n {
            let component = FIRST_COMPONENT + i as u8;
            if beat {
                out.send(component, &heartbeat(MavType::MAV_TYPE_CAMERA));
            }
            if listened {
                if beat && managers {
                    out.send(component, &self.manager_status(&state, i));
                }
                if managers {
                    self.report_attitude(out, &state, i, now);
                }
                self.report_tracking(out, &state, i, now);
            }
        }
    }
}

/// The HEARTBEAT of one of the views' components: a camera (MAV_TYPE_CAMERA) or a gimbal
/// device (MAV_TYPE_GIMBAL).
pub(crate) fn heartbeat(mavtype: MavType) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// Milliseconds since this machine booted, the time base of what the cameras send.
fn boot_ms() -> u32 {
    (clock_us() / 1000) as u32
}
