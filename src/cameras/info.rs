//! What a camera says about itself, built from the live state each time it is asked:
//! CAMERA_INFORMATION, CAMERA_SETTINGS, STORAGE_INFORMATION, CAMERA_CAPTURE_STATUS,
//! VIDEO_STREAM_INFORMATION and VIDEO_STREAM_STATUS, and the view's orientation.

use super::{Cameras, Streams, boot_ms};
use crate::geometry::ground::ground_point;
use crate::modes::ThermalShow;
use crate::state::State;
use crate::state::view::zoom;
use crate::supervise::Locked;
use glam::DQuat;
use mavlink::dialects::common::{
    CAMERA_CAPTURE_STATUS_DATA, CAMERA_FOV_STATUS_DATA, CAMERA_INFORMATION_DATA,
    CAMERA_SETTINGS_DATA, CameraCapFlags, CameraMode, MavMessage, STORAGE_INFORMATION_DATA,
    StorageStatus, StorageType, VIDEO_STREAM_INFORMATION_DATA, VIDEO_STREAM_STATUS_DATA,
    VideoStreamEncoding, VideoStreamStatusFlags, VideoStreamType,
};
use std::path::Path;

/// Stream 1 is the view's own stream, stream 2 the composed frame.
pub const VIEW_STREAM: u8 = 1;
pub const COMPOSED_STREAM: u8 = 2;

/// The streams told in answer to a request for stream `id`: that one, or for 0 (every stream)
/// the view's own first and again last. QGroundControl shows the first stream it hears of
/// and MAVSDK keeps the last, so both show the view; the composed frame is listed between
/// (docs/decisions.md, "Which stream a ground station shows").
fn told(id: u8) -> &'static [u8] {
    match id {
        VIEW_STREAM => &[VIEW_STREAM],
        COMPOSED_STREAM => &[COMPOSED_STREAM],
        _ => &[VIEW_STREAM, COMPOSED_STREAM, VIEW_STREAM],
    }
}

/// The gimbal of each camera: the camera component is its own gimbal manager and device.
pub const GIMBAL_DEVICE_ID: u8 = 1;

/// A fixed-size, zero-padded text field.
fn text<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let n = s.len().min(N);
    out[..n].copy_from_slice(&s.as_bytes()[..n]);
    out
}

/// `(Dev & 0xff) << 24 | patch << 16 | minor << 8 | major`, from the crate's version.
pub(super) fn firmware_version() -> u32 {
    let part = |s: &str| s.parse::<u32>().unwrap_or(0) & 0xff;
    part(env!("CARGO_PKG_VERSION_MAJOR"))
        | part(env!("CARGO_PKG_VERSION_MINOR")) << 8
        | part(env!("CARGO_PKG_VERSION_PATCH")) << 16
}

/// The view's orientation in the world (NED), MAVLink's (w, x, y, z).
pub fn view_quaternion(state: &State, i: usize) -> [f32; 4] {
    let v = &state.vehicle;
    let m = state.settings.cameras[i]
        .steering()
        .world_from_view(v.attitude.euler(), &v.position);
    let q = DQuat::from_mat3(&m).normalize();
    [q.w as f32, q.x as f32, q.y as f32, q.z as f32]
}

impl Cameras {
    pub(super) fn information(&self, state: &State, i: usize) -> MavMessage {
        let cam = &state.settings.cameras[i];
        let (w, h) = (self.cfg.width, self.cfg.height);
        // Over MAVLink FTP, which every ground station reaches (the HTTP server serves the
        // same file at /camera.xml for browsers and tools).
        let (uri, version) = (super::ftp::definition_uri(i), self.definition().1);
        MavMessage::CAMERA_INFORMATION(CAMERA_INFORMATION_DATA {
            time_boot_ms: boot_ms(),
            firmware_version: firmware_version(),
            focal_length: zoom::focal_length_mm(cam.fov()),
            sensor_size_h: zoom::SENSOR_WIDTH_MM as f32,
            sensor_size_v: (zoom::SENSOR_WIDTH_MM * h as f64 / w as f64) as f32,
            flags: CameraCapFlags::CAMERA_CAP_FLAGS_CAPTURE_VIDEO
                | CameraCapFlags::CAMERA_CAP_FLAGS_CAPTURE_IMAGE
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_BASIC_ZOOM
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_POINT
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_RECTANGLE
                | CameraCapFlags::CAMERA_CAP_FLAGS_HAS_TRACKING_GEO_STATUS
                | match self.has_thermal() {
                    true => CameraCapFlags::CAMERA_CAP_FLAGS_HAS_THERMAL_RANGE,
                    false => CameraCapFlags::empty(),
                },
            resolution_h: w as u16,
            resolution_v: h as u16,
            cam_definition_version: version,
            vendor_name: text("DigiView"),
            model_name: text(&format!("virtual camera {i}")),
            lens_id: state.settings.lens,
            cam_definition_uri: uri.as_str().into(),
            gimbal_device_id: self.gimbal_device_id(i),
            camera_device_id: 0,
        })
    }

