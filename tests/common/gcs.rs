//! A ground station written with the `mavlink` crate, as QGroundControl or a MAVSDK app
//! speaks to cameras: system 255, component 190 (MAV_COMP_ID_MISSIONPLANNER), a HEARTBEAT a
//! second, commands answered by COMMAND_ACK, everything heard kept in order for the test.

use digiview::control::client::Client;
use digiview::protocol::Param;
use digiview::protocol::params::{CamEuler, CamFov};
use mavlink::dialects::common::*;
use mavlink::{MavConnection, MavHeader};
use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub const SYSTEM: u8 = 255;
pub const REQUEST: MavCmd = MavCmd::MAV_CMD_REQUEST_MESSAGE;
const DEG: f64 = std::f64::consts::PI / 180.0;
pub const COMPONENT: u8 = 190;

pub struct Gcs {
    link: Arc<dyn MavConnection<MavMessage> + Send + Sync>,
    heard: Mutex<Receiver<(MavHeader, MavMessage)>>,
    stop: Arc<AtomicBool>,
}

impl Gcs {
    /// Talks to DigiView's link at `udpout:127.0.0.1:PORT`.
    pub fn connect(port: u16) -> Gcs {
        Gcs::connect_signed(port, None)
    }

    /// As [`Gcs::connect`], signing every message with `key` when given.
    pub fn connect_signed(port: u16, key: Option<[u8; 32]>) -> Gcs {
        let mut link = mavlink::connect::<MavMessage>(&format!("udpout:127.0.0.1:{port}"))
            .expect("the ground station's link");
        link.setup_signing(key.map(|k| mavlink::SigningConfig::new(k, 0, true, false)));
        let link: Arc<dyn MavConnection<MavMessage> + Send + Sync> = Arc::from(link);
        let (tx, rx) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        {
            let link = link.clone();
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    match link.recv() {
                        Ok(m) => {
                            if tx.send(m).is_err() {
                                break;
                            }
                        }
                        // A datagram sent while DigiView's port was closed (its link
                        // restarting) comes back as "connection refused" on the next
                        // read: a ground station goes on listening.
                        Err(mavlink::error::MessageReadError::Io(e))
                            if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                        Err(mavlink::error::MessageReadError::Io(_)) => break,
                        Err(_) => {}
                    }
                }
            });
        }
        {
            let link = link.clone();
            let stop = stop.clone();
            std::thread::spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let beat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                        mavtype: MavType::MAV_TYPE_GCS,
                        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                        system_status: MavState::MAV_STATE_ACTIVE,
                        mavlink_version: 3,
                        ..Default::default()
                    });
                    let _ = link.send(&header(), &beat);
                    std::thread::sleep(Duration::from_secs(1));
                }
            });
        }
        Gcs {
            link,
            heard: Mutex::new(rx),
            stop,
        }
    }

    /// A file read over MAVLink FTP from `component`: OpenFileRO, ReadFile to its size,
    /// TerminateSession.
    pub fn ftp_read(&self, system: u8, component: u8, path: &str) -> Vec<u8> {
        let mut seq = 0u16;
        let mut ask = |opcode: u8, offset: u32, size: u8, body: &[u8]| -> [u8; 251] {
            let mut p = [0u8; 251];
            seq += 1;
            p[..2].copy_from_slice(&seq.to_le_bytes());
            (p[3], p[4]) = (opcode, size);
            p[8..12].copy_from_slice(&offset.to_le_bytes());
            p[12..12 + body.len()].copy_from_slice(body);
            self.forget();
            self.send(&MavMessage::FILE_TRANSFER_PROTOCOL(
                FILE_TRANSFER_PROTOCOL_DATA {
                    target_network: 0,
                    target_system: system,
                    target_component: component,
                    payload: p,
                },
            ));
            let reply = self
                .wait_for(Duration::from_secs(3), |h, m| match m {
                    MavMessage::FILE_TRANSFER_PROTOCOL(f) if h.component_id == component => {
                        Some(f.payload)
                    }
                    _ => None,
                })
                .expect("an FTP answer");
            assert_eq!(
                (reply[3], reply[5]),
                (128, opcode),
                "ACK of {opcode}: {reply:?}"
            );
            reply
        };
        let open = ask(4, 0, path.len() as u8, path.as_bytes());
        let size = u32::from_le_bytes(open[12..16].try_into().unwrap()) as usize;
        let mut file = vec![];
        while file.len() < size {
            let r = ask(5, file.len() as u32, 239, &[]);
            file.extend_from_slice(&r[12..12 + r[4] as usize]);
        }
        ask(1, 0, 0, &[]);
        file
    }

    pub fn send(&self, msg: &MavMessage) {
        self.link.send(&header(), msg).unwrap();
    }

    /// Drops everything heard so far.
    pub fn forget(&self) {
        let rx = self.heard.lock().unwrap();
        while rx.try_recv().is_ok() {}
    }

    /// The first message within `limit` for which `pick` gives something.
    pub fn wait_for<T>(
        &self,
        limit: Duration,
        mut pick: impl FnMut(&MavHeader, &MavMessage) -> Option<T>,
    ) -> Option<T> {
        let rx = self.heard.lock().unwrap();
        let end = Instant::now() + limit;
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            match rx.recv_timeout(left) {
                Ok((h, m)) => {
                    if let Some(t) = pick(&h, &m) {
                        return Some(t);
                    }
                }
                Err(_) => return None,
            }
        }
        None
    }

    /// Everything heard within `limit`.
    pub fn collect(&self, limit: Duration) -> Vec<(MavHeader, MavMessage)> {
        let mut all = vec![];
        self.wait_for::<()>(limit, |h, m| {
            all.push((*h, m.clone()));
            None
        });
        all
    }

    /// Sends COMMAND_LONG `command` to `(system, component)` and returns its ACK's result and
    /// the messages from that component that came after the ACK within 0.5 s (None: no ACK
    /// within 3 s).
    pub fn command(
        &self,
        system: u8,
        component: u8,
        command: MavCmd,
        params: [f32; 7],
    ) -> Option<(MavResult, Vec<MavMessage>)> {
        self.forget();
        self.send_command(system, component, command, params);
        let result = self.wait_for(Duration::from_secs(3), |h, m| match m {
            MavMessage::COMMAND_ACK(a) if h.component_id == component && a.command == command => {
                Some(a.result)
            }
            _ => None,
        })?;
        let after = self
            .collect(Duration::from_millis(500))
            .into_iter()
            .filter(|(h, m)| {
                h.component_id == component
                    && !matches!(
                        m,
                        MavMessage::HEARTBEAT(_)
                            | MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_)
                            | MavMessage::GIMBAL_MANAGER_STATUS(_)
                    )
            })
            .map(|(_, m)| m)
            .collect();
        Some((result, after))
    }

    /// Sends COMMAND_LONG `command` to `(system, component)` and nothing more: what was heard
    /// before stays to be read.
    pub fn send_command(&self, system: u8, component: u8, command: MavCmd, params: [f32; 7]) {
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: system,
            target_component: component,
            command,
            param1: params[0],
            param2: params[1],
            param3: params[2],
            param4: params[3],
            param5: params[4],
            param6: params[5],
            param7: params[6],
            confirmation: 0,
        }));
    }
}

