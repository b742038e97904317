//! Building a SET from named fields, as people and scripts give them: `digiview ctl set`
//! (`fov=30deg`) and the web API (`{"fov": "30deg"}`) both go through here, so a field name,
//! an angle's unit or a value that does not fit is refused alike on every path.

use super::{Param, ParamType, Unit};

/// One field's value as given: a number, or text (an angle with its unit, `30deg`).
#[derive(Clone, Copy, Debug)]
pub enum Given<'a> {
    Number(f64),
    Text(&'a str),
}

/// Why a field could not be set; the text names the field and what it takes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct EditError(pub String);

/// Whether a SET of `kind` starts from the current values (so fields left out keep them),
/// rather than from zeros: the types whose every field is a setting. A relative CAM_EULER
/// (`is_delta`) starts from zeros, since its fields are steps.
pub fn reads_first(kind: ParamType, is_delta: bool) -> bool {
    match kind {
        ParamType::VideoOutput
        | ParamType::Detection
        | ParamType::CamSensor
        | ParamType::GeneralSettings
        | ParamType::Thermal => true,
        ParamType::CamEuler => !is_delta,
        _ => false,
    }
}

/// Sets field `key` (`cam` is short for `cam_id`) of `p` to `value`.
pub fn set(p: &mut Param, key: &str, value: Given) -> Result<(), EditError> {
    let kind = p.param_type();
    let key = match key.trim() {
        "cam" => "cam_id",
        k => k,
    };
    let Some(field) = kind.fields().iter().find(|f| f.name == key) else {
        let names: Vec<_> = kind.fields().iter().map(|f| f.name).collect();
        return Err(EditError(format!(
            "{kind} has no field `{key}`; its fields: {}",
            names.join(", ")
        )));
    };
    let v = match (field.unit, value) {
        (Unit::Boxes | Unit::Text, _) => {
            return Err(EditError(format!(
                "{kind} {key} is reported by GET; it cannot be sent"
            )));
        }
        (Unit::Radians, Given::Text(t)) => {
            crate::units::parse_angle(t).map_err(|e| EditError(format!("{key}: {e}")))?
        }
        (_, Given::Number(n)) if n.is_finite() => n,
        (_, Given::Text(t)) => t
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| EditError(format!("{key}=`{t}` is not a number")))?,
        (_, Given::Number(n)) => return Err(EditError(format!("{key}={n} is not a number"))),
    };
    p.set_field(key, v).map_err(|_| {
        EditError(format!(
            "{key}={v} does not fit the field (`digiview ctl params {kind}` lists them)"
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_take_numbers_angles_with_units_and_refuse_what_does_not_fit() {
        let mut p = ParamType::CamFov.zeroed();
        set(&mut p, "cam", Given::Number(2.0)).unwrap();
        set(&mut p, "fov", Given::Text("90deg")).unwrap();
        let Param::CamFov(f) = p else { unreachable!() };
        assert_eq!(f.cam_id, 2);
        assert!((f.fov - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let e = set(&mut p, "zoom", Given::Number(1.0)).unwrap_err();
        assert_eq!(e.0, "CAM_FOV has no field `zoom`; its fields: cam_id, fov");
        let e = set(&mut p, "cam_id", Given::Number(300.0)).unwrap_err();
        assert!(e.0.starts_with("cam_id=300 does not fit the field"), "{e}");
        let e = set(&mut p, "fov", Given::Text("wide")).unwrap_err();
        assert!(e.0.starts_with("fov: "), "{e}");
        let mut v = ParamType::VideoOutput.zeroed();
        let e = set(&mut v, "views", Given::Number(1.0)).unwrap_err();
        assert!(e.0.contains("reported by GET"), "{e}");
    }
}
