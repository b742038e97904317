//! The camera commands a ground station sends (COMMAND_LONG or COMMAND_INT), each answered
//! with COMMAND_ACK first and then what it asked for: the information requests (both
//! MAV_CMD_REQUEST_MESSAGE and the older REQUEST_* commands), zoom, image and video capture,
//! streaming and storage. The gimbal's commands are in `gimbal`. A command with a value that
//! is not a number, or out of its range, is DENIED and changes nothing; one not known here is
//! UNSUPPORTED when it names the camera, and left to others when it was sent to every
//! component.

use super::info::COMPOSED_STREAM;
use super::{Cameras, Permitted, Shooting};
use crate::autopilot::Outbox;
use crate::policy::{Act, Peer};
use crate::state::State;
use crate::state::view::{Op, Zoom};
use crate::units::seconds;
use mavlink::dialects::common::*;
use mavlink::{MavHeader, MessageData};
use std::time::{Duration, Instant};
use tracing::info;

/// A single image asked for again with its sequence number within this long is a resend.
const RESEND_WITHIN: Duration = Duration::from_secs(5);
/// The longest interval between images IMAGE_START_CAPTURE takes: a day.
const MAX_IMAGE_INTERVAL_S: f64 = 86_400.0;

/// A command, whichever message carried it. `location` is params 5 to 7 read as a place:
/// degrees from COMMAND_LONG, degE7 from COMMAND_INT; its altitude is above mean sea level,
/// or above home where `above_home` (COMMAND_INT's relative and terrain frames: DigiView's
/// ground is a plane at home's altitude).
pub struct Command {
    pub command: MavCmd,
    pub params: [f32; 7],
    pub location: (f64, f64, f64),
    pub above_home: bool,
}

impl Command {
    pub fn long(c: &COMMAND_LONG_DATA) -> Command {
        let params = [
            c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
        ];
        Command {
            command: c.command,
            params,
            location: (c.param5 as f64, c.param6 as f64, c.param7 as f64),
            above_home: false,
        }
    }

    /// COMMAND_INT's x and y are params 5 and 6: a latitude and longitude in degE7 for a
    /// command that names a place, plain whole numbers for every other (the gimbal
    /// manager's flags, for DO_GIMBAL_MANAGER_PITCHYAW), as each command's definition says.
    /// The `_INT` frames are superseded by their plain names, and still sent.
    #[allow(deprecated)]
    pub fn int(c: &COMMAND_INT_DATA) -> Command {
        let place = matches!(c.command, MavCmd::MAV_CMD_DO_SET_ROI_LOCATION);
        let scale = if place { 1e-7 } else { 1.0 };
        let (x, y) = (c.x as f64 * scale, c.y as f64 * scale);
        Command {
            command: c.command,
            params: [
                c.param1, c.param2, c.param3, c.param4, x as f32, y as f32, c.z,
            ],
            location: (x, y, c.z as f64),
            above_home: matches!(
                c.frame,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
                    | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_TERRAIN_ALT_INT
            ),
        }
    }

    /// Param `n` (1-based) as a whole number, when it is one in range.
    pub(super) fn whole(&self, n: usize, max: f32) -> Option<u32> {
        let v = self.params[n - 1];
        (v.is_finite() && v >= 0.0 && v <= max && v.fract() == 0.0).then_some(v as u32)
    }

    /// Param `n` as a video stream id: 0 (or NaN, as MAVSDK fills what it does not use) for
    /// every stream, else one of the camera's.
    fn stream(&self, n: usize) -> Option<u32> {
        match self.params[n - 1] {
            v if v.is_nan() => Some(0),
            _ => self.whole(n, COMPOSED_STREAM as f32),
        }
    }
}

/// What a command came to: its COMMAND_ACK's result, the messages that follow it, and why
/// it was denied or failed (noted in the refusal log every control path shares).
pub struct Answer {
    pub result: MavResult,
    pub then: Vec<MavMessage>,
    pub why: Option<String>,
}

