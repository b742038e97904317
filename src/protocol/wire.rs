//! Field encodings of the control protocol's 64-byte data area (protocol.md, "Field
//! encodings"): little-endian integers and the fixed-point forms of angles, fovs, offsets,
//! degrees, metres and ratios. Encoders round to the nearest integer and saturate.
//!
//! Each encoding is a marker type implementing [`Wire`], so a parameter struct is declared
//! once as a list of (field, encoding) and its codec, units and field names follow from it.

use serde::{Deserialize, Serialize};

/// The data area of a frame.
pub const DATA_LEN: usize = 64;

/// Writes fields one after another into the data area.
pub struct Writer<'a> {
    data: &'a mut [u8; DATA_LEN],
    at: usize,
}

impl<'a> Writer<'a> {
    pub fn new(data: &'a mut [u8; DATA_LEN]) -> Self {
        Writer { data, at: 0 }
    }
    fn put(&mut self, bytes: &[u8]) {
        self.data[self.at..self.at + bytes.len()].copy_from_slice(bytes);
        self.at += bytes.len();
    }
}

/// Reads fields one after another from the data area.
pub struct Reader<'a> {
    data: &'a [u8; DATA_LEN],
    at: usize,
}

impl<'a> Reader<'a> {
    pub fn new(data: &'a [u8; DATA_LEN]) -> Self {
        Reader { data, at: 0 }
    }
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let out = self.data[self.at..self.at + N].try_into().expect("N bytes");
        self.at += N;
        out
    }
}

/// How a field's value reads to a person, for the command-line client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    Integer,
    Radians,
    /// Latitude or longitude.
    Degrees,
    Metres,
    /// A ratio in [0, 1).
    Ratio,
    /// A normalized offset in [-1, 1].
    Offset,
    /// A bounding box or a list of them (GET only).
    Boxes,
    /// A duration or a clock's offset.
    Seconds,
    /// A temperature.
    Kelvin,
    /// UTF-8 text (GET only).
    Text,
}

/// One field encoding: its Rust value, its bytes and its unit.
pub trait Wire {
    type Value: Copy + Default + PartialEq + std::fmt::Debug + Serialize;
    const UNIT: Unit;
    /// Bytes on the wire.
    const SIZE: usize;
    fn put(w: &mut Writer, v: Self::Value);
    fn get(r: &mut Reader) -> Self::Value;
}

macro_rules! integer {
    ($name:ident, $t:ty) => {
        pub struct $name;
        impl Wire for $name {
            type Value = $t;
            const UNIT: Unit = Unit::Integer;
            const SIZE: usize = size_of::<$t>();
            fn put(w: &mut Writer, v: $t) {
                w.put(&v.to_le_bytes());
            }
            fn get(r: &mut Reader) -> $t {
                <$t>::from_le_bytes(r.take())
            }
        }
    };
}

integer!(U8, u8);
integer!(I8, i8);
integer!(I16, i16);
integer!(U16, u16);
integer!(U32, u32);

