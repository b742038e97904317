//! Image capture of a camera's view: interval shooting (IMAGE_START_CAPTURE's count and
//! interval) asks the head for stills of the view alone, and each still written is announced
//! with CAMERA_IMAGE_CAPTURED (where the vehicle was, where the view looked, the file's URL on
//! the head's HTTP server, the image's index) and remembered so a ground station can ask for it again.

use super::info::view_quaternion;
use super::{Cameras, FIRST_COMPONENT, IMAGES_KEPT, Shot, Taken, boot_ms};
use crate::autopilot::Outbox;
use crate::clock::utc_us;
use crate::state::capture::Geotag;
use crate::supervise::Locked;
use mavlink::dialects::common::{CAMERA_IMAGE_CAPTURED_DATA, MavBool, MavMessage};
use std::time::Instant;
use tracing::warn;

impl Cameras {
    /// Asks for the stills that are due.
    pub(super) fn shoot_due(&self, n: usize, now: Instant) {
        let Some(shooter) = &self.shooter else {
            return;
        };
        let state = self.state();
        for i in 0..n {
            let due = {
                let mut p = self.periodic();
                let cam = &mut p.cameras[i];
                match &mut cam.shooting {
                    Some(s) if s.next <= now => {
                        s.next = super::commands::next_after(now, s.interval);
                        if let Some(left) = &mut s.left {
                            *left -= 1;
                            if *left == 0 {
                                cam.shooting = None;
                            }
                        }
                        cam.pending += 1;
                        true
                    }
                    _ => false,
                }
            };
            if !due {
                continue;
            }
            let taken = Taken {
                time_utc_us: utc_us(),
                time_boot_ms: boot_ms(),
                state_q: view_quaternion(&state, i),
                position: state.vehicle.position,
            };
            let shots = self.shots.clone();
            let done = Box::new(move |file| {
                let shot = Shot {
                    camera: i,
                    taken,
                    file,
                };
                shots.locked().push(shot);
            });
            if let Err(e) = shooter.shoot(i, done) {
                warn!("camera {i}: no image: {e}");
                let mut p = self.periodic();
                p.cameras[i].pending -= 1;
                p.cameras[i].shooting = None;
            }
        }
    }

    /// Announces the stills written since the last tick.
    pub(super) fn deliver_shots(&self, out: &Outbox) {
        let shots: Vec<Shot> = std::mem::take(&mut *self.shots.locked());
        for shot in shots {
            let i = shot.camera;
            let t = shot.taken;
            let (url, ok) = match (&shot.file, self.streams().captures) {
                (Ok((path, _)), Some(captures)) => {
                    let name = path.file_name().unwrap_or_default().to_string_lossy();
                    (format!("{captures}{name}"), true)
                }
                (Ok((path, _)), None) => (format!("file://{}", path.display()), true),
                (Err(e), _) => {
                    warn!("camera {i}: image not written: {e}");
                    (String::new(), false)
                }
            };
            // Where the frame the still was drawn from was taken, when it was written; else
            // when it was asked for.
            let t = match &shot.file {
                Ok((_, tag)) => of_frame(tag),
                Err(_) => t,
            };
            let msg = {
                let mut p = self.periodic();
                let cam = &mut p.cameras[i];
                cam.pending = cam.pending.saturating_sub(1);
                let data = CAMERA_IMAGE_CAPTURED_DATA {
                    time_utc: t.time_utc_us,
                    time_boot_ms: t.time_boot_ms,
                    lat: (t.position.lat * 1e7).round() as i32,
                    lon: (t.position.lon * 1e7).round() as i32,
                    alt: (t.position.alt * 1e3).round() as i32,
                    relative_alt: (t.position.relative_alt * 1e3).round() as i32,
                    q: t.state_q,
                    image_index: cam.images.len() as i32,
                    camera_id: 0,
                    capture_result: if ok {
                        MavBool::MAV_BOOL_TRUE
                    } else {
                        MavBool::MAV_BOOL_FALSE
                    },
                    file_url: url.as_str().into(),
                };
                if ok && cam.images.len() < IMAGES_KEPT {
                    cam.images.push(data.clone());
                }
                MavMessage::CAMERA_IMAGE_CAPTURED(data)
            };
            out.send(FIRST_COMPONENT + i as u8, &msg);
        }
    }
}

/// What CAMERA_IMAGE_CAPTURED reports of a still drawn from a frame: the frame's time (on
/// this machine's boot clock too), the vehicle's position and the view's orientation then.
fn of_frame(tag: &Geotag) -> Taken {
    let age_ms = utc_us().saturating_sub(tag.unix_us) / 1000;
    let q = glam::DQuat::from_euler(
        glam::EulerRot::ZYX,
        tag.view.yaw,
        tag.view.pitch,
        tag.view.roll,
    );
    Taken {
        time_utc_us: tag.unix_us,
        time_boot_ms: boot_ms().saturating_sub(age_ms as u32),
        state_q: [q.w as f32, q.x as f32, q.y as f32, q.z as f32],
        position: tag.position,
    }
}
