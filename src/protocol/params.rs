//! The twenty parameter types of the control protocol as typed values, each declared once as
//! its list of (field, encoding) in protocol.md's order, so the offsets, the codec, the units
//! and the field names the command-line client accepts all come from that one list.

use super::wire::{
    Angle, BoundingBox, CoarseDegrees, DATA_LEN, Degrees, Fov, I8, I16, Kelvin, LayoutMode, Metres,
    Offset, Ratio, Reader, Seconds, Text, TextValue, U8, U16, U32, Unit, ViewBoxes, Views, Wire,
    Writer,
};
use serde::Serialize;

/// A field value the command line can set from a number.
pub trait FromNumber: Sized {
    fn from_number(v: f64) -> Option<Self>;
}

/// A field value read as a number (None: the field is not a number).
pub trait ToNumber {
    fn to_number(&self) -> Option<f64>;
}

macro_rules! from_integer {
    ($($t:ty),*) => {$(
        impl FromNumber for $t {
            fn from_number(v: f64) -> Option<$t> {
                (v.fract() == 0.0 && v >= <$t>::MIN as f64 && v <= <$t>::MAX as f64)
                    .then_some(v as $t)
            }
        }
        impl ToNumber for $t {
            fn to_number(&self) -> Option<f64> {
                Some(*self as f64)
            }
        }
    )*};
}
from_integer!(u8, i8, i16, u16, u32);

impl FromNumber for f64 {
    fn from_number(v: f64) -> Option<f64> {
        v.is_finite().then_some(v)
    }
}
impl ToNumber for f64 {
    fn to_number(&self) -> Option<f64> {
        Some(*self)
    }
}
macro_rules! not_a_number {
    ($($t:ty),*) => {$(
        impl ToNumber for $t {
            fn to_number(&self) -> Option<f64> {
                None
            }
        }
    )*};
}
not_a_number!(BoundingBox, ViewBoxes, TextValue);
impl FromNumber for BoundingBox {
    fn from_number(_: f64) -> Option<BoundingBox> {
        None
    }
}
impl FromNumber for ViewBoxes {
    fn from_number(_: f64) -> Option<ViewBoxes> {
        None
    }
}
impl FromNumber for TextValue {
    fn from_number(_: f64) -> Option<TextValue> {
        None
    }
}

macro_rules! wire_struct {
    ($(#[$doc:meta])* $name:ident { $($field:ident: $kind:ty),* $(,)? }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
        pub struct $name {
            $(pub $field: <$kind as Wire>::Value,)*
        }

        impl $name {
            /// Field names, units and sizes in bytes, in wire order.
            pub const FIELDS: &'static [Field] =
                &[$(Field {
                    name: stringify!($field),
                    unit: <$kind as Wire>::UNIT,
                    size: <$kind as Wire>::SIZE,
                }),*];

            fn encode(&self, w: &mut Writer) {
                $(<$kind as Wire>::put(w, self.$field);)*
            }

            fn decode(r: &mut Reader) -> Self {
                $name { $($field: <$kind as Wire>::get(r),)* }
            }

            fn field(&self, name: &str) -> Option<f64> {
                match name {
                    $(stringify!($field) => self.$field.to_number(),)*
                    _ => None,
                }
            }

            fn set_field(&mut self, name: &str, v: f64) -> Result<(), FieldError> {
                match name {
                    $(stringify!($field) => {
                        self.$field = FromNumber::from_number(v).ok_or(FieldError::Value)?;
                        Ok(())
                    })*
                    _ => Err(FieldError::Name),
                }
            }
        }
    };
}

/// One field of a parameter type's data, in wire order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    pub name: &'static str,
    pub unit: Unit,
    pub size: usize,
}

/// Why a field could not be set by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldError {
    /// No field of that name.
    Name,
    /// The number does not fit the field (or the field is not a number).
    Value,
}