    /// CAMERA_INFORMATION and, after it, the streams (as for a request of every stream): a
    /// ground station that has just found the camera has its stream at once. MAVSDK asks for
    /// the streams only every 20 s, so its apps would show none for that long.
    pub(super) fn introduction(&self, state: &State, i: usize) -> Vec<MavMessage> {
        let mut all = vec![self.information(state, i)];
        all.extend(self.stream_information(state, i, 0));
        all
    }

    /// CAMERA_FOV_STATUS: where the vehicle (the camera) is, where the view's centre ray
    /// meets the ground (INT32_MAX when it does not, within 10 km), the view's orientation
    /// and its horizontal and vertical fov, all from one state.
    pub(super) fn fov_status(&self, state: &State, i: usize) -> MavMessage {
        let cam = &state.settings.cameras[i];
        let v = &state.vehicle;
        let world_from_view = cam
            .steering()
            .world_from_view(v.attitude.euler(), &v.position);
        let e7 = |deg: f64| (deg * 1e7).round() as i32;
        let mm = |m: f64| (m * 1e3).round() as i32;
        let centre = ground_point(&v.position, world_from_view * glam::DVec3::X);
        let (w, h) = (self.cfg.width as f64, self.cfg.height as f64);
        let vfov = 2.0 * ((cam.fov() / 2.0).tan() * h / w).atan();
        MavMessage::CAMERA_FOV_STATUS(CAMERA_FOV_STATUS_DATA {
            time_boot_ms: boot_ms(),
            lat_camera: e7(v.position.lat),
            lon_camera: e7(v.position.lon),
            alt_camera: mm(v.position.alt),
            lat_image: centre.map_or(i32::MAX, |(g, _)| e7(g.lat)),
            lon_image: centre.map_or(i32::MAX, |(g, _)| e7(g.lon)),
            alt_image: centre.map_or(i32::MAX, |(g, _)| mm(g.alt)),
            q: view_quaternion(state, i),
            hfov: cam.fov().to_degrees() as f32,
            vfov: vfov.to_degrees() as f32,
            camera_device_id: 0,
        })
    }

    pub(super) fn settings(&self, state: &State, i: usize) -> MavMessage {
        let cam = &state.settings.cameras[i];
        MavMessage::CAMERA_SETTINGS(CAMERA_SETTINGS_DATA {
            time_boot_ms: boot_ms(),
            mode_id: if self.video_mode(i) {
                CameraMode::CAMERA_MODE_VIDEO
            } else {
                CameraMode::CAMERA_MODE_IMAGE
            },
            zoomLevel: zoom::level(cam.fov(), cam.crop()),
            focusLevel: f32::NAN,
            camera_device_id: 0,
        })
    }

    pub(super) fn storage(&self) -> MavMessage {
        let space = self.shooter.as_ref().and_then(|s| space_mib(s.dir()));
        let (total, available, status) = match space {
            Some((t, a)) => (t, a, StorageStatus::STORAGE_STATUS_READY),
            None => (0.0, 0.0, StorageStatus::STORAGE_STATUS_NOT_SUPPORTED),
        };
        MavMessage::STORAGE_INFORMATION(STORAGE_INFORMATION_DATA {
            time_boot_ms: boot_ms(),
            total_capacity: total,
            used_capacity: total - available,
            available_capacity: available,
            read_speed: f32::NAN,
            write_speed: f32::NAN,
            storage_id: 1,
            storage_count: 1,
            status,
            mavtype: StorageType::STORAGE_TYPE_OTHER,
            name: "captures".into(),
            ..Default::default()
        })
    }

    pub(super) fn capture_status(&self, i: usize) -> MavMessage {
        let available = self
            .shooter
            .as_ref()
            .and_then(|s| space_mib(s.dir()))
            .map_or(f32::NAN, |s| s.1);
        let p = self.periodic();
        let cam = &p.cameras[i];
        let interval = cam
            .shooting
            .as_ref()
            .map_or(0.0, |s| s.interval.as_secs_f32());
        // 0 idle, 1 capturing, 2 interval set and idle, 3 interval set and capturing.
        let image_status = (cam.pending > 0) as u8 | (cam.shooting.is_some() as u8) << 1;
        MavMessage::CAMERA_CAPTURE_STATUS(CAMERA_CAPTURE_STATUS_DATA {
            time_boot_ms: boot_ms(),
            image_interval: interval,
            recording_time_ms: self.recording_ms(i),
            available_capacity: available,
            image_status,
            video_status: self.recording(i) as u8,
            image_count: cam.images.len() as i32,
            camera_device_id: 0,
        })
    }

