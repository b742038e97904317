//! What the payload component streams to the SDK: its status items (the SDK's own indices,
//! asked for with SET_MESSAGE_INTERVAL and sent as PARAM_VALUE with that index), and the
//! tracked objects as its detection packets (V2_EXTENSION, message type 0x4001, boxes in
//! 1920x1080 pixels). Both read the same state every other path reads.

use crate::cameras::{InPicture, PictureBox};
use mavlink::dialects::common::{MavParamType, PARAM_VALUE_DATA, V2_EXTENSION_DATA};
use std::time::{Duration, Instant};

/// The SDK's picture, in which its boxes are given and reported.
pub const SDK_WIDTH: f64 = 1920.0;
pub const SDK_HEIGHT: f64 = 1080.0;

/// The status items, by the SDK's index (`payloadSdkInterface.h`, PARAM_EO_ZOOM_LEVEL ..
/// PARAM_IR_TEMP_MEAN): their names, and whether DigiView has them.
pub const ITEMS: [(&str, bool); 28] = [
    ("EO_ZOOM", true),
    ("IR_ZOOM", false),
    ("LRF_RANGE", false),
    ("TRK_POS_X", true),
    ("TRK_POS_Y", true),
    ("TRK_POS_W", true),
    ("TRK_POS_H", true),
    ("TRK_STATUS", true),
    ("LRF_OFFSET_X", false),
    ("LRF_OFFSET_Y", false),
    ("TARGET_LON", true),
    ("TARGET_LAT", true),
    ("TARGET_ALT", true),
    ("PAY_LON", true),
    ("PAY_LAT", true),
    ("PAY_ALT", true),
    ("APP_VER_X", true),
    ("APP_VER_Y", true),
    ("APP_VER_Z", true),
    ("VIEW_MODE", true),
    ("REC_SRC", true),
    ("IR_TYPE", false),
    ("PALETTE_ID", false),
    ("FFC_MODE", false),
    ("GB_MODE", true),
    ("IR_TEMP_MAX", false),
    ("IR_TEMP_MIN", false),
    ("IR_TEMP_MEAN", false),
];

/// TRK_STATUS's values.
pub const TRACK_IDLE: f32 = 0.0;
pub const TRACK_TRACKED: f32 = 1.0;
pub const TRACK_LOST: f32 = 2.0;

/// The shortest interval an item is streamed at.
const FASTEST: Duration = Duration::from_millis(20);

/// The items streamed: each one's interval and when it went last.
#[derive(Default)]
pub struct Streaming {
    items: [Option<(Duration, Option<Instant>)>; 28],
}

impl Streaming {
    /// SET_MESSAGE_INTERVAL for item `index`, `interval_us` (0 or negative stops it): the
    /// item's name, or why it is refused.
    pub fn set(&mut self, index: f32, interval_us: f32) -> Result<&'static str, String> {
        let item = (index.fract() == 0.0 && index >= 0.0)
            .then_some(index as usize)
            .and_then(|i| ITEMS.get(i).map(|item| (i, item)));
        let Some((i, &(name, has))) = item else {
            return Err(format!("status item {index}: the SDK's items are 0 to 27"));
        };
        if !interval_us.is_finite() || interval_us <= 0.0 {
            self.items[i] = None;
            return Ok(name);
        }
        if !has {
            return Err(format!(
                "status item {i} ({name}): DigiView has no such sensor"
            ));
        }
        let every = Duration::from_micros(interval_us as u64).max(FASTEST);
        self.items[i] = Some((every, None));
        Ok(name)
    }

    /// The items due at `now`, marked sent.
    pub fn due(&mut self, now: Instant) -> Vec<usize> {
        let mut due = vec![];
        for (i, item) in self.items.iter_mut().enumerate() {
            if let Some((every, last)) = item
                && last.is_none_or(|t| now - t >= *every)
            {
                *last = Some(now);
                due.push(i);
            }
        }
        due
    }
}

/// Item `index`'s PARAM_VALUE.
pub fn item(index: usize, value: f32) -> PARAM_VALUE_DATA {
    let name = ITEMS.get(index).map_or("", |i| i.0);
    PARAM_VALUE_DATA {
        param_value: value,
        param_count: ITEMS.len() as u16,
        param_index: index as u16,
        param_id: name.into(),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    }
}