impl Answer {
    pub fn accepted(then: Vec<MavMessage>) -> Answer {
        Answer {
            result: MavResult::MAV_RESULT_ACCEPTED,
            then,
            why: None,
        }
    }
    pub fn denied(why: impl std::fmt::Display) -> Answer {
        Answer {
            result: MavResult::MAV_RESULT_DENIED,
            then: vec![],
            why: Some(why.to_string()),
        }
    }
    pub fn failed(why: impl std::fmt::Display) -> Answer {
        Answer {
            result: MavResult::MAV_RESULT_FAILED,
            then: vec![],
            why: Some(why.to_string()),
        }
    }
    pub fn unsupported(why: impl std::fmt::Display) -> Answer {
        Answer {
            result: MavResult::MAV_RESULT_UNSUPPORTED,
            then: vec![],
            why: Some(why.to_string()),
        }
    }

    /// The COMMAND_ACK of `command` from `component` to whoever sent it (`to`), then what
    /// follows it.
    pub fn send(&self, out: &Outbox, (component, command): (u8, MavCmd), to: &MavHeader) {
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result: self.result,
            target_system: to.system_id as u8,
            target_component: to.component_id,
            ..Default::default()
        });
        out.send(component, &ack);
        for m in &self.then {
            out.send(component, m);
        }
    }
}

/// What a camera command would do, as the policy judges it: None for those that only read
/// (the information requests; streaming, which is served whenever watched).
#[allow(deprecated)]
pub(super) fn act_of(command: MavCmd) -> Option<Act> {
    use MavCmd::*;
    match command {
        MAV_CMD_SET_CAMERA_MODE
        | MAV_CMD_SET_CAMERA_ZOOM
        | MAV_CMD_IMAGE_START_CAPTURE
        | MAV_CMD_IMAGE_STOP_CAPTURE
        | MAV_CMD_VIDEO_START_CAPTURE
        | MAV_CMD_VIDEO_STOP_CAPTURE
        | MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
        | MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE
        | MAV_CMD_DO_SET_ROI_LOCATION
        | MAV_CMD_DO_SET_ROI_NONE
        | MAV_CMD_CAMERA_TRACK_POINT
        | MAV_CMD_CAMERA_TRACK_RECTANGLE
        | MAV_CMD_CAMERA_STOP_TRACKING
        | MAV_CMD_SET_CAMERA_SOURCE => Some(Act::Change),
        MAV_CMD_STORAGE_FORMAT => Some(Act::Delete),
        _ => None,
    }
}

impl Cameras {
    /// Runs `cmd` for camera `i` and answers `from`: the ACK, then what follows. A command
    /// the policy did not permit `peer` is DENIED and changes nothing. Unknown commands
    /// sent to every component are left to the others.
    pub(super) fn command(
        &self,
        out: &Outbox,
        (from, peer, permitted): (&MavHeader, Peer, Permitted),
        i: usize,
        cmd: &Command,
        broadcast: bool,
    ) {
        let name = format!("{:?} to camera {i}", cmd.command);
        let answer = match permitted {
            Err(e) => Answer::denied(e),
            Ok(()) => match self.run(from, i, cmd) {
                Some(a) => a,
                None if broadcast => return,
                None => Answer::unsupported(format!(
                    "{:?} is not a command DigiView's cameras take",
                    cmd.command
                )),
            },
        };
        // The policy's refusal is noted where it was asked; this path notes its own.
        if let (Some(why), Ok(())) = (&answer.why, permitted) {
            self.gate.policy().refusals.note(peer, &name, why);
        }
        answer.send(out, (super::FIRST_COMPONENT + i as u8, cmd.command), from);
    }