    /// VIDEO_STREAM_INFORMATION of stream `id` (0: both, in the order [`told`] gives).
    pub(super) fn stream_information(&self, state: &State, i: usize, id: u8) -> Vec<MavMessage> {
        let streams = self.streams();
        told(id)
            .iter()
            .map(|&s| {
                let d = self.stream(state, i, s, &streams);
                let name = match s {
                    VIEW_STREAM => format!("camera {i}"),
                    _ => "all views".to_string(),
                };
                let uri = match s {
                    VIEW_STREAM => format!("{}/cam{i}", streams.base),
                    _ => streams.base.clone(),
                };
                MavMessage::VIDEO_STREAM_INFORMATION(VIDEO_STREAM_INFORMATION_DATA {
                    framerate: d.framerate,
                    bitrate: d.bitrate,
                    flags: d.flags,
                    resolution_h: d.resolution_h,
                    resolution_v: d.resolution_v,
                    rotation: 0,
                    hfov: d.hfov,
                    stream_id: s,
                    count: 2,
                    mavtype: VideoStreamType::VIDEO_STREAM_TYPE_RTSP,
                    name: name.as_str().into(),
                    uri: uri.as_str().into(),
                    encoding: match streams.codec {
                        crate::stream::Codec::H264 => {
                            VideoStreamEncoding::VIDEO_STREAM_ENCODING_H264
                        }
                        crate::stream::Codec::H265 => {
                            VideoStreamEncoding::VIDEO_STREAM_ENCODING_H265
                        }
                    },
                    camera_device_id: 0,
                })
            })
            .collect()
    }

    /// VIDEO_STREAM_STATUS of stream `id` (0: both, in the order [`told`] gives).
    pub(super) fn stream_status(&self, state: &State, i: usize, id: u8) -> Vec<MavMessage> {
        let streams = self.streams();
        told(id)
            .iter()
            .map(|&s| MavMessage::VIDEO_STREAM_STATUS(self.stream(state, i, s, &streams)))
            .collect()
    }

    /// A stream's figures: the view's own at the configured size, or the composed frame.
    fn stream(
        &self,
        state: &State,
        i: usize,
        id: u8,
        streams: &Streams,
    ) -> VIDEO_STREAM_STATUS_DATA {
        let cam = &state.settings.cameras[i];
        let out = &state.settings.output;
        // The view's own stream showing the thermal picture alone is the thermal camera's,
        // as zoomed.
        let alone = id == VIEW_STREAM && cam.thermal() == ThermalShow::Thermal;
        let zoom = state.settings.thermal.zoom.max(1) as f64;
        let fov = match self.thermal_hfov() {
            Some(thermal) if alone => 2.0 * ((thermal / 2.0).tan() / zoom).atan(),
            _ => cam.fov(),
        };
        let (w, h, hfov) = match id {
            VIEW_STREAM => (self.cfg.width, self.cfg.height, fov.to_degrees()),
            // The composed frame shows many views: its hfov is that of the camera asked.
            _ => (out.width, out.height, fov.to_degrees()),
        };
        let mut flags = VideoStreamStatusFlags::VIDEO_STREAM_STATUS_FLAGS_RUNNING;
        if self.has_thermal() {
            flags |= VideoStreamStatusFlags::VIDEO_STREAM_STATUS_FLAGS_THERMAL_RANGE_ENABLED;
            // The view's own stream is the thermal picture while the view shows it alone.
            if alone {
                flags |= VideoStreamStatusFlags::VIDEO_STREAM_STATUS_FLAGS_THERMAL;
            }
        }
        // A view's own stream at the rate it really runs (a small machine draws the watched
        // views less often than the composed frame), once measured.
        let configured = out.fps as f32;
        let framerate = match id {
            VIEW_STREAM => self.gate.sensed().view_rate(i).map_or(configured, |r| {
                (r * 10.0).round().min(configured * 10.0) / 10.0
            }),
            _ => configured,
        };
        VIDEO_STREAM_STATUS_DATA {
            framerate,
            bitrate: streams.bitrate_kbps * 1000,
            flags,
            resolution_h: w as u16,
            resolution_v: h as u16,
            rotation: 0,
            hfov: hfov.round().min(360.0) as u16,
            stream_id: id,
            camera_device_id: 0,
        }
    }

    /// How long camera `i`'s recording has run, ms (0 when none runs).
    fn recording_ms(&self, i: usize) -> u32 {
        let mut since = self.recording_since.locked();
        match (self.recording(i), since[i]) {
            (true, Some(t)) => t.elapsed().as_millis() as u32,
            (true, None) => {
                since[i] = Some(std::time::Instant::now());
                0
            }
            (false, _) => {
                since[i] = None;
                0
            }
        }
    }
}

/// The total and available space of the file system holding `dir`, MiB.
pub fn space_mib(dir: &Path) -> Option<(f32, f32)> {
    let _ = std::fs::create_dir_all(dir);
    let s = rustix::fs::statvfs(dir).ok()?;
    let mib = |blocks: u64| (blocks.saturating_mul(s.f_frsize) as f64 / (1024.0 * 1024.0)) as f32;
    Some((mib(s.f_blocks), mib(s.f_bavail)))
}
