//! Each camera is the gimbal manager of its own view (Gimbal Protocol v2), the view being a
//! gimbal with no motors. Pitch and roll are always from the horizon; yaw is from the
//! vehicle's nose unless the command says earth frame (or yaw lock, as older ground stations
//! send it). The protocol's roll, pitch and yaw lock flags are DigiView's lock flags (a locked
//! axis is held in the world): a command sets them, and the angles are turned into the view's
//! CAM_EULER under them, so the view points where the command says. Rates turn the view every
//! tick until another command; DO_SET_ROI_LOCATION aims it at a place (coordinate control,
//! followed as the vehicle flies) and DO_SET_ROI_NONE leaves it pointing where it points.

use super::commands::{Answer, Command};
use super::info::{GIMBAL_DEVICE_ID, firmware_version, view_quaternion};
use super::{ATTITUDE_EVERY, ATTITUDE_SOONEST, Cameras, FIRST_COMPONENT, boot_ms};
use crate::autopilot::Outbox;
use crate::geometry::GeoPoint;
use crate::geometry::rotation::{wrap_pi, yaw_pitch};
use crate::geometry::view::LockFlags;
use crate::state::State;
use crate::state::view::{Op, Pointing};
use glam::{DQuat, DVec3, EulerRot};
use mavlink::MavHeader;
use mavlink::dialects::common::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::time::Instant;

/// What each view can do as a gimbal, told alike by its manager and its device: every axis
/// turns, follows the vehicle or holds in the world (the lock flags), and yaw turns without end.
const CAPS: GimbalDeviceCapFlags = GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_ROLL_AXIS
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_ROLL_FOLLOW)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_ROLL_LOCK)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_PITCH_AXIS)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_PITCH_FOLLOW)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_PITCH_LOCK)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_YAW_AXIS)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_YAW_FOLLOW)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_HAS_YAW_LOCK)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_SUPPORTS_INFINITE_YAW)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_SUPPORTS_YAW_IN_EARTH_FRAME)
    .union(GimbalDeviceCapFlags::GIMBAL_DEVICE_CAP_FLAGS_CAN_POINT_LOCATION_GLOBAL);

/// The largest roll, pitch and yaw either way, radians.
const LIMITS: (f32, f32, f32) = (FRAC_PI_2 as f32, FRAC_PI_2 as f32, PI as f32);

/// Who may point a gimbal (DO_GIMBAL_MANAGER_CONFIGURE): (system, component), 0 for none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Control {
    pub primary: (u8, u8),
    pub secondary: (u8, u8),
}

impl Control {
    /// Anyone while no primary control is set; then only the primary and secondary.
    fn allows(&self, from: &MavHeader) -> bool {
        let who = (from.system_id as u8, from.component_id);
        self.primary == (0, 0) || who == self.primary || who == self.secondary
    }
}

/// Why a gimbal command is refused (DENIED, and the log says why).
#[derive(Debug, thiserror::Error)]
pub enum Refused {
    #[error("an angle or rate that is infinite, or a quaternion that is not a rotation")]
    Infinite,
    #[error("{}/{} is not in control of gimbal {gimbal}", who.0, who.1)]
    NotInControl { who: (u8, u8), gimbal: usize },
    #[error("gimbal controller {0}/{1}")]
    Controller(f32, f32),
    #[error(transparent)]
    State(#[from] crate::state::Refused),
}

/// Whether a gimbal device id names this camera's gimbal (0: all of them).
pub fn for_this_gimbal(id: u8) -> bool {
    id == 0 || id == GIMBAL_DEVICE_ID
}

/// What a gimbal command asks for, radians and rad/s; None where it leaves an axis alone.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Aim {
    yaw: Option<f64>,
    pitch: Option<f64>,
    roll: Option<f64>,
    yaw_rate: Option<f64>,
    pitch_rate: Option<f64>,
    /// A value that is infinite: the command is refused.
    bad: bool,
}

/// NaN means "leave it"; an infinity is an error.
fn given(v: f32, bad: &mut bool) -> Option<f64> {
    *bad |= v.is_infinite();
    v.is_finite().then_some(v as f64)
}

impl Aim {
    pub fn pitch_yaw(pitch: f32, yaw: f32, pitch_rate: f32, yaw_rate: f32) -> Aim {
        let mut bad = false;
        Aim {
            pitch: given(pitch, &mut bad),
            yaw: given(yaw, &mut bad),
            roll: None,
            pitch_rate: given(pitch_rate, &mut bad),
            yaw_rate: given(yaw_rate, &mut bad),
            bad,
        }
    }