    /// The answer to `cmd`, None when it is not a camera's command. The REQUEST_* commands
    /// that REQUEST_MESSAGE superseded are answered too: ground stations still send them.
    #[allow(deprecated)]
    fn run(&self, from: &MavHeader, i: usize, cmd: &Command) -> Option<Answer> {
        use MavCmd::*;
        let state = self.state();
        let s = &state;
        let p = &cmd.params;
        Some(match cmd.command {
            MAV_CMD_REQUEST_MESSAGE => {
                let Some(id) = cmd.whole(1, 1e6) else {
                    return Some(Answer::denied("REQUEST_MESSAGE without a message id"));
                };
                return self.requested(s, i, id, cmd);
            }
            MAV_CMD_REQUEST_CAMERA_INFORMATION => Answer::accepted(self.introduction(s, i)),
            MAV_CMD_REQUEST_CAMERA_SETTINGS => Answer::accepted(vec![self.settings(s, i)]),
            MAV_CMD_REQUEST_STORAGE_INFORMATION => Answer::accepted(vec![self.storage()]),
            MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS => Answer::accepted(vec![self.capture_status(i)]),
            MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION | MAV_CMD_REQUEST_VIDEO_STREAM_STATUS => {
                let Some(id) = cmd.stream(1) else {
                    return Some(Answer::denied(format!("no video stream {}", p[0])));
                };
                let info = cmd.command == MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION;
                Answer::accepted(match info {
                    true => self.stream_information(s, i, id as u8),
                    false => self.stream_status(s, i, id as u8),
                })
            }
            MAV_CMD_REQUEST_CAMERA_IMAGE_CAPTURE => match cmd.whole(1, i32::MAX as f32) {
                Some(index) => self.image_again(i, index),
                None => Answer::denied(format!("no image index {}", p[0])),
            },
            MAV_CMD_SET_CAMERA_MODE => match cmd.whole(2, 1.0) {
                // Stills and video are both taken in either mode; the mode is remembered
                // for the ground station that shows it.
                Some(mode) => {
                    self.periodic().cameras[i].video_mode = mode == 1;
                    Answer::accepted(vec![self.settings(s, i)])
                }
                None => Answer::denied(format!("camera mode {}", p[1])),
            },
            MAV_CMD_SET_CAMERA_ZOOM => self.zoom(i, p[0], p[1]),
            MAV_CMD_SET_CAMERA_SOURCE => self.camera_source(i, cmd),
            MAV_CMD_IMAGE_START_CAPTURE => {
                let asker = (from.system_id as u8, from.component_id);
                self.start_images(i, (p[1], p[2]), (asker, p[3]))
            }
            MAV_CMD_IMAGE_STOP_CAPTURE => {
                self.periodic().cameras[i].shooting = None;
                Answer::accepted(vec![self.capture_status(i)])
            }
            MAV_CMD_VIDEO_START_CAPTURE | MAV_CMD_VIDEO_STOP_CAPTURE => {
                let on = cmd.command == MAV_CMD_VIDEO_START_CAPTURE;
                let Some(shooter) = &self.shooter else {
                    return Some(Answer::failed("there is no video pipeline to record"));
                };
                match shooter.record(i, on) {
                    Ok(()) => Answer::accepted(vec![self.capture_status(i), self.settings(s, i)]),
                    Err(e) => Answer::failed(e),
                }
            }
            // The streams are served whenever someone watches them.
            MAV_CMD_VIDEO_START_STREAMING | MAV_CMD_VIDEO_STOP_STREAMING => match cmd.stream(1) {
                Some(_) => Answer::accepted(vec![]),
                None => Answer::denied(format!("no video stream {}", p[0])),
            },
            MAV_CMD_STORAGE_FORMAT => self.format(i, cmd),
            MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
            | MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE
            | MAV_CMD_DO_SET_ROI_LOCATION
            | MAV_CMD_DO_SET_ROI_NONE => return self.gimbal_command(from, i, cmd),
            MAV_CMD_CAMERA_TRACK_POINT
            | MAV_CMD_CAMERA_TRACK_RECTANGLE
            | MAV_CMD_CAMERA_STOP_TRACKING => self.tracking_command(from, i, cmd),
            _ => return None,
        })
    }