/// A fixed-point value: an integer of type `$int` holding `value * $scale`.
macro_rules! fixed {
    ($(#[$doc:meta])* $name:ident, $int:ty, $scale:expr, $unit:expr) => {
        $(#[$doc])*
        pub struct $name;
        impl $name {
            pub const SCALE: f64 = $scale;
        }
        impl Wire for $name {
            type Value = f64;
            const UNIT: Unit = $unit;
            const SIZE: usize = size_of::<$int>();
            fn put(w: &mut Writer, v: f64) {
                // `as` saturates at the integer's range and maps NaN to 0.
                let n = (v * $scale).round() as $int;
                w.put(&n.to_le_bytes());
            }
            fn get(r: &mut Reader) -> f64 {
                <$int>::from_le_bytes(r.take()) as f64 / $scale
            }
        }
    };
}

fixed!(
    /// Radians as i32 milliradians.
    Angle, i32, 1000.0, Unit::Radians
);
fixed!(
    /// A fov in radians as i16 milliradians.
    Fov, i16, 1000.0, Unit::Radians
);
fixed!(
    /// A normalized offset in [-1, 1] as i16 / 32767.
    Offset, i16, 32767.0, Unit::Offset
);
fixed!(
    /// Latitude or longitude in degrees as i32 microdegrees.
    Degrees, i32, 1e6, Unit::Degrees
);
fixed!(
    /// Latitude or longitude in degrees as i32 thousandths of a degree: DETECTED_ROI's, as
    /// DigiView's original header packs it (about 110 m a unit).
    CoarseDegrees, i32, 1000.0, Unit::Degrees
);
fixed!(
    /// Metres as i32 millimetres.
    Metres, i32, 1000.0, Unit::Metres
);
fixed!(
    /// Seconds as i32 milliseconds (about ±24 days).
    Seconds, i32, 1000.0, Unit::Seconds
);
fixed!(
    /// A temperature in kelvin as u16 tenths of a kelvin (0 to 6553.5 K).
    Kelvin, u16, 10.0, Unit::Kelvin
);
fixed!(
    /// A ratio in [0, 1) as u8 / 255.
    Ratio, u8, 255.0, Unit::Ratio
);

/// UTF-8 text, zero-padded: REFUSAL's reason, a part of it per frame.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct TextValue {
    bytes: [u8; TextValue::MAX],
}

impl TextValue {
    /// Bytes a frame carries (after REFUSAL's part and parts).
    pub const MAX: usize = DATA_LEN - 2;

    /// `text` up to [`TextValue::MAX`] bytes, cut at a character boundary.
    pub fn new(text: &str) -> TextValue {
        let mut bytes = [0u8; Self::MAX];
        let part = split_text(text, Self::MAX)[0];
        bytes[..part.len()].copy_from_slice(part.as_bytes());
        TextValue { bytes }
    }

    /// The text up to the first zero byte; invalid UTF-8 is replaced, never refused.
    pub fn text(&self) -> String {
        let end = self.bytes.iter().position(|&b| b == 0).unwrap_or(Self::MAX);
        String::from_utf8_lossy(&self.bytes[..end]).into_owned()
    }
}

/// `text` in parts of at most `max` bytes, cut at character boundaries; one empty part for
/// an empty text.
pub fn split_text(text: &str, max: usize) -> Vec<&str> {
    let mut parts = Vec::new();
    let mut rest = text;
    loop {
        let mut end = rest.len().min(max);
        while !rest.is_char_boundary(end) {
            end -= 1;
        }
        parts.push(&rest[..end]);
        rest = &rest[end..];
        if rest.is_empty() {
            return parts;
        }
    }
}

impl Default for TextValue {
    fn default() -> Self {
        TextValue {
            bytes: [0; Self::MAX],
        }
    }
}

impl std::fmt::Debug for TextValue {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{:?}", self.text())
    }
}

impl Serialize for TextValue {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.text())
    }
}

pub struct Text;

impl Wire for Text {
    type Value = TextValue;
    const UNIT: Unit = Unit::Text;
    const SIZE: usize = TextValue::MAX;
    fn put(w: &mut Writer, v: TextValue) {
        w.put(&v.bytes);
    }
    fn get(r: &mut Reader) -> TextValue {
        TextValue { bytes: r.take() }
    }
}

/// The seed's `bounding_box`: x, y, w, h as u16.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoundingBox {
    pub x: u16,
    pub y: u16,
    pub w: u16,
    pub h: u16,
}

impl Wire for BoundingBox {
    type Value = BoundingBox;
    const UNIT: Unit = Unit::Boxes;
    const SIZE: usize = 8;
    fn put(w: &mut Writer, v: BoundingBox) {
        for n in [v.x, v.y, v.w, v.h] {
            U16::put(w, n);
        }
    }
    fn get(r: &mut Reader) -> BoundingBox {
        BoundingBox {
            x: U16::get(r),
            y: U16::get(r),
            w: U16::get(r),
            h: U16::get(r),
        }
    }
}

/// Where VIDEO_OUTPUT's `layout_mode` byte is: its high four bits count the view boxes.
const LAYOUT_MODE_AT: usize = 5;

/// VIDEO_OUTPUT's `layout_mode`, as DigiView's original header packs it: the mode in the low
/// four bits. The high four hold the number of view boxes, which [`Views`] writes and reads;
/// a SET's high bits are ignored (protocol.md, "What the original header does").
pub struct LayoutMode;

impl Wire for LayoutMode {
    type Value = u8;
    const UNIT: Unit = Unit::Integer;
    const SIZE: usize = 1;
    fn put(w: &mut Writer, v: u8) {
        U8::put(w, v & 0x0F);
    }
    fn get(r: &mut Reader) -> u8 {
        U8::get(r) & 0x0F
    }
}

/// VIDEO_OUTPUT's view rectangles: as many as the layout shows, at most four.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ViewBoxes {
    len: u8,
    boxes: [BoundingBox; ViewBoxes::MAX],
}

impl ViewBoxes {
    pub const MAX: usize = 4;