    /// GIMBAL_MANAGER_SET_ATTITUDE: a quaternion (NaN: rates only) and angular velocities.
    pub fn attitude(m: &GIMBAL_MANAGER_SET_ATTITUDE_DATA) -> Aim {
        Aim::quaternion(m.q, m.angular_velocity_y, m.angular_velocity_z)
    }

    /// A gimbal message's quaternion (w, x, y, z; any NaN: no angle, rates only) and its
    /// pitch and yaw rates (NaN: not this one). A quaternion of numbers that is not a
    /// rotation (its length not 1, as the all-zero one) is refused like an infinity: taken
    /// as "no angle" it would still set the lock flags.
    pub fn quaternion(q: [f32; 4], pitch_rate: f32, yaw_rate: f32) -> Aim {
        let mut bad = q.iter().any(|v| v.is_infinite());
        let [w, x, y, z] = q.map(|v| v as f64);
        let q = DQuat::from_xyzw(x, y, z, w);
        let rotation = q.is_finite().then(|| q.length());
        bad |= rotation.is_some_and(|l| (l - 1.0).abs() > UNIT_SLACK);
        let (yaw, pitch, roll) = match rotation {
            Some(_) if !bad => {
                let (yaw, pitch, roll) = q.normalize().to_euler(EulerRot::ZYX);
                (Some(yaw), Some(pitch), Some(roll))
            }
            _ => (None, None, None),
        };
        Aim {
            yaw,
            pitch,
            roll,
            pitch_rate: given(pitch_rate, &mut bad),
            yaw_rate: given(yaw_rate, &mut bad),
            bad,
        }
    }
}

/// How far a quaternion's length may be from 1 and still be taken as a rotation (senders
/// that pack it as f32 from their own Euler angles are off by far less).
const UNIT_SLACK: f64 = 0.01;

/// The lock flags a gimbal command's flags set.
fn locks_of(flags: GimbalManagerFlags) -> u8 {
    use GimbalManagerFlags as F;
    let mut l = 0;
    for (f, bit) in [
        (F::GIMBAL_MANAGER_FLAGS_ROLL_LOCK, LockFlags::ROLL),
        (F::GIMBAL_MANAGER_FLAGS_PITCH_LOCK, LockFlags::PITCH),
        (F::GIMBAL_MANAGER_FLAGS_YAW_LOCK, LockFlags::YAW),
    ] {
        if flags.contains(f) {
            l |= bit;
        }
    }
    l
}

/// A rate's tick: the view turned by yaw and pitch deltas, as CAM_EULER's is_delta turns it.
pub fn turn(dyaw: f64, dpitch: f64) -> Op {
    Op::Angles {
        yaw: dyaw,
        pitch: dpitch,
        roll: 0.0,
        delta: true,
    }
}

impl Cameras {
    /// Points camera `i` as a gimbal manager command from `from` says, if `from` is in
    /// control of it.
    pub(super) fn aim(
        &self,
        from: &MavHeader,
        i: usize,
        flags: GimbalManagerFlags,
        aim: Aim,
    ) -> Result<(), Refused> {
        self.in_control(from, i)?;
        self.point(i, flags, aim)
    }

    /// Points camera `i` as a gimbal message says (the manager's commands and, as a gimbal
    /// device, its manager's GIMBAL_DEVICE_SET_ATTITUDE: their flags share their bits); its
    /// rates turn it on every tick until the next. Yaw is in the earth frame when the flags
    /// say so, or, saying neither frame, when they lock yaw (as older senders mean it).
    pub(super) fn point(
        &self,
        i: usize,
        flags: GimbalManagerFlags,
        aim: Aim,
    ) -> Result<(), Refused> {
        use GimbalManagerFlags as F;
        if aim.bad {
            return Err(Refused::Infinite);
        }
        let earth = flags.contains(F::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME)
            || (flags.contains(F::GIMBAL_MANAGER_FLAGS_YAW_LOCK)
                && !flags.contains(F::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME));
        let pointing = Pointing {
            yaw: aim.yaw,
            pitch: aim.pitch,
            roll: aim.roll,
            earth,
            locks: LockFlags(locks_of(flags)),
        };
        self.gate.steer(i, Op::Point(pointing))?;
        let rates = match (aim.yaw_rate, aim.pitch_rate) {
            (None, None) => None,
            (y, p) => Some((
                if aim.yaw.is_some() {
                    0.0
                } else {
                    y.unwrap_or(0.0)
                },
                if aim.pitch.is_some() {
                    0.0
                } else {
                    p.unwrap_or(0.0)
                },
            )),
        };
        self.periodic().cameras[i].rates = rates.filter(|r| *r != (0.0, 0.0));
        Ok(())
    }

