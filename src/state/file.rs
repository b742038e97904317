//! State files: a [`State`] written as TOML (docs/cli.md shows one), angles in radians or
//! `"30deg"`, `[[camera]]` tables placed by their `id`. A bad file is an error that names the
//! file and line, or the field and its range.

use super::{
    Angles, Camera, DetectionSettings, Invalid, MAX_CAMERAS, Output, Sensor, Settings, State,
    ThermalLook, Tracked, Vehicle,
};
use crate::lens::LensCal;
use crate::units::line_of;
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use std::path::Path;

thread_local! {
    /// The lens names (and ids) a state file being parsed may name: `lens = "CIL018"`.
    static LENS_NAMES: RefCell<Vec<(String, u8)>> = const { RefCell::new(Vec::new()) };
}

/// A state file as written: the settings' sections and the state's own beside them, at the
/// top level.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(super) struct StateFile {
    output: Output,
    /// lens_id in lens.cal; a file may give the lens's name.
    #[serde(deserialize_with = "lens_id")]
    lens: u8,
    camera: Vec<Camera>,
    vehicle: Vehicle,
    mount: Angles,
    sensor: Sensor,
    detection: DetectionSettings,
    /// How the thermal picture is coloured.
    thermal: ThermalLook,
    tracked: Vec<Tracked>,
    time: f64,
}

impl Default for StateFile {
    fn default() -> Self {
        StateFile::from(State::default())
    }
}

impl From<StateFile> for State {
    fn from(f: StateFile) -> State {
        State {
            settings: Settings {
                output: f.output,
                lens: f.lens,
                cameras: f.camera,
                mount: f.mount,
                sensor: f.sensor,
                detection: f.detection,
                thermal: f.thermal,
            },
            vehicle: f.vehicle,
            tracked: f.tracked,
            time: f.time,
        }
    }
}

impl From<State> for StateFile {
    fn from(s: State) -> StateFile {
        let Settings {
            output,
            lens,
            cameras,
            mount,
            sensor,
            detection,
            thermal,
        } = s.settings;
        StateFile {
            output,
            lens,
            camera: cameras,
            vehicle: s.vehicle,
            mount,
            sensor,
            detection,
            thermal,
            tracked: s.tracked,
            time: s.time,
        }
    }
}

/// `lens`: a lens_id, or a lens's name in the lens.cal the file is read with.
fn lens_id<'de, D: serde::Deserializer<'de>>(d: D) -> Result<u8, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum IdOrName {
        Id(u8),
        Name(String),
    }
    match IdOrName::deserialize(d)
        .map_err(|_| serde::de::Error::custom("lens is a lens_id 0..=255 or a lens name"))?
    {
        IdOrName::Id(id) => Ok(id),
        IdOrName::Name(name) => LENS_NAMES.with_borrow(|names| {
            names
                .iter()
                .find(|(n, _)| n.eq_ignore_ascii_case(name.trim()))
                .map(|(_, id)| *id)
                .ok_or_else(|| {
                    let have: Vec<_> = names.iter().map(|(n, id)| format!("{n} ({id})")).collect();
                    serde::de::Error::custom(format!(
                        "lens `{name}` is not in lens.cal; it has {}",
                        have.join(", ")
                    ))
                })
        }),
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
    #[error("{path}: {source}")]
    Invalid { path: String, source: Invalid },
}

impl State {
    /// A state file; lens names in it are looked up in `cal`.
    pub fn load(path: &Path, cal: &LensCal) -> Result<State, StateError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| StateError::Io {
            path: shown.clone(),
            source,
        })?;
        State::parse(&text, &shown, cal)
    }

    /// Its fields are checked here; the lens and sensor crop by [`State::validate`].
    pub fn parse(text: &str, path: &str, cal: &LensCal) -> Result<State, StateError> {
        let names = cal.entries.iter().map(|e| (e.name.clone(), e.lens_id));
        LENS_NAMES.set(names.collect());
        let parsed = toml::from_str::<State>(text);
        LENS_NAMES.set(Vec::new());
        let mut state: State = parsed.map_err(|e| StateError::Parse {
            path: path.to_string(),
            line: e.span().map_or(1, |s| line_of(text, s.start)),
            message: e.message().trim().to_string(),
        })?;
        state.settings.output.even();
        if !gives_exposure(text) {
            // The default exposure fits the file's frame rate, as GENERAL_SETTINGS shortens it.
            let sensor = &mut state.settings.sensor;
            sensor.exposure_us = sensor.exposure_us.min(sensor.longest_exposure_us());
        }
        state
            .place_cameras()
            .and_then(|()| state.validate_fields())
            .map_err(|source| StateError::Invalid {
                path: path.to_string(),
                source,
            })?;
        Ok(state)
    }
}