    /// The first [`ViewBoxes::MAX`] of `boxes`.
    pub fn new(boxes: impl IntoIterator<Item = BoundingBox>) -> ViewBoxes {
        let mut v = ViewBoxes::default();
        for b in boxes.into_iter().take(Self::MAX) {
            v.boxes[v.len as usize] = b;
            v.len += 1;
        }
        v
    }
}

impl std::ops::Deref for ViewBoxes {
    type Target = [BoundingBox];
    fn deref(&self) -> &[BoundingBox] {
        &self.boxes[..self.len as usize]
    }
}

impl Serialize for ViewBoxes {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

/// VIDEO_OUTPUT's view boxes, packed as the original header packs them: only as many as the
/// layout shows, one after another, their number in the high four bits of `layout_mode`.
/// What follows them (the overlay box) moves up accordingly.
pub struct Views;

impl Wire for Views {
    type Value = ViewBoxes;
    const UNIT: Unit = Unit::Boxes;
    /// At most: four boxes.
    const SIZE: usize = 8 * ViewBoxes::MAX;
    fn put(w: &mut Writer, v: ViewBoxes) {
        w.data[LAYOUT_MODE_AT] = (w.data[LAYOUT_MODE_AT] & 0x0F) | (v.len() as u8) << 4;
        for b in v.iter() {
            BoundingBox::put(w, *b);
        }
    }
    fn get(r: &mut Reader) -> ViewBoxes {
        let n = (r.data[LAYOUT_MODE_AT] >> 4) as usize;
        ViewBoxes::new((0..n.min(ViewBoxes::MAX)).map(|_| BoundingBox::get(r)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip<W: Wire>(v: W::Value) -> (W::Value, [u8; DATA_LEN]) {
        let mut data = [0u8; DATA_LEN];
        W::put(&mut Writer::new(&mut data), v);
        (W::get(&mut Reader::new(&data)), data)
    }

    #[test]
    fn text_is_cut_at_character_boundaries_and_reads_back_whole() {
        let long = "é".repeat(40); // 80 bytes: two parts, the first 62 bytes (31 chars).
        let parts = split_text(&long, TextValue::MAX);
        assert_eq!(parts.iter().map(|p| p.len()).collect::<Vec<_>>(), [62, 18]);
        assert_eq!(parts.concat(), long);
        let (v, d) = round_trip::<Text>(TextValue::new(parts[0]));
        assert_eq!(v.text(), parts[0]);
        assert_eq!(&d[..2], "é".as_bytes());
        // A part ending mid-character.
        let odd = format!("a{long}");
        assert_eq!(split_text(&odd, TextValue::MAX)[0].len(), 61);
        assert_eq!(split_text("", 62), [""]);
    }

    #[test]
    fn fixed_point_rounds_to_nearest_and_saturates() {
        let (v, d) = round_trip::<Angle>(0.612_398);
        assert_eq!(i32::from_le_bytes(d[..4].try_into().unwrap()), 612);
        assert_eq!(v, 0.612);
        let (v, _) = round_trip::<Angle>(-0.0015);
        assert_eq!(v, -0.002, "ties round away from zero");
        let (v, _) = round_trip::<Fov>(100.0);
        assert_eq!(v, i16::MAX as f64 / 1000.0, "saturates at i16::MAX");
        let (v, _) = round_trip::<Ratio>(-0.5);
        assert_eq!(v, 0.0, "a ratio below zero saturates at 0");
        let (v, _) = round_trip::<Offset>(f64::NAN);
        assert_eq!(v, 0.0, "NaN encodes as zero");
        let (v, _) = round_trip::<Degrees>(58.123_456_7);
        assert!((v - 58.123_457).abs() < 1e-9);
    }

    #[test]
    fn every_decoded_value_encodes_back_to_the_same_integer() {
        for n in [i32::MIN, -1_234_567, -1, 0, 1, 999, i32::MAX] {
            let mut d = [0u8; DATA_LEN];
            d[..4].copy_from_slice(&n.to_le_bytes());
            let v = Degrees::get(&mut Reader::new(&d));
            let (_, back) = round_trip::<Degrees>(v);
            assert_eq!(back[..4], d[..4], "microdegrees {n}");
            let v = Angle::get(&mut Reader::new(&d));
            let (_, back) = round_trip::<Angle>(v);
            assert_eq!(back[..4], d[..4], "milliradians {n}");
        }
        for n in i16::MIN..=i16::MAX {
            let mut d = [0u8; DATA_LEN];
            d[..2].copy_from_slice(&n.to_le_bytes());
            let (_, back) = round_trip::<Offset>(Offset::get(&mut Reader::new(&d)));
            assert_eq!(back[..2], d[..2], "offset {n}");
        }
    }
}