/// A box of a view's picture in the SDK's pixels: centre x, y, width, height.
pub fn sdk_box(b: &PictureBox) -> [f64; 4] {
    [
        b.centre.x * SDK_WIDTH,
        b.centre.y * SDK_HEIGHT,
        2.0 * b.half.x * SDK_WIDTH,
        2.0 * b.half.y * SDK_HEIGHT,
    ]
}

/// The detection packet's header: magic "GD", version 1.
const MAGIC: u16 = 0x4744;
const VERSION: u8 = 1;
/// V2_EXTENSION's message type for detections.
pub const DETECTIONS: u16 = 0x4001;
/// The most boxes a packet holds.
pub const MAX_BOXES: usize = 20;

/// The detection packet of `objects` (the first [`MAX_BOXES`]), numbered `frame_id`:
/// `detection_packet.h`'s layout, little-endian, each box's top left, width and height in
/// 1920x1080 pixels, its track id, a class (0: DigiView's movers have none) and confidence.
pub fn detections(frame_id: u32, objects: &[InPicture], to: (u8, u8)) -> V2_EXTENSION_DATA {
    let mut payload = [0u8; 249];
    let shown = &objects[..objects.len().min(MAX_BOXES)];
    payload[..2].copy_from_slice(&MAGIC.to_le_bytes());
    payload[2] = VERSION;
    payload[3] = shown.len() as u8;
    payload[4..8].copy_from_slice(&frame_id.to_le_bytes());
    for (k, o) in shown.iter().enumerate() {
        let [cx, cy, w, h] = sdk_box(&o.at);
        let px = |v: f64| v.round().clamp(0.0, u16::MAX as f64) as u16;
        let fields = [
            px(cx - w / 2.0),
            px(cy - h / 2.0),
            px(w),
            px(h),
            (o.id & 0xffff) as u16,
        ];
        let at = 8 + 12 * k;
        for (j, f) in fields.iter().enumerate() {
            payload[at + 2 * j..at + 2 * j + 2].copy_from_slice(&f.to_le_bytes());
        }
        payload[at + 10] = 0;
        payload[at + 11] = (o.score.min(100) as u32 * 255 / 100) as u8;
    }
    V2_EXTENSION_DATA {
        target_network: 0,
        target_system: to.0,
        target_component: to.1,
        message_type: DETECTIONS,
        payload,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    #[test]
    fn a_detection_packet_has_the_sdk_header_and_boxes() {
        let o = InPicture {
            id: 7,
            score: 100,
            label: "moving".into(),
            at: PictureBox {
                centre: DVec2::new(0.5, 0.5),
                half: DVec2::new(0.05, 0.1),
            },
        };
        let p = detections(3, &[o], (1, 193)).payload;
        let u16_at = |i: usize| u16::from_le_bytes([p[i], p[i + 1]]);
        assert_eq!((u16_at(0), p[2], p[3]), (0x4744, 1, 1));
        assert_eq!(u32::from_le_bytes([p[4], p[5], p[6], p[7]]), 3);
        // Top left 864, 432; 192 by 216; track 7; confidence 255.
        assert_eq!(
            (u16_at(8), u16_at(10), u16_at(12), u16_at(14)),
            (864, 432, 192, 216)
        );
        assert_eq!((u16_at(16), p[19]), (7, 255));
    }

    #[test]
    fn an_item_without_a_sensor_is_refused_and_zero_stops_any() {
        let mut s = Streaming::default();
        assert_eq!(s.set(7.0, 100_000.0), Ok("TRK_STATUS"));
        assert!(
            s.set(25.0, 100_000.0)
                .unwrap_err()
                .contains("no such sensor")
        );
        assert_eq!(s.set(25.0, 0.0), Ok("IR_TEMP_MAX"));
        assert!(s.set(28.0, 1.0).is_err());
        let now = Instant::now();
        assert_eq!(s.due(now), vec![7]);
        assert!(s.due(now).is_empty());
        s.set(7.0, -1.0).unwrap();
        assert!(s.due(now + Duration::from_secs(1)).is_empty());
    }
}