impl Drop for Gcs {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn header() -> MavHeader {
    MavHeader {
        system_id: SYSTEM.into(),
        component_id: COMPONENT,
        sequence: 0,
    }
}

/// A NUL-padded text field as a string.
pub fn text(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

/// The system and component ids of the cameras heard within 5 s.
pub fn cameras(gcs: &Gcs) -> (u8, BTreeSet<u8>) {
    let mut seen = BTreeSet::new();
    let mut system = 0;
    gcs.wait_for(Duration::from_secs(5), |h, m| {
        if let MavMessage::HEARTBEAT(b) = m
            && b.mavtype == MavType::MAV_TYPE_CAMERA
        {
            seen.insert(h.component_id);
            system = h.system_id as u8;
        }
        (seen.len() == 4).then_some(())
    });
    (system, seen)
}

/// IMAGE_START_CAPTURE of `count` images `interval` s apart on camera `component`, and the
/// CAMERA_IMAGE_CAPTURED of each, in the order they came (within 15 s).
pub fn image_capture(
    gcs: &Gcs,
    (system, component): (u8, u8),
    count: usize,
    interval: f32,
) -> Vec<CAMERA_IMAGE_CAPTURED_DATA> {
    let start = MavCmd::MAV_CMD_IMAGE_START_CAPTURE;
    let then = accepted(
        gcs.command(
            system,
            component,
            start,
            params(&[0.0, interval, count as f32]),
        ),
        "image capture",
    );
    let mut images: Vec<_> = then
        .into_iter()
        .filter_map(|m| match m {
            MavMessage::CAMERA_IMAGE_CAPTURED(c) => Some(c),
            _ => None,
        })
        .collect();
    gcs.wait_for(Duration::from_secs(15), |h, m| {
        if let MavMessage::CAMERA_IMAGE_CAPTURED(c) = m
            && h.component_id == component
        {
            images.push(c.clone());
        }
        (images.len() == count).then_some(())
    });
    assert_eq!(images.len(), count, "CAMERA_IMAGE_CAPTURED of every image");
    images
}

pub fn params(p: &[f32]) -> [f32; 7] {
    let mut all = [0.0; 7];
    all[..p.len()].copy_from_slice(p);
    all
}

/// CAM_EULER (yaw, pitch, roll) of camera `cam`, degrees.
pub fn euler(ctl: &mut Client, cam: u8) -> (f64, f64, f64) {
    match ctl
        .get_one(Param::CamEuler(CamEuler {
            cam_id: cam,
            ..Default::default()
        }))
        .unwrap()
    {
        Param::CamEuler(e) => (e.yaw / DEG, e.pitch / DEG, e.roll / DEG),
        other => panic!("{other:?}"),
    }
}

pub fn fov(ctl: &mut Client, cam: u8) -> f64 {
    match ctl
        .get_one(Param::CamFov(CamFov {
            cam_id: cam,
            ..Default::default()
        }))
        .unwrap()
    {
        Param::CamFov(f) => f.fov / DEG,
        other => panic!("{other:?}"),
    }
}

pub fn accepted(answer: Option<(MavResult, Vec<MavMessage>)>, what: &str) -> Vec<MavMessage> {
    let (result, then) = answer.unwrap_or_else(|| panic!("{what}: no COMMAND_ACK"));
    assert_eq!(result, MavResult::MAV_RESULT_ACCEPTED, "{what}");
    then
}

/// An HTTP GET of `url` (`http://HOST:PORT/PATH`) with std alone: the status and the body.
pub fn http_get(url: &str) -> (u16, Vec<u8>) {
    http_get_as(url, None)
}

/// As [`http_get`], with an `Authorization` header when given.
pub fn http_get_as(url: &str, authorization: Option<&str>) -> (u16, Vec<u8>) {
    use std::io::{Read, Write};
    let rest = url.strip_prefix("http://").unwrap();
    let (host, path) = rest.split_at(rest.find('/').unwrap());
    let mut s = std::net::TcpStream::connect(host).unwrap_or_else(|e| panic!("{url}: {e}"));
    let auth = authorization.map_or(String::new(), |a| format!("Authorization: {a}\r\n"));
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\n{auth}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = vec![];
    s.read_to_end(&mut reply).unwrap();
    let status = String::from_utf8_lossy(&reply[9..12]).parse().unwrap();
    let head = reply.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    (status, reply[head + 4..].to_vec())
}

/// DETECTED_ROI 255 through the web API at `http` (`http://HOST:PORT/`): each object reported,
/// its label, world direction and score.
pub fn reported(http: &str) -> Vec<(String, glam::DVec3, u64)> {
    let (code, body) = http_get(&format!("{http}api/params"));
    assert_eq!(code, 200);
    let all: serde_json::Value = serde_json::from_slice(&body).unwrap();
    all["DETECTED_ROI"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["total_detections"].as_u64() != Some(0))
        .map(|d| {
            let n = |k: &str| d[k].as_f64().unwrap();
            (
                d["label"].as_str().unwrap_or("").to_string(),
                digiview::geometry::rotation::direction(n("yaw_abs"), n("pitch_abs")),
                d["score"].as_u64().unwrap(),
            )
        })
        .collect()
}