    /// MAV_CMD_REQUEST_MESSAGE: the message `id` (param 2 the stream id or image index).
    fn requested(&self, s: &State, i: usize, id: u32, cmd: &Command) -> Option<Answer> {
        let p2 = cmd.params[1];
        Some(match id {
            CAMERA_INFORMATION_DATA::ID => Answer::accepted(self.introduction(s, i)),
            CAMERA_SETTINGS_DATA::ID => Answer::accepted(vec![self.settings(s, i)]),
            CAMERA_FOV_STATUS_DATA::ID => Answer::accepted(vec![self.fov_status(s, i)]),
            CAMERA_TRACKING_IMAGE_STATUS_DATA::ID => {
                Answer::accepted(vec![self.tracking_image_status(s, i)])
            }
            CAMERA_TRACKING_GEO_STATUS_DATA::ID => {
                Answer::accepted(vec![self.tracking_geo_status(s, i)])
            }
            STORAGE_INFORMATION_DATA::ID => Answer::accepted(vec![self.storage()]),
            CAMERA_CAPTURE_STATUS_DATA::ID => Answer::accepted(vec![self.capture_status(i)]),
            CAMERA_THERMAL_RANGE_DATA::ID => return self.thermal_range(i),
            VIDEO_STREAM_INFORMATION_DATA::ID | VIDEO_STREAM_STATUS_DATA::ID => {
                let Some(stream) = cmd.stream(2) else {
                    return Some(Answer::denied(format!("no video stream {p2}")));
                };
                Answer::accepted(match id {
                    VIDEO_STREAM_INFORMATION_DATA::ID => {
                        self.stream_information(s, i, stream as u8)
                    }
                    _ => self.stream_status(s, i, stream as u8),
                })
            }
            CAMERA_IMAGE_CAPTURED_DATA::ID => match cmd.whole(2, i32::MAX as f32) {
                Some(index) => self.image_again(i, index),
                None => Answer::denied(format!("no image index {p2}")),
            },
            // As gimbal devices, the views' gimbals answer for themselves (`device`).
            GIMBAL_MANAGER_INFORMATION_DATA::ID
            | GIMBAL_DEVICE_INFORMATION_DATA::ID
            | GIMBAL_MANAGER_STATUS_DATA::ID
            | GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID
                if self.devices() =>
            {
                return None;
            }
            GIMBAL_MANAGER_INFORMATION_DATA::ID => {
                Answer::accepted(vec![self.manager_information()])
            }
            GIMBAL_DEVICE_INFORMATION_DATA::ID => {
                Answer::accepted(vec![self.device_information(i)])
            }
            GIMBAL_MANAGER_STATUS_DATA::ID => Answer::accepted(vec![self.manager_status(s, i)]),
            GIMBAL_DEVICE_ATTITUDE_STATUS_DATA::ID => {
                Answer::accepted(vec![self.device_attitude(s, i)])
            }
            _ => return None,
        })
    }

    /// SET_CAMERA_ZOOM: a step (each ±1 is ±8 of CAM_ZOOM's 32 to a doubling), continuous
    /// (-1, 0, 1: the fov doubles or halves each second until stopped), a range 0..=100, a
    /// focal length (mm, 35 mm frame) or a horizontal fov (degrees).
    fn zoom(&self, i: usize, kind: f32, value: f32) -> Answer {
        if !value.is_finite() || kind.fract() != 0.0 {
            return Answer::denied(format!("zoom type {kind}, value {value}"));
        }
        let v = value as f64;
        let zoom = match kind as i32 {
            0 if (-32.0..=32.0).contains(&v) => Zoom::Step((8.0 * v) as i8),
            1 if (-1.0..=1.0).contains(&v) => {
                self.periodic().cameras[i].zooming = v;
                return Answer::accepted(vec![self.settings(&self.state(), i)]);
            }
            2 if (0.0..=100.0).contains(&v) => Zoom::Level(v),
            3 if v > 0.0 => Zoom::FocalLength(v),
            4 if v > 0.0 && v <= 360.0 => Zoom::Fov(v.to_radians()),
            1 => return Answer::denied(format!("continuous zoom {v}")),
            _ => return Answer::denied(format!("zoom {kind} {value}")),
        };
        match self.gate.steer(i, Op::Zoom(zoom)) {
            Ok(()) => {
                self.periodic().cameras[i].zooming = 0.0;
                Answer::accepted(vec![self.settings(&self.state(), i)])
            }
            Err(e) => Answer::denied(e),
        }
    }