/// Whether a (parsed) state file sets `[sensor] exposure_us` itself.
fn gives_exposure(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| {
        t.get("sensor")
            .and_then(|s| s.as_table())
            .is_some_and(|s| s.contains_key("exposure_us"))
    })
}

impl State {
    /// Puts `[[camera]]` tables at their ids and fills missing cameras with defaults.
    fn place_cameras(&mut self) -> Result<(), Invalid> {
        let given = std::mem::take(&mut self.settings.cameras);
        if given.len() > MAX_CAMERAS {
            return Err(Invalid(format!(
                "{} cameras given, at most {MAX_CAMERAS}",
                given.len()
            )));
        }
        let mut slots: Vec<Option<Camera>> = vec![None; MAX_CAMERAS];
        for (i, mut cam) in given.into_iter().enumerate() {
            let id = cam.id.take().unwrap_or(i);
            if id >= MAX_CAMERAS || slots[id].is_some() {
                return Err(Invalid(format!(
                    "camera id {id} is out of range (0..={}) or given twice",
                    MAX_CAMERAS - 1
                )));
            }
            slots[id] = Some(cam);
        }
        self.settings.cameras = slots
            .into_iter()
            .enumerate()
            .map(|(i, c)| c.unwrap_or_else(|| Camera::numbered(i)))
            .collect();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cal() -> LensCal {
        let text = include_str!("../../lens-cal/lens.cal");
        LensCal::parse(Path::new("lens.cal"), text).unwrap()
    }

    #[test]
    fn a_state_file_names_its_lens_by_id_or_by_name() {
        let s = State::parse("lens = \"cil018\"", "s.toml", &cal()).unwrap();
        assert_eq!(s.settings.lens, 1);
        let e = State::parse("\nlens = \"CIL999\"", "s.toml", &cal()).unwrap_err();
        let e = e.to_string();
        assert!(
            e.starts_with("s.toml:2: lens `CIL999` is not in lens.cal; it has CIL216 (0)"),
            "{e}"
        );
        let e = State::parse("lens = 1.5", "s.toml", &cal())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lens is a lens_id 0..=255 or a lens name"),
            "{e}"
        );
    }

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
            &cal(),
        )
        .unwrap();
        let c = &s.settings.cameras;
        assert_eq!(s.settings.lens, 2);
        assert_eq!(s.settings.output.layout, crate::modes::LayoutMode::One);
        assert_eq!(c.len(), 4);
        assert!((c[2].yaw() - 45f64.to_radians()).abs() < 1e-12);
        assert_eq!(c[2].fov(), 1.0);
        assert_eq!(c[1], Camera::numbered(1));
        assert!((s.vehicle.attitude.roll - 20f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn an_exposure_left_out_fits_the_frame_rate_and_one_given_is_checked() {
        let s = State::parse("[sensor]\nfps = 120\n", "s.toml", &cal()).unwrap();
        assert_eq!(s.settings.sensor.exposure_us, 8_333);
        let e = State::parse(
            "[sensor]\nfps = 120\nexposure_us = 10000\n",
            "s.toml",
            &cal(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("outside 1..=8333"), "{e}");
        let s = State::parse("[sensor]\nfps = 25\n", "s.toml", &cal()).unwrap();
        assert_eq!(s.settings.sensor.exposure_us, 10_000);
    }

    #[test]
    fn bad_state_files_name_the_line_or_the_field() {
        let err = |text| {
            State::parse(text, "s.toml", &cal())
                .unwrap_err()
                .to_string()
        };
        let e = err("[output]\nwidht = 3\n");
        assert!(e.starts_with("s.toml:2: unknown field `widht`"), "{e}");
        let e = err("[output]\nlayout = 9\n");
        assert_eq!(e, "s.toml:2: output layout 9 is outside 0..=6");
        let e = err("[[camera]]\nyaw = \"north\"\n");
        assert!(e.starts_with("s.toml:2: "), "{e}");
        let e = err("[[camera]]\nfov = \"200deg\"\n");
        assert!(e.contains("camera 0: fov 3.491 rad is outside"), "{e}");
    }
}