    /// The gimbal's commands: PITCHYAW (degrees), CONFIGURE, ROI_LOCATION and ROI_NONE.
    pub(super) fn gimbal_command(
        &self,
        from: &MavHeader,
        i: usize,
        cmd: &Command,
    ) -> Option<Answer> {
        use MavCmd::*;
        let p = &cmd.params;
        let device = match cmd.command {
            MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW | MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => p[6],
            _ => p[0],
        };
        let named = device >= 0.0 && device.fract() == 0.0 && for_this_gimbal(device as u8);
        if !(device.is_nan() || named) {
            return Some(Answer::denied(format!("no gimbal device {device}")));
        }
        let done = |r: Result<(), Refused>| match r {
            Ok(()) => Answer {
                result: MavResult::MAV_RESULT_ACCEPTED,
                then: vec![],
                why: None,
            },
            Err(e) => Answer::denied(e),
        };
        Some(match cmd.command {
            MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW => {
                let deg = |v: f32| v.to_radians();
                let whole = p[4].fract() == 0.0 && (0.0..=u32::MAX as f32).contains(&p[4]);
                if !whole {
                    return Some(Answer::denied(format!("gimbal manager flags {}", p[4])));
                }
                let flags = GimbalManagerFlags::from_bits_truncate(p[4] as u32);
                let aim = Aim::pitch_yaw(deg(p[0]), deg(p[1]), deg(p[2]), deg(p[3]));
                done(self.aim(from, i, flags, aim))
            }
            MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE => done(self.configure(from, i, p)),
            MAV_CMD_DO_SET_ROI_LOCATION => {
                let (lat, lon, alt) = cmd.location;
                let home = match cmd.above_home {
                    true => self.gate.sensed().vehicle().position.home_alt(),
                    false => 0.0,
                };
                let place = GeoPoint {
                    lat,
                    lon,
                    alt: alt + home,
                };
                done(self.roi(from, i, Some(place)))
            }
            _ => done(self.roi(from, i, None)),
        })
    }

    /// DO_GIMBAL_MANAGER_CONFIGURE: -1 leaves a controller, -2 makes it the sender, -3
    /// releases it, other values name it.
    fn configure(&self, from: &MavHeader, i: usize, p: &[f32; 7]) -> Result<(), Refused> {
        let sender = (from.system_id as u8, from.component_id);
        let mut periodic = self.periodic();
        let control = &mut periodic.cameras[i].control;
        let pick = |sys: f32, comp: f32, now: (u8, u8)| -> Result<(u8, u8), Refused> {
            match (sys, comp) {
                (-1.0, _) => Ok(now),
                (-2.0, _) => Ok(sender),
                (-3.0, _) => Ok((0, 0)),
                (s, c) if (0.0..=255.0).contains(&s) && (0.0..=255.0).contains(&c) => {
                    Ok((s as u8, c as u8))
                }
                (s, c) => Err(Refused::Controller(s, c)),
            }
        };
        let primary = pick(p[0], p[1], control.primary)?;
        let secondary = pick(p[2], p[3], control.secondary)?;
        *control = Control { primary, secondary };
        Ok(())
    }

    /// Aims camera `i` at a place and follows it (coordinate control), or (None) leaves it
    /// pointing where it points now, steered by its angles again.
    fn roi(&self, from: &MavHeader, i: usize, place: Option<GeoPoint>) -> Result<(), Refused> {
        self.in_control(from, i)?;
        let op = place.map_or(Op::ReleaseTarget, Op::Target);
        self.gate.steer(i, op)?;
        self.periodic().cameras[i].rates = None;
        Ok(())
    }

    /// Whether `from` may point gimbal `i` now.
    pub(super) fn in_control(&self, from: &MavHeader, i: usize) -> Result<(), Refused> {
        match self.periodic().cameras[i].control.allows(from) {
            true => Ok(()),
            false => Err(Refused::NotInControl {
                who: (from.system_id as u8, from.component_id),
                gimbal: i,
            }),
        }
    }

    pub(super) fn manager_information(&self) -> MavMessage {
        let (roll, pitch, yaw) = LIMITS;
        MavMessage::GIMBAL_MANAGER_INFORMATION(GIMBAL_MANAGER_INFORMATION_DATA {
            time_boot_ms: boot_ms(),
            cap_flags: GimbalManagerCapFlags::from_bits_truncate(CAPS.bits()),
            roll_min: -roll,
            roll_max: roll,
            pitch_min: -pitch,
            pitch_max: pitch,
            yaw_min: -yaw,
            yaw_max: yaw,
            gimbal_device_id: GIMBAL_DEVICE_ID,
        })
    }