    /// IMAGE_START_CAPTURE: `count` images (0: until stopped), `interval` s apart (0.1 s
    /// to a day; a single image takes any interval in 0..=a day, and ignores it). A single
    /// image asked for again with the same sequence number by the same component (a command
    /// sent again for want of an ACK, as PX4's command sender does after 0.5 s) is accepted
    /// and taken once.
    fn start_images(
        &self,
        i: usize,
        (interval, count): (f32, f32),
        (asker, sequence): ((u8, u8), f32),
    ) -> Answer {
        let count_ok = count.is_finite() && count >= 0.0 && count.fract() == 0.0;
        if !count_ok {
            return Answer::denied(format!("image capture of {count} every {interval} s"));
        }
        let least = if count == 1.0 { 0.0 } else { 0.1 };
        let interval = match seconds(interval as f64, least..=MAX_IMAGE_INTERVAL_S) {
            Ok(d) => d,
            Err(e) => return Answer::denied(format!("an image interval of {e}")),
        };
        let numbered = (count == 1.0 && sequence >= 1.0 && sequence.fract() == 0.0)
            .then_some((asker, sequence as u32));
        let resent = self.periodic().cameras[i]
            .last_single
            .is_some_and(|(last, at)| Some(last) == numbered && at.elapsed() < RESEND_WITHIN);
        if resent {
            info!("camera {i}: image {sequence} asked for again by {asker:?}: taken once");
            return Answer::accepted(vec![]);
        }
        let Some(shooter) = &self.shooter else {
            return Answer::failed("there is no video pipeline to take images from");
        };
        // The directory and its room are checked before the first image is promised.
        if let Some(dir) = super::info::space_mib(shooter.dir())
            && dir.1 < 1.0
        {
            return Answer::failed(format!("{} is full", shooter.dir().display()));
        }
        let mut p = self.periodic();
        p.cameras[i].shooting = Some(Shooting {
            interval,
            left: (count > 0.0).then_some(count as u32),
            next: Instant::now(),
        });
        if let Some(n) = numbered {
            p.cameras[i].last_single = Some((n, Instant::now()));
        }
        drop(p);
        info!(
            "camera {i}: taking {count} images every {} s (0: until stopped)",
            interval.as_secs_f64()
        );
        Answer::accepted(vec![])
    }

    /// CAMERA_IMAGE_CAPTURED of image `index` again.
    fn image_again(&self, i: usize, index: u32) -> Answer {
        match self.periodic().cameras[i].images.get(index as usize) {
            Some(m) => Answer::accepted(vec![MavMessage::CAMERA_IMAGE_CAPTURED(m.clone())]),
            None => Answer::denied(format!("camera {i} has no image {index}")),
        }
    }

    /// STORAGE_FORMAT: removes DigiView's stills and recordings from the capture directory
    /// (nothing else there, and no recording still running), and with param 3 starts the
    /// image indices again.
    fn format(&self, i: usize, cmd: &Command) -> Answer {
        if cmd.whole(1, 1.0).is_none() || cmd.params[1] != 1.0 {
            return Answer::denied("STORAGE_FORMAT of storage 1 (or 0, all) with param 2 = 1");
        }
        let Some(shooter) = &self.shooter else {
            return Answer::failed("there is no capture directory");
        };
        let removed = match shooter.format() {
            Ok(n) => n,
            Err(e) => return Answer::failed(format!("{}: {e}", shooter.dir().display())),
        };
        info!(
            "storage format: {removed} captures removed from {}",
            shooter.dir().display()
        );
        if cmd.params[2] == 1.0 {
            self.periodic().cameras[i].images.clear();
        }
        Answer::accepted(vec![self.storage()])
    }
}

/// When the next interval image is due after one taken at `t`.
pub(super) fn next_after(t: Instant, interval: Duration) -> Instant {
    t + interval.max(Duration::from_millis(100))
}