wire_struct!(SystemStatus {
    status: U8,
    error: U8
});
wire_struct!(
    /// A SET reads only width..detection_overlay_mode; the rest is filled by a GET reply, with
    /// only the layout's views (their number in `layout_mode`'s high four bits on the wire).
    VideoOutput {
        width: U16,
        height: U16,
        fps: U8,
        layout_mode: LayoutMode,
        detection_overlay_mode: U8,
        views: Views,
        detection_overlay_box: BoundingBox,
        single_detection_size: U16,
    }
);
wire_struct!(Capture {
    flags: U8,
    images_captured: U16,
    videos_captured: U16,
});
wire_struct!(Detection {
    mode: U8,
    sorting_mode: U8,
    crop_confidence_threshold: Ratio,
    var_confidence_threshold: Ratio,
    crop_box_limit: U16,
    var_box_limit: U16,
    crop_box_overlap: Ratio,
    var_box_overlap: Ratio,
    creation_score_scale: U8,
    bonus_detection_scale: U8,
    bonus_redetection_scale: U8,
    missed_detection_penalty: U8,
    missed_redetection_penalty: U8,
});
wire_struct!(
    /// A GET reads only `index`.
    DetectedRoi {
        index: U8,
        score: U8,
        total_detections: U8,
        yaw_abs: Angle,
        pitch_abs: Angle,
        yaw_rel: Angle,
        pitch_rel: Angle,
        latitude: CoarseDegrees,
        longitude: CoarseDegrees,
        altitude: Metres,
        distance: Metres,
    }
);
wire_struct!(Lens { lens_id: U8 });
wire_struct!(CamEuler {
    cam_id: U8,
    is_delta: U8,
    yaw: Angle,
    pitch: Angle,
    roll: Angle,
});
wire_struct!(CamZoom {
    cam_id: U8,
    zoom: I8
});
wire_struct!(CamLockFlags {
    cam_id: U8,
    flags: U8
});
wire_struct!(CamControlMode {
    cam_id: U8,
    mode: U8
});
wire_struct!(CamCropMode {
    cam_id: U8,
    mode: U8
});
wire_struct!(
    /// A GET carries cam_id, x, y and frame_rel; the reply fills yaw and pitch.
    CamOffset {
        cam_id: U8,
        x: Offset,
        y: Offset,
        frame_rel: U8,
        yaw: Angle,
        pitch: Angle,
    }
);
wire_struct!(CamFov {
    cam_id: U8,
    fov: Fov
});
wire_struct!(
    /// A GET carries cam_id, x and y; the reply fills the target.
    CamTarget {
        cam_id: U8,
        x: Offset,
        y: Offset,
        t_latitude: Degrees,
        t_longitude: Degrees,
        t_altitude: Metres,
    }
);
wire_struct!(CamSensor {
    ae: U8,
    target_brightness: U8,
    exposure_value: U32,
    gain_value: U32,
});
wire_struct!(
    /// The extension: the fisheye camera's frame, sensor crop, fps and mount, and the detector.
    GeneralSettings {
        camera_width: U16,
        camera_height: U16,
        roi_width: U16,
        roi_height: U16,
        camera_fps: U8,
        mount_yaw: Angle,
        mount_pitch: Angle,
        mount_roll: Angle,
        run_ai: U8,
    }
);

wire_struct!(
    /// The extension (GET only): the autopilot link and its clock mapping. `link`: 0 off, 1
    /// opening, 2 open with no attitude yet, 3 attitude coming, 4 attitude stale. `clock`: 0
    /// no mapping yet, 1 from the stamps, 2 from the stamps with the drift fitted.
    /// `simulated`: 1 while the views follow the demo's simulated flight; `others`: how many
    /// other components sent attitude in the last 5 s (ignored), the newest of them named.
    Autopilot {
        link: U8,
        system_id: U8,
        component_id: U8,
        attitude_rate: U16,
        attitude_age: Seconds,
        clock: U8,
        clock_offset: Seconds,
        clock_drift_ppm: I16,
        clock_span: Seconds,
        timesync_trips: U8,
        link_delay_us: U32,
        messages: U32,
        unsigned: U32,
        simulated: U8,
        others: U8,
        other_system: U8,
        other_component: U8,
    }
);

wire_struct!(
    /// The extension (GET only): why this client's last refused request was refused, so a
    /// client can show the reason behind a DATA_ERROR or FORBIDDEN; empty when none was. A
    /// long reason comes in parts: the GET names the part, the reply how many there are.
    RefusalReason {
        part: U8,
        parts: U8,
        reason: Text,
    }
);

wire_struct!(
    /// The extension: how a thermal sensor's picture is coloured. `palette`: 0 white-hot, 1
    /// black-hot, 2 ironbow, 3 rainbow, 4 arctic, 5 lava; `gain`: 0 automatic, 1 the span
    /// from `span_low` to `span_high`; `blend`: the thermal colour's share of a blended pixel;
    /// `zoom`: 1 to 8 times, the thermal picture shown whole or inset.
    Thermal {
        palette: U8,
        gain: U8,
        span_low: Kelvin,
        span_high: Kelvin,
        blend: Ratio,
        zoom: U8,
    }
);
wire_struct!(
    /// The extension: how a view shows the thermal sensor. `show`: 0 not at all, 1 blended
    /// onto the view, 2 picture in picture, 3 the thermal picture alone.
    CamThermal {
        cam_id: U8,
        show: U8
    }
);

