//! A camera's settings as the camera protocol exposes them: PARAM_EXT_* parameters (layout,
//! overlay, lens, the view's crop mode, lock flags and control mode, the detection's sorting
//! mode and whether it runs, how the view shows a thermal sensor and how its picture is
//! coloured where there is one, and the camera mode), described for ground stations by a
//! camera definition file (the protocol's XML) that each camera offers over MAVLink FTP and
//! the head serves over HTTP. Every parameter is read from and written to the live state, so
//! a change over the DigiView protocol shows here and one made here shows there. The file's version is a checksum of its content: it changes
//! whenever the content does (another lens.cal, another DigiView), and ground stations fetch
//! it again.

use super::{Cameras, FIRST_COMPONENT, Permitted};
use crate::autopilot::Outbox;
use crate::modes::{LayoutMode, OverlayMode};
use crate::policy::Peer;
use crate::state::view::Op;
use crate::state::{Invalid, Refused, Settings, State, ThermalGain};
use crate::thermal::Palette;
use mavlink::dialects::common::{
    MavMessage, MavParamExtType, PARAM_EXT_ACK_DATA, PARAM_EXT_VALUE_DATA, ParamAck,
};

/// One parameter: its name (at most 16 characters), what the ground station shows, its
/// options (value, label).
struct Setting {
    name: &'static str,
    description: &'static str,
    options: Vec<(u8, String)>,
}

/// Options 0, 1, 2 ... named `names`.
fn named(names: &[&str]) -> Vec<(u8, String)> {
    names
        .iter()
        .enumerate()
        .map(|(i, n)| (i as u8, n.to_string()))
        .collect()
}

/// The parameters, in PARAM_EXT index order; LENS's options are lens.cal's lenses; THERMAL,
/// PALETTE, IR_GAIN and IR_ZOOM only with a thermal sensor.
fn settings(lenses: &[(u8, String)], thermal: bool) -> Vec<Setting> {
    let mut all = vec![
        Setting {
            name: "LAYOUT",
            description: "Layout",
            options: named(&[
                "1 view",
                "2 views stacked",
                "2 panoramas",
                "2 views + panorama",
                "4 views",
                "3 views + panorama",
                "Whole fisheye",
            ]),
        },
        Setting {
            name: "OVERLAY",
            description: "Detection tiles",
            options: named(&["None", "One tile", "Right", "Left", "Top", "Bottom"]),
        },
        Setting {
            name: "LENS",
            description: "Lens",
            options: lenses.to_vec(),
        },
        Setting {
            name: "CROP",
            description: "Projection",
            options: named(&[
                "Fisheye crop",
                "Rectilinear",
                "Panorama",
                "Rectified crop",
                "Whole fisheye",
            ]),
        },
        Setting {
            name: "LOCK",
            description: "Held in the world",
            options: named(&[
                "None",
                "Roll",
                "Pitch",
                "Roll, pitch",
                "Yaw",
                "Roll, yaw",
                "Pitch, yaw",
                "All axes",
            ]),
        },
        Setting {
            name: "CONTROL",
            description: "Steering",
            options: named(&["Pilot", "Directional", "Coordinate", "Pass"]),
        },
        Setting {
            name: "SORTING",
            description: "Tile order",
            options: named(&["Score", "Age", "Score, tiles held"]),
        },
        Setting {
            name: "DETECTION",
            description: "Detection",
            options: named(&["Off", "On"]),
        },
    ];
    if thermal {
        all.extend(thermal_settings());
    }
    // The camera protocol's own: MAVSDK and QGroundControl look for it in a definition.
    all.push(Setting {
        name: "CAM_MODE",
        description: "Camera mode",
        options: named(&["Photo", "Video"]),
    });
    all
}

/// The thermal sensor's: how the view shows it, and how its picture is coloured and zoomed.
fn thermal_settings() -> [Setting; 4] {
    [
        Setting {
            name: "THERMAL",
            description: "Thermal picture",
            options: named(&["Off", "Blended", "Picture in picture", "Thermal"]),
        },
        Setting {
            name: "PALETTE",
            description: "Thermal palette",
            options: named(&[
                "White hot",
                "Black hot",
                "Ironbow",
                "Rainbow",
                "Arctic",
                "Lava",
            ]),
        },
        Setting {
            name: "IR_GAIN",
            description: "Thermal gain",
            options: named(&["Automatic", "Fixed span"]),
        },
        Setting {
            name: "IR_ZOOM",
            description: "Thermal zoom",
            options: (1..=8).map(|z| (z, format!("{z}x"))).collect(),
        },
    ]
}

/// Whether `name` is one of the cameras' parameters.
pub fn is_setting(name: &str) -> bool {
    settings(&[], true).iter().any(|s| s.name == name)
}

