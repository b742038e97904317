//! Everything an operator can set (what the control protocol reaches) plus the vehicle's
//! attitude, position and the camera mount: the input of every render.
//!
//! Read from a TOML state file (docs/cli.md shows one), overridden by command-line flags in
//! the same `key=value` form, and checked for range so a bad value is an error naming the
//! field, not a surprise in the picture.

use crate::geometry::ground::ray_to_target;
use crate::geometry::view::{LockFlags, aim, clamp_fov, crop, view_orientation};
use crate::geometry::{Euler, GeoPoint, GeoPosition};
use crate::units::{de_angle, parse_angle};
use glam::DMat3;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const MAX_CAMERAS: usize = 4;
/// The output sizes and frame rates VIDEO_OUTPUT allows (the seed's ranges).
pub const MIN_OUTPUT: (u32, u32) = (640, 480);
pub const MAX_OUTPUT: (u32, u32) = (1920, 1080);
pub const FPS_RANGE: (u32, u32) = (5, 30);

/// CAM_CONTROL_MODE values.
pub mod control {
    /// The view looks along the vehicle's nose (pilot view).
    pub const PILOT: u8 = 0;
    pub const DIRECTIONAL: u8 = 1;
    /// The view aims at its geographic target.
    pub const COORDINATE: u8 = 2;
    /// Pass: as directional.
    pub const PASS: u8 = 3;
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Output {
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    pub layout: u8,
    pub overlay: u8,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            width: 1920,
            height: 1080,
            fps: 30,
            layout: 4,
            overlay: 2,
        }
    }
}

/// One user-controlled camera (a view).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    /// Which camera this table sets (0..=3); by default the table's position in the list.
    #[serde(skip_serializing)]
    pub id: Option<usize>,
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    #[serde(deserialize_with = "de_angle")]
    pub roll: f64,
    /// Horizontal field of view.
    #[serde(deserialize_with = "de_angle")]
    pub fov: f64,
    /// The last CAM_ZOOM step applied.
    pub zoom: i8,
    pub crop: u8,
    pub lock: u8,
    /// 0 pilot, 1 directional, 2 coordinate (aims at `target`), 3 pass.
    pub control: u8,
    pub target: Option<GeoPoint>,
}

impl Camera {
    pub fn euler(&self) -> Euler {
        Euler::new(self.yaw, self.pitch, self.roll)
    }
    pub fn locks(&self) -> LockFlags {
        LockFlags(self.lock)
    }
    fn numbered(i: usize) -> Camera {
        Camera {
            id: None,
            yaw: (i as f64 * 90.0).to_radians(),
            pitch: (-30f64).to_radians(),
            roll: 0.0,
            fov: 90f64.to_radians(),
            zoom: 0,
            crop: crop::RECTILINEAR,
            lock: 7,
            control: control::DIRECTIONAL,
            target: None,
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera::numbered(0)
    }
}

/// Angles as written in a state file: radians or `"30deg"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Angles {
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    #[serde(deserialize_with = "de_angle")]
    pub roll: f64,
}

impl Angles {
    pub fn euler(&self) -> Euler {
        Euler::new(self.yaw, self.pitch, self.roll)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Vehicle {
    pub attitude: Angles,
    pub position: GeoPosition,
}

impl Default for Vehicle {
    fn default() -> Self {
        Vehicle {
            attitude: Angles::default(),
            position: DEFAULT_POSITION,
        }
    }
}

/// 50 m above a home at 100 m AMSL (the synthetic world's origin).
pub const DEFAULT_POSITION: GeoPosition = GeoPosition {
    lat: 58.0,
    lon: 15.0,
    alt: 150.0,
    relative_alt: 50.0,
};

/// The fisheye camera: its frame size and optional sensor crop (GENERAL_SETTINGS).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sensor {
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    /// Sensor crop [x, y, width, height] in pixels of the lens's calibration frame.
    pub roi: Option<[u32; 4]>,
    /// Automatic exposure (CAM_SENSOR).
    pub ae: bool,
    pub target_brightness: u8,
    /// Exposure in microseconds.
    pub exposure_us: u32,
    pub gain: u32,
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor {
            width: 3840,
            height: 2160,
            fps: 30,
            roi: None,
            ae: true,
            target_brightness: 128,
            exposure_us: 10_000,
            gain: 1_000,
        }
    }
}