    /// GIMBAL_DEVICE_INFORMATION of gimbal `i`, which its camera answers for as its manager
    /// (the view is a gimbal with no component of its own, GIMBAL_DEVICE_ID 1): what MAVSDK's
    /// Gimbal plugin waits for before it lists the gimbal with a vendor and a model.
    pub(crate) fn device_information(&self, i: usize) -> MavMessage {
        let (roll, pitch, yaw) = LIMITS;
        MavMessage::GIMBAL_DEVICE_INFORMATION(GIMBAL_DEVICE_INFORMATION_DATA {
            uid: 0,
            time_boot_ms: boot_ms(),
            firmware_version: firmware_version(),
            hardware_version: 0,
            roll_min: -roll,
            roll_max: roll,
            pitch_min: -pitch,
            pitch_max: pitch,
            yaw_min: -yaw,
            yaw_max: yaw,
            cap_flags: GimbalDeviceCapFlagsU16::from_bits_truncate(CAPS.bits() as u16),
            custom_cap_flags: 0,
            vendor_name: "DigiView".into(),
            model_name: format!("virtual gimbal {i}").as_str().into(),
            custom_name: format!("view {i}").as_str().into(),
            gimbal_device_id: self.own_device_id(),
            cap_flags2: CAPS,
        })
    }

    pub(super) fn manager_status(&self, state: &State, i: usize) -> MavMessage {
        let control = self.periodic().cameras[i].control;
        MavMessage::GIMBAL_MANAGER_STATUS(GIMBAL_MANAGER_STATUS_DATA {
            time_boot_ms: boot_ms(),
            flags: GimbalManagerFlags::from_bits_truncate(device_flags(state, i).bits() as u32),
            gimbal_device_id: GIMBAL_DEVICE_ID,
            primary_control_sysid: control.primary.0,
            primary_control_compid: control.primary.1,
            secondary_control_sysid: control.secondary.0,
            secondary_control_compid: control.secondary.1,
        })
    }

    /// The view's attitude: earth frame, with its yaw from the vehicle's nose beside it.
    pub(super) fn device_attitude(&self, state: &State, i: usize) -> MavMessage {
        let q = view_quaternion(state, i);
        let rates = self.periodic().cameras[i].rates.unwrap_or((0.0, 0.0));
        let [w, x, y, z] = q.map(|v| v as f64);
        let (yaw, _) = yaw_pitch(DQuat::from_xyzw(x, y, z, w) * DVec3::X);
        MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
            time_boot_ms: boot_ms(),
            q,
            angular_velocity_x: 0.0,
            angular_velocity_y: rates.1 as f32,
            angular_velocity_z: rates.0 as f32,
            failure_flags: GimbalDeviceErrorFlags::empty(),
            flags: device_flags(state, i),
            target_system: 0,
            target_component: 0,
            delta_yaw: wrap_pi(yaw - state.vehicle.attitude.yaw) as f32,
            delta_yaw_velocity: f32::NAN,
            gimbal_device_id: self.own_device_id(),
        })
    }

    /// Sends camera `i`'s attitude every [`ATTITUDE_EVERY`], and at once (at most every
    /// [`ATTITUDE_SOONEST`]) when the view is steered: its angles, locks, control or target
    /// change. The vehicle's own motion waits for the next regular report, so a link is not
    /// flooded while an unlocked view follows a turning vehicle.
    pub(super) fn report_attitude(&self, out: &Outbox, state: &State, i: usize, now: Instant) {
        let c = &state.settings.cameras[i];
        let steering = [c.yaw(), c.pitch(), c.roll()]
            .into_iter()
            .chain([c.locks().0 as f64, c.control().code() as f64])
            .chain(c.target().map_or([f64::NAN; 3], |t| [t.lat, t.lon, t.alt]))
            .map(f64::to_bits)
            .collect::<Vec<u64>>();
        let due = {
            let mut p = self.periodic();
            let last = &mut p.cameras[i].reported;
            let due = match last {
                None => true,
                Some((t, old)) => {
                    now - *t >= ATTITUDE_EVERY || (*old != steering && now - *t >= ATTITUDE_SOONEST)
                }
            };
            if due {
                *last = Some((now, steering));
            }
            due
        };
        if due {
            out.send(FIRST_COMPONENT + i as u8, &self.device_attitude(state, i));
        }
    }
}

/// The lock flags as the gimbal protocol's, yaw reported in the earth frame.
fn device_flags(state: &State, i: usize) -> GimbalDeviceFlags {
    use GimbalDeviceFlags as F;
    let l = state.settings.cameras[i].locks();
    let mut f = F::GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME;
    for (on, flag) in [
        (l.roll(), F::GIMBAL_DEVICE_FLAGS_ROLL_LOCK),
        (l.pitch(), F::GIMBAL_DEVICE_FLAGS_PITCH_LOCK),
        (l.yaw(), F::GIMBAL_DEVICE_FLAGS_YAW_LOCK),
    ] {
        if on {
            f |= flag;
        }
    }
    f
}