/// A parameter's value in camera `i`'s state (CAM_MODE is the camera's own, not the state's).
fn value(s: &Settings, i: usize, name: &str) -> u8 {
    let c = &s.cameras[i];
    match name {
        "LAYOUT" => s.output.layout.code(),
        "OVERLAY" => s.output.overlay.code(),
        "LENS" => s.lens,
        "CROP" => c.crop().code(),
        "LOCK" => c.locks().0,
        "CONTROL" => c.control().code(),
        "THERMAL" => c.thermal().code(),
        "PALETTE" => s.thermal.palette.code(),
        "IR_GAIN" => s.thermal.gain as u8,
        "IR_ZOOM" => s.thermal.zoom,
        "SORTING" => s.detection.sorting_mode,
        _ => s.detection.run_ai as u8,
    }
}

/// What setting a parameter of camera `i` to `v` (one of its options, checked before; not
/// CAM_MODE) does: a view operation, or a change of the other settings.
enum Change {
    View(Op),
    /// Sets the value given.
    Other(fn(&mut Settings, u8) -> Result<(), Invalid>),
}

fn change_of(name: &str, v: u8) -> Change {
    let other = Change::Other;
    match name {
        "CROP" => Change::View(Op::Crop(v)),
        "LOCK" => Change::View(Op::Locks(v as f64)),
        "CONTROL" => Change::View(Op::Control(v)),
        "THERMAL" => Change::View(Op::Thermal(v)),
        "LAYOUT" => other(|s, v| {
            s.output.layout = LayoutMode::try_from(v).map_err(|e| Invalid(e.to_string()))?;
            Ok(())
        }),
        "OVERLAY" => other(|s, v| {
            s.output.overlay = OverlayMode::try_from(v).map_err(|e| Invalid(e.to_string()))?;
            Ok(())
        }),
        "LENS" => other(|s, v| {
            s.lens = v;
            Ok(())
        }),
        "PALETTE" => other(|s, v| {
            s.thermal.palette = Palette::try_from(v).map_err(|e| Invalid(e.to_string()))?;
            Ok(())
        }),
        "IR_GAIN" => other(|s, v| {
            s.thermal.gain = ThermalGain::try_from(v).map_err(|e| Invalid(e.to_string()))?;
            Ok(())
        }),
        "IR_ZOOM" => other(|s, v| {
            s.thermal.zoom = v;
            Ok(())
        }),
        "SORTING" => other(|s, v| {
            s.detection.sorting_mode = v;
            Ok(())
        }),
        _ => other(|s, v| {
            s.detection.run_ai = v == 1;
            Ok(())
        }),
    }
}

impl Cameras {
    /// A parameter's value for camera `i`: the state's, or the camera's own mode.
    fn value(&self, s: &State, i: usize, name: &str) -> u8 {
        match name {
            "CAM_MODE" => self.video_mode(i) as u8,
            _ => value(&s.settings, i, name),
        }
    }

    /// The parameters as this head has them (its lenses, its thermal sensor or none).
    fn all_settings(&self) -> Vec<Setting> {
        settings(&self.gate.settings().lenses().names(), self.has_thermal())
    }

    /// The camera definition file, and its version (never 0, which means "none").
    pub fn definition(&self) -> (String, u16) {
        let body = definition_body(&self.all_settings());
        let crc = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740).checksum(body.as_bytes());
        let version = crc.max(1);
        let xml = format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n<mavlinkcamera>\n  <definition \
             version=\"{version}\">\n    <model>virtual camera</model>\n    \
             <vendor>DigiView</vendor>\n  </definition>\n{body}</mavlinkcamera>\n"
        );
        (xml, version)
    }

    /// PARAM_EXT_REQUEST_LIST, _REQUEST_READ and _SET for camera `i` (a SET `permitted` or
    /// not, once for the message, by the policy).
    pub(super) fn parameter(
        &self,
        out: &Outbox,
        (peer, permitted): (Peer, Permitted),
        i: usize,
        msg: &MavMessage,
    ) {
        let all = self.all_settings();
        let component = FIRST_COMPONENT + i as u8;
        let value_of = |index: usize, s: &State| {
            let p = &all[index];
            MavMessage::PARAM_EXT_VALUE(PARAM_EXT_VALUE_DATA {
                param_count: all.len() as u16,
                param_index: index as u16,
                param_id: p.name.into(),
                param_value: encode(self.value(s, i, p.name)),
                param_type: PARAM_TYPE,
            })
        };
        let state = self.state();
        match msg {
            MavMessage::PARAM_EXT_REQUEST_LIST(_) => {
                for index in 0..all.len() {
                    out.send(component, &value_of(index, &state));
                }
            }
            MavMessage::PARAM_EXT_REQUEST_READ(r) => {
                let name = r.param_id.to_str().unwrap_or("");
                let index = match r.param_index {
                    -1 => all.iter().position(|p| p.name == name),
                    n => usize::try_from(n).ok().filter(|&n| n < all.len()),
                };
                if let Some(index) = index {
                    out.send(component, &value_of(index, &state));
                }
            }
            MavMessage::PARAM_EXT_SET(p) => {
                let name = p.param_id.to_str().unwrap_or("").to_string();
                let what = format!("PARAM_EXT_SET {name} of camera {i}");
                let result = match permitted {
                    Err(_) => ParamAck::PARAM_ACK_FAILED,
                    Ok(()) => {
                        match self.set_parameter(&all, i, &name, p.param_type, &p.param_value) {
                            Ok(()) => ParamAck::PARAM_ACK_ACCEPTED,
                            Err((ack, why)) => {
                                self.gate.policy().refusals.note(peer, &what, &why);
                                ack
                            }
                        }
                    }
                };
                let now = self.state();
                let shown = all
                    .iter()
                    .find(|s| s.name == name)
                    .map_or(0, |s| self.value(&now, i, s.name));
                out.send(
                    component,
                    &MavMessage::PARAM_EXT_ACK(PARAM_EXT_ACK_DATA {
                        param_id: p.param_id,
                        param_value: encode(shown),
                        param_type: PARAM_TYPE,
                        param_result: result,
                    }),
                );
            }
            _ => {}
        }
    }

    /// A PARAM_EXT_SET: a known parameter, a one-byte value, one of its options, and a state
    /// the one validation accepts; else the ACK's result and why.
    fn set_parameter(
        &self,
        all: &[Setting],
        i: usize,
        name: &str,
        kind: MavParamExtType,
        raw: &[u8; 128],
    ) -> Result<(), (ParamAck, String)> {
        let Some(setting) = all.iter().find(|s| s.name == name) else {
            return Err((ParamAck::PARAM_ACK_FAILED, format!("no parameter {name:?}")));
        };
        let v = raw[0];
        let one_byte = matches!(
            kind,
            MavParamExtType::MAV_PARAM_EXT_TYPE_UINT8 | MavParamExtType::MAV_PARAM_EXT_TYPE_INT8
        ) || raw[1..4].iter().all(|&b| b == 0);
        let unsupported = ParamAck::PARAM_ACK_VALUE_UNSUPPORTED;
        if !one_byte || !setting.options.iter().any(|o| o.0 == v) {
            return Err((unsupported, format!("{name} has no option {v}")));
        }
        if name == "CAM_MODE" {
            self.periodic().cameras[i].video_mode = v == 1;
            return Ok(());
        }
        let set = match change_of(name, v) {
            Change::View(op) => self.gate.steer(i, op),
            Change::Other(set) => self.gate.change(|s| set(s, v)).map_err(Refused::from),
        };
        set.map_err(|e| (unsupported, format!("{name} = {v}: {e}")))
    }
}