/// A tracked object that gets a detection tile: its centre ray in the world and its angular size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tracked {
    pub id: u32,
    #[serde(deserialize_with = "de_angle")]
    pub yaw: f64,
    #[serde(deserialize_with = "de_angle")]
    pub pitch: f64,
    /// Angular diameter.
    #[serde(deserialize_with = "de_angle")]
    pub size: f64,
    pub score: u8,
}

impl Default for Tracked {
    fn default() -> Self {
        Tracked {
            id: 0,
            yaw: 0.0,
            pitch: -FRAC_PI_4,
            size: 0.05,
            score: 100,
        }
    }
}

/// How detections are kept and shown (DETECTION, and GENERAL_SETTINGS' run_ai). Field names
/// are the seed's; ratios are in [0, 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectionSettings {
    pub run_ai: bool,
    /// Unused by the seed; kept for GET.
    pub mode: u8,
    /// 0 by score, 1 by age, 2 by score with tiles locked to their object.
    pub sorting_mode: u8,
    pub crop_confidence_threshold: f64,
    pub var_confidence_threshold: f64,
    pub crop_box_limit: u16,
    pub var_box_limit: u16,
    pub crop_box_overlap: f64,
    pub var_box_overlap: f64,
    pub creation_score_scale: u8,
    pub bonus_detection_scale: u8,
    pub bonus_redetection_scale: u8,
    pub missed_detection_penalty: u8,
    pub missed_redetection_penalty: u8,
}

impl Default for DetectionSettings {
    fn default() -> Self {
        DetectionSettings {
            run_ai: true,
            mode: 0,
            sorting_mode: 0,
            crop_confidence_threshold: 0.5,
            var_confidence_threshold: 0.3,
            crop_box_limit: 100,
            var_box_limit: 100,
            crop_box_overlap: 0.5,
            var_box_overlap: 0.5,
            creation_score_scale: 50,
            bonus_detection_scale: 10,
            bonus_redetection_scale: 5,
            missed_detection_penalty: 10,
            missed_redetection_penalty: 5,
        }
    }
}

/// Ratios the seed accepts: [0, 0.99).
pub const RATIO_RANGE: std::ops::Range<f64> = 0.0..0.99;

const FRAC_PI_4: f64 = std::f64::consts::FRAC_PI_4;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct State {
    pub output: Output,
    /// lens_id in lens.cal (0 CIL216, 1 CIL018, 2 LN007).
    pub lens: u8,
    #[serde(rename = "camera")]
    pub cameras: Vec<Camera>,
    pub vehicle: Vehicle,
    pub mount: Angles,
    pub sensor: Sensor,
    pub detection: DetectionSettings,
    /// Tracked objects in the tracker's sorted order: the first ones get the overlay's tiles.
    #[serde(rename = "tracked")]
    pub tracked: Vec<Tracked>,
    /// Scene time in seconds (moves the synthetic world's objects).
    pub time: f64,
}

impl Default for State {
    fn default() -> Self {
        State {
            output: Output::default(),
            lens: 0,
            cameras: (0..MAX_CAMERAS).map(Camera::numbered).collect(),
            vehicle: Vehicle::default(),
            mount: Angles {
                yaw: 0.0,
                pitch: -std::f64::consts::FRAC_PI_2,
                roll: 0.0,
            },
            sensor: Sensor::default(),
            detection: DetectionSettings::default(),
            tracked: vec![],
            time: 0.0,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum StateError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {message}")]
    Parse {
        path: String,
        line: usize,
        message: String,
    },
    #[error("{0}")]
    Invalid(String),
}

impl State {
    pub fn load(path: &Path) -> Result<State, StateError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| StateError::Io {
            path: shown.clone(),
            source,
        })?;
        State::parse(&text, &shown)
    }

    pub fn parse(text: &str, path: &str) -> Result<State, StateError> {
        let mut state: State = toml::from_str(text).map_err(|e| StateError::Parse {
            path: path.to_string(),
            line: e
                .span()
                .map_or(1, |s| text[..s.start].matches('\n').count() + 1),
            message: e.message().trim().to_string(),
        })?;
        state.place_cameras()?;
        state
            .validate()
            .map_err(|e| StateError::Invalid(format!("{path}: {e}")))?;
        Ok(state)
    }