macro_rules! params {
    ($($variant:ident = $n:literal, $wire_name:literal, $settable:literal;)*) => {
        /// The param_type byte.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
        #[repr(u8)]
        pub enum ParamType {
            $($variant = $n,)*
        }

        /// A parameter type's data, typed.
        #[derive(Clone, Copy, Debug, PartialEq, Serialize)]
        #[serde(untagged)]
        pub enum Param {
            $($variant($variant),)*
        }

        impl ParamType {
            pub const ALL: &'static [ParamType] = &[$(ParamType::$variant),*];

            pub fn from_u8(n: u8) -> Option<ParamType> {
                match n {
                    $($n => Some(ParamType::$variant),)*
                    _ => None,
                }
            }

            /// The name as protocol.md writes it (`CAM_EULER`).
            pub fn name(self) -> &'static str {
                match self {
                    $(ParamType::$variant => $wire_name,)*
                }
            }

            /// Whether SET is allowed (SYSTEM_STATUS, DETECTED_ROI, AUTOPILOT and REFUSAL are GET
            /// only).
            pub fn settable(self) -> bool {
                match self {
                    $(ParamType::$variant => $settable,)*
                }
            }

            pub fn fields(self) -> &'static [Field] {
                match self {
                    $(ParamType::$variant => $variant::FIELDS,)*
                }
            }

            /// All fields zero.
            pub fn zeroed(self) -> Param {
                match self {
                    $(ParamType::$variant => Param::$variant($variant::default()),)*
                }
            }
        }

        impl Param {
            pub fn param_type(&self) -> ParamType {
                match self {
                    $(Param::$variant(_) => ParamType::$variant,)*
                }
            }

            pub fn encode(&self) -> [u8; DATA_LEN] {
                let mut data = [0u8; DATA_LEN];
                let w = &mut Writer::new(&mut data);
                match self {
                    $(Param::$variant(p) => p.encode(w),)*
                }
                data
            }

            /// Never fails: every 64 bytes are some value of every type.
            pub fn decode(param_type: ParamType, data: &[u8; DATA_LEN]) -> Param {
                let r = &mut Reader::new(data);
                match param_type {
                    $(ParamType::$variant => Param::$variant($variant::decode(r)),)*
                }
            }

            /// A field's value by its protocol name, where it is a number.
            pub fn field(&self, name: &str) -> Option<f64> {
                match self {
                    $(Param::$variant(p) => p.field(name),)*
                }
            }

            /// Sets a field by its protocol name (what `digiview ctl set` does).
            pub fn set_field(&mut self, name: &str, v: f64) -> Result<(), FieldError> {
                match self {
                    $(Param::$variant(p) => p.set_field(name, v),)*
                }
            }
        }
    };
}

params! {
    SystemStatus = 0, "SYSTEM_STATUS", false;
    VideoOutput = 1, "VIDEO_OUTPUT", true;
    Capture = 2, "CAPTURE", true;
    Detection = 3, "DETECTION", true;
    DetectedRoi = 4, "DETECTED_ROI", false;
    Lens = 5, "LENS", true;
    CamEuler = 6, "CAM_EULER", true;
    CamZoom = 7, "CAM_ZOOM", true;
    CamLockFlags = 8, "CAM_LOCK_FLAGS", true;
    CamControlMode = 9, "CAM_CONTROL_MODE", true;
    CamCropMode = 10, "CAM_CROP_MODE", true;
    CamOffset = 11, "CAM_OFFSET", true;
    CamFov = 12, "CAM_FOV", true;
    CamTarget = 13, "CAM_TARGET", true;
    CamSensor = 14, "CAM_SENSOR", true;
    GeneralSettings = 15, "GENERAL_SETTINGS", true;
    Autopilot = 16, "AUTOPILOT", false;
    RefusalReason = 17, "REFUSAL", false;
    Thermal = 18, "THERMAL", true;
    CamThermal = 19, "CAM_THERMAL", true;
}

impl ParamType {
    /// Per-camera types (6..=13, and the extension CAM_THERMAL) carry cam_id in data[0].
    pub fn per_camera(self) -> bool {
        matches!(self as u8, 6..=13 | 19)
    }

    /// Parses `CAM_EULER`, `cam_euler`, `cam-euler` or the number `6`.
    pub fn parse(text: &str) -> Option<ParamType> {
        let t = text.trim().replace('-', "_");
        if let Ok(n) = t.parse::<u8>() {
            return ParamType::from_u8(n);
        }
        ParamType::ALL
            .iter()
            .copied()
            .find(|p| p.name().eq_ignore_ascii_case(&t))
    }
}

impl Param {
    /// The camera a per-camera parameter addresses.
    pub fn cam_id(&self) -> Option<u8> {
        self.param_type().per_camera().then(|| self.encode()[0])
    }
}

impl std::fmt::Display for ParamType {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