/// The type every parameter is told as. Their values are small options, but MAVSDK (4.0)
/// delivers a changed value only to an int32, float or text parameter and logs an error for
/// each other one; the first byte is the value either way, so a client that reads one byte
/// reads it right (docs/decisions.md, "Camera settings are int32").
const PARAM_TYPE: MavParamExtType = MavParamExtType::MAV_PARAM_EXT_TYPE_INT32;

/// A value as PARAM_EXT carries it: the little-endian bytes of an int32.
fn encode(v: u8) -> mavlink::types::CharArray<128> {
    let mut bytes = [0u8; 128];
    bytes[..4].copy_from_slice(&i32::from(v).to_le_bytes());
    bytes.into()
}

/// The `<parameters>` part of the definition file.
fn definition_body(all: &[Setting]) -> String {
    let mut x = String::from("  <parameters>\n");
    for p in all {
        x += &format!(
            "    <parameter name=\"{}\" type=\"int32\" default=\"{}\">\n      \
             <description>{}</description>\n      <options>\n",
            p.name,
            p.options.first().map_or(0, |o| o.0),
            escape(p.description)
        );
        for (v, label) in &p.options {
            x += &format!(
                "        <option name=\"{}\" value=\"{v}\" />\n",
                escape(label)
            );
        }
        x += "      </options>\n    </parameter>\n";
    }
    x + "  </parameters>\n"
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::rules::RULES;

    /// Each parameter a ground station sets offers the values the state's rule takes (the
    /// one table): all of them, but for the crop modes, where only the known ones are
    /// offered, and the lenses, which are lens.cal's.
    #[test]
    fn the_options_are_the_values_the_table_takes() {
        let lenses = [(0, "CIL216".to_string())];
        for s in settings(&lenses, true) {
            let key = match s.name {
                "LAYOUT" => "output.layout",
                "OVERLAY" => "output.overlay",
                "CROP" => "camera.crop",
                "LOCK" => "camera.lock",
                "CONTROL" => "camera.control",
                "THERMAL" => "camera.thermal",
                "PALETTE" => "thermal.palette",
                "IR_GAIN" => "thermal.gain",
                "IR_ZOOM" => "thermal.zoom",
                "SORTING" => "detection.sorting_mode",
                "DETECTION" => "detection.run_ai",
                _ => continue,
            };
            let rule = RULES.iter().find(|r| r.key == Some(key)).unwrap();
            let values: Vec<f64> = s.options.iter().map(|o| o.0 as f64).collect();
            assert!(
                values.iter().all(|&v| rule.holds(v)),
                "{}: {values:?}",
                s.name
            );
            if !matches!(s.name, "CROP" | "DETECTION") {
                let all: Vec<f64> = (rule.lo as u32..=rule.hi as u32).map(f64::from).collect();
                assert_eq!(values, all, "{}", s.name);
            }
        }
    }
}