    /// Puts `[[camera]]` tables at their ids and fills missing cameras with defaults.
    fn place_cameras(&mut self) -> Result<(), StateError> {
        let given = std::mem::take(&mut self.cameras);
        if given.len() > MAX_CAMERAS {
            return Err(StateError::Invalid(format!(
                "{} cameras given, at most {MAX_CAMERAS}",
                given.len()
            )));
        }
        let mut slots: Vec<Option<Camera>> = vec![None; MAX_CAMERAS];
        for (i, cam) in given.into_iter().enumerate() {
            let id = cam.id.unwrap_or(i);
            if id >= MAX_CAMERAS || slots[id].is_some() {
                return Err(StateError::Invalid(format!(
                    "camera id {id} is out of range (0..=3) or given twice"
                )));
            }
            slots[id] = Some(Camera { id: None, ..cam });
        }
        self.cameras = slots
            .into_iter()
            .enumerate()
            .map(|(i, c)| c.unwrap_or_else(|| Camera::numbered(i)))
            .collect();
        Ok(())
    }

    /// Checks every field against the range the protocol allows.
    pub fn validate(&self) -> Result<(), String> {
        let o = &self.output;
        let (lo, hi) = (MIN_OUTPUT, MAX_OUTPUT);
        if !(lo.0..=hi.0).contains(&o.width) || !(lo.1..=hi.1).contains(&o.height) {
            return Err(format!(
                "output size {}x{} is outside {}x{}..={}x{}",
                o.width, o.height, lo.0, lo.1, hi.0, hi.1
            ));
        }
        if !(FPS_RANGE.0..=FPS_RANGE.1).contains(&o.fps) {
            return Err(format!(
                "output fps {} is outside {}..={}",
                o.fps, FPS_RANGE.0, FPS_RANGE.1
            ));
        }
        if o.layout > 6 {
            return Err(format!("layout {} does not exist (0..=6)", o.layout));
        }
        if o.overlay > 5 {
            return Err(format!("overlay {} does not exist (0..=5)", o.overlay));
        }
        for (i, c) in self.cameras.iter().enumerate() {
            if c.lock > 7 {
                return Err(format!(
                    "camera {i}: lock flags {} are outside 0..=7",
                    c.lock
                ));
            }
            if c.control > 3 {
                return Err(format!(
                    "camera {i}: control mode {} is outside 0..=3",
                    c.control
                ));
            }
            if clamp_fov(c.fov, c.crop) != c.fov && c.crop <= crop::DEBUG {
                let (lo, hi) = crate::geometry::view::fov_range(c.crop);
                return Err(format!(
                    "camera {i}: fov {:.3} rad is outside {lo}..={hi:.3} for crop mode {}",
                    c.fov, c.crop
                ));
            }
            if c.control == 2 && c.target.is_none() {
                return Err(format!(
                    "camera {i}: control mode 2 needs a target (lat, lon, alt)"
                ));
            }
        }
        let s = &self.sensor;
        if s.width == 0 || s.height == 0 {
            return Err("sensor size must be positive".into());
        }
        let d = &self.detection;
        for (name, v) in [
            ("crop_confidence_threshold", d.crop_confidence_threshold),
            ("var_confidence_threshold", d.var_confidence_threshold),
            ("crop_box_overlap", d.crop_box_overlap),
            ("var_box_overlap", d.var_box_overlap),
        ] {
            if !RATIO_RANGE.contains(&v) {
                return Err(format!("detection {name} {v} is outside [0, 0.99)"));
            }
        }
        if d.sorting_mode > 2 {
            return Err(format!(
                "detection sorting_mode {} is outside 0..=2",
                d.sorting_mode
            ));
        }
        let p = &self.vehicle.position;
        if !(-90.0..=90.0).contains(&p.lat) || !(-180.0..=180.0).contains(&p.lon) {
            return Err(format!(
                "vehicle position {}, {} is not a latitude, longitude",
                p.lat, p.lon
            ));
        }
        Ok(())
    }

    /// R_world_view of camera `i` by its control mode: pilot (0) looks along the vehicle's
    /// nose; coordinate (2) aims at its target, recomputed from the current position; the
    /// others compose the camera's angles with the vehicle's per the lock flags.
    pub fn world_from_view(&self, i: usize) -> DMat3 {
        let cam = &self.cameras[i];
        let vehicle = self.vehicle.attitude.euler();
        match (cam.control, cam.target) {
            (control::PILOT, _) => vehicle.matrix(),
            (control::COORDINATE, Some(target)) => {
                match ray_to_target(&self.vehicle.position, target) {
                    Some(ray) => view_orientation(
                        aim(ray, cam.euler(), cam.locks(), vehicle),
                        cam.locks(),
                        vehicle,
                    ),
                    None => view_orientation(cam.euler(), cam.locks(), vehicle),
                }
            }
            _ => view_orientation(cam.euler(), cam.locks(), vehicle),
        }
    }

    /// Applies `--cam 0:yaw=45deg,pitch=-30deg,fov=90deg,crop=1,lock=7`.
    pub fn apply_camera_flag(&mut self, flag: &str) -> Result<(), String> {
        let (id, pairs) = flag
            .split_once(':')
            .ok_or_else(|| format!("`{flag}`: expected N:key=value,..."))?;
        let id: usize = id
            .trim()
            .parse()
            .map_err(|_| format!("`{flag}`: camera id `{id}` is not a number"))?;
        let cam = self
            .cameras
            .get_mut(id)
            .ok_or_else(|| format!("`{flag}`: camera id {id} is outside 0..=3"))?;
        for (key, value) in key_values(pairs)? {
            match key {
                "yaw" => cam.yaw = parse_angle(value)?,
                "pitch" => cam.pitch = parse_angle(value)?,
                "roll" => cam.roll = parse_angle(value)?,
                "fov" => cam.fov = parse_angle(value)?,
                "zoom" => cam.zoom = number(key, value)?,
                "crop" => cam.crop = number(key, value)?,
                "lock" => cam.lock = number(key, value)?,
                "control" => cam.control = number(key, value)?,
                _ => {
                    return Err(format!(
                        "`{key}` is not a camera field (yaw, pitch, roll, fov, zoom, crop, lock, control)"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Applies `--attitude yaw=10deg,pitch=5deg,roll=20deg` (or `--mount ...`) to a triple.
    pub fn apply_angles(target: &mut Angles, flag: &str) -> Result<(), String> {
        for (key, value) in key_values(flag)? {
            match key {
                "yaw" => target.yaw = parse_angle(value)?,
                "pitch" => target.pitch = parse_angle(value)?,
                "roll" => target.roll = parse_angle(value)?,
                _ => return Err(format!("`{key}` is not an angle (yaw, pitch, roll)")),
            }
        }
        Ok(())
    }

    /// Applies `--position lat=58.0,lon=15.0,alt=150,rel=50`.
    pub fn apply_position(&mut self, flag: &str) -> Result<(), String> {
        let p = &mut self.vehicle.position;
        for (key, value) in key_values(flag)? {
            match key {
                "lat" => p.lat = number(key, value)?,
                "lon" => p.lon = number(key, value)?,
                "alt" => p.alt = number(key, value)?,
                "rel" | "relative_alt" => p.relative_alt = number(key, value)?,
                _ => {
                    return Err(format!(
                        "`{key}` is not a position field (lat, lon, alt, rel)"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Adds a tracked object from `--track yaw=10deg,pitch=-40deg,size=3deg,score=90`.
    pub fn add_tracked(&mut self, flag: &str) -> Result<(), String> {
        let mut t = Tracked {
            id: self.tracked.len() as u32,
            ..Tracked::default()
        };
        for (key, value) in key_values(flag)? {
            match key {
                "yaw" => t.yaw = parse_angle(value)?,
                "pitch" => t.pitch = parse_angle(value)?,
                "size" => t.size = parse_angle(value)?,
                "score" => t.score = number(key, value)?,
                "id" => t.id = number(key, value)?,
                _ => {
                    return Err(format!(
                        "`{key}` is not a tracked-object field (yaw, pitch, size, score, id)"
                    ));
                }
            }
        }
        self.tracked.push(t);
        Ok(())
    }
}

fn key_values(text: &str) -> Result<Vec<(&str, &str)>, String> {
    text.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|kv| {
            kv.split_once('=')
                .map(|(k, v)| (k.trim(), v.trim()))
                .ok_or_else(|| format!("`{kv}` is not key=value"))
        })
        .collect()
}

fn number<T: std::str::FromStr>(key: &str, value: &str) -> Result<T, String> {
    value
        .parse()
        .map_err(|_| format!("{key}=`{value}` is not a valid number here"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_file_reads_degrees_places_cameras_by_id_and_fills_the_rest() {
        let s = State::parse(
            r#"
            lens = 2
            [output]
            layout = 0
            [[camera]]
            id = 2
            yaw = "45deg"
            fov = 1.0
            [vehicle.attitude]
            roll = "20deg"
            "#,
            "s.toml",
        )
        .unwrap();
        assert_eq!(s.lens, 2);
        assert_eq!(s.output.layout, 0);
        assert_eq!(s.cameras.len(), 4);
        assert!((s.cameras[2].yaw - 45f64.to_radians()).abs() < 1e-12);
        assert_eq!(s.cameras[2].fov, 1.0);
        assert_eq!(s.cameras[1], Camera::numbered(1));
        assert!((s.vehicle.attitude.roll - 20f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn bad_state_files_name_the_line_or_the_field() {
        let err = |text| State::parse(text, "s.toml").unwrap_err().to_string();
        let e = err("[output]\nwidht = 3\n");
        assert!(e.starts_with("s.toml:2: unknown field `widht`"), "{e}");
        let e = err("[output]\nlayout = 9\n");
        assert_eq!(e, "s.toml: layout 9 does not exist (0..=6)");
        let e = err("[[camera]]\nyaw = \"north\"\n");
        assert!(e.starts_with("s.toml:2: "), "{e}");
        let e = err("[[camera]]\nfov = \"200deg\"\n");
        assert!(e.contains("camera 0: fov 3.491 rad is outside"), "{e}");
    }

    #[test]
    fn flags_override_fields_and_reject_unknown_keys() {
        let mut s = State::default();
        s.apply_camera_flag("1:yaw=10deg,crop=2,lock=3").unwrap();
        assert_eq!((s.cameras[1].crop, s.cameras[1].lock), (2, 3));
        assert!(
            s.apply_camera_flag("4:yaw=0")
                .unwrap_err()
                .contains("outside 0..=3")
        );
        assert!(
            s.apply_camera_flag("0:colour=red")
                .unwrap_err()
                .contains("not a camera field")
        );
        State::apply_angles(&mut s.vehicle.attitude, "roll=20deg,pitch=0.1").unwrap();
        assert_eq!(s.vehicle.attitude.pitch, 0.1);
        s.apply_position("lat=1,lon=2,alt=30,rel=20").unwrap();
        assert_eq!(s.vehicle.position.relative_alt, 20.0);
        s.add_tracked("yaw=5deg,size=2deg").unwrap();
        assert_eq!(s.tracked.len(), 1);
    }

    #[test]
    fn pilot_views_look_along_the_nose_and_coordinate_views_at_their_target() {
        let mut s = State::default();
        s.vehicle.attitude = Angles {
            yaw: 0.3,
            pitch: 0.1,
            roll: -0.2,
        };
        s.cameras[0].control = control::PILOT;
        let nose = s.world_from_view(0) * glam::DVec3::X;
        assert!((nose - s.vehicle.attitude.euler().matrix() * glam::DVec3::X).length() < 1e-12);
        // A target 100 m east on the ground, 50 m below: the view points at it.
        let target = crate::geometry::ground::from_ned(
            s.vehicle.position.point(),
            glam::DVec3::new(0.0, 100.0, 50.0),
        );
        s.cameras[1].control = control::COORDINATE;
        s.cameras[1].target = Some(target);
        let fwd = s.world_from_view(1) * glam::DVec3::X;
        assert!(
            (fwd - glam::DVec3::new(0.0, 100.0, 50.0).normalize()).length() < 1e-6,
            "{fwd}"
        );
    }
}
