//! The tracked objects a view shows, as an ST 0903 (VMTI) local set nested in ST 0601's tag
//! 74: the frame's size, the view's fields of view and, per object, its id, its centre and box
//! in the frame's pixels, its score, its class (an ontology entry per distinct label) and
//! where it stands on the ground. Nested, the set has no key and no checksum of its own (the
//! ST 0601 packet's covers it); numbers are ST 1201's IMAPB where the standard says so.

use super::LocalSet;
use crate::geometry::GeoPoint;

/// The ST 0903 revision the sets follow (its tag 4).
pub const VERSION: u8 = 6;
/// The ontology DigiView's classes are entries of (tag 103's IRIs): its detectors' labels.
pub const ONTOLOGY: &str = "urn:digiview:detector-classes";

/// One tracked object as a view's frame shows it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Target {
    /// The tracker's id (DETECTED_ROI's objects, the page's "#n").
    pub id: u32,
    /// Its centre and its box's top-left and bottom-right pixels, in the frame's pixels
    /// (x right, y down, from the top-left); None where the frame does not draw the view.
    pub pixels: Option<[(u32, u32); 3]>,
    /// The detector's score, 0 to 100.
    pub score: u8,
    /// What it is, as its detector names it; empty if not said.
    pub label: String,
    /// Where its centre's ray meets the ground; None above the horizon.
    pub ground: Option<GeoPoint>,
}

/// A view's objects, for its frame (`size` pixels; None where the frame does not draw it).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Vmti {
    pub size: Option<(u32, u32)>,
    /// How many objects the tracker follows, shown in this view or not.
    pub total: usize,
    pub targets: Vec<Target>,
}

/// `v` as an unsigned integer in as few bytes as it takes (at least one).
fn uint(v: u64) -> Vec<u8> {
    let bytes = v.to_be_bytes();
    let skip = bytes.iter().take_while(|&&b| b == 0).count().min(7);
    bytes[skip..].to_vec()
}

/// `x` as ST 1201's IMAPB maps `min..=max` onto `n` bytes (clamped into the range).
pub fn imapb(x: f64, (min, max): (f64, f64), n: usize) -> Vec<u8> {
    let b_pow = (max - min).log2().ceil() as i32;
    let d_pow = 8 * n as i32 - 1;
    let scale = 2f64.powi(d_pow - b_pow);
    let offset = match min < 0.0 && max > 0.0 {
        true => scale * min - (scale * min).floor(),
        false => 0.0,
    };
    let y = (scale * (x.clamp(min, max) - min) + offset).floor() as u64;
    y.to_be_bytes()[8 - n..].to_vec()
}

/// ST 0903's Location pack: latitude, longitude and height (HAE), 10 bytes.
fn location(p: &GeoPoint) -> Vec<u8> {
    let mut out = imapb(p.lat, (-90.0, 90.0), 4);
    out.extend(imapb(p.lon, (-180.0, 180.0), 4));
    out.extend(imapb(p.alt, (-900.0, 19_000.0), 2));
    out
}

/// A label as the last segment of an IRI: letters, digits, `-`, `.` and `_` as they are,
/// every other byte percent-encoded.
fn iri_segment(label: &str) -> String {
    label
        .bytes()
        .map(|b| match b.is_ascii_alphanumeric() || b"-._".contains(&b) {
            true => (b as char).to_string(),
            false => format!("%{b:02X}"),
        })
        .collect()
}

/// Appends `value` to a series: its BER length, then itself.
fn series_item(value: &[u8], out: &mut Vec<u8>) {
    super::ber_length(value.len(), out);
    out.extend_from_slice(value);
}

impl Vmti {
    /// The local set's bytes (the value of ST 0601's tag 74) for the frame captured at
    /// `time_us`, from the view `source` with fields of view `fov` (degrees).
    pub fn local_set(&self, time_us: u64, source: &str, fov: (f64, f64)) -> Vec<u8> {
        let mut labels: Vec<&str> = vec![];
        for t in &self.targets {
            if !t.label.is_empty() && !labels.contains(&t.label.as_str()) {
                labels.push(&t.label);
            }
        }
        let mut set = LocalSet::default();
        set.push(2, &time_us.to_be_bytes());
        set.push(3, b"DigiView");
        set.push(4, &uint(VERSION as u64));
        set.push(5, &uint(self.total as u64));
        set.push(6, &uint(self.targets.len() as u64));
        let width = self.size.map(|(w, h)| {
            set.push(8, &uint(w as u64));
            set.push(9, &uint(h as u64));
            w as u64
        });
        set.push(10, source.as_bytes());
        set.push(11, &imapb(fov.0, (0.0, 180.0), 2));
        set.push(12, &imapb(fov.1, (0.0, 180.0), 2));
        if !self.targets.is_empty() {
            let mut series = vec![];
            for t in &self.targets {
                let class = labels.iter().position(|&l| l == t.label);
                series_item(&target(t, width, class.map(|k| k as u64 + 1)), &mut series);
            }
            set.push(101, &series);
        }
        if !labels.is_empty() {
            let mut series = vec![];
            for (k, label) in labels.iter().enumerate() {
                let mut o = LocalSet::default();
                o.push(1, &uint(k as u64 + 1));
                o.push(3, ONTOLOGY.as_bytes());
                o.push(4, format!("{ONTOLOGY}#{}", iri_segment(label)).as_bytes());
                o.push(6, label.as_bytes());
                series_item(&o.into_items(), &mut series);
            }
            set.push(103, &series);
        }
        set.into_items()
    }
}

/// One VTarget pack (without its series length): the id, then its items. Pixel numbers count
/// from 1 along rows of `width`; `class` is the ontology entry of its label.
fn target(t: &Target, width: Option<u64>, class: Option<u64>) -> Vec<u8> {
    let mut out = vec![];
    super::ber_oid(t.id, &mut out);
    let mut items = LocalSet::default();
    if let (Some(px), Some(w)) = (t.pixels, width) {
        for (tag, (x, y)) in [1, 2, 3].into_iter().zip(px) {
            items.push(tag, &uint(y as u64 * w + x as u64 + 1));
        }
    }
    items.push(5, &[t.score.min(100)]);
    if let Some(g) = &t.ground {
        items.push(17, &location(g));
    }
    if let Some(id) = class {
        let mut object = LocalSet::default();
        object.push(3, &uint(id));
        let mut series = vec![];
        series_item(&object.into_items(), &mut series);
        items.push(107, &series);
    }
    out.extend(items.into_items());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn imapb_maps_as_st_1201_says() {
        // Latitude in 4 bytes: 2^23 a degree from -90; height in 2 bytes: a metre from -900.
        assert_eq!(imapb(-90.0, (-90.0, 90.0), 4), [0, 0, 0, 0]);
        assert_eq!(imapb(0.0, (-90.0, 90.0), 4), (90u32 << 23).to_be_bytes());
        assert_eq!(imapb(100.5, (-900.0, 19_000.0), 2), 1000u16.to_be_bytes());
        // Fields of view: 128 steps a degree, rounded down.
        assert_eq!(imapb(90.0, (0.0, 180.0), 2), (90u16 * 128).to_be_bytes());
        assert_eq!(uint(0), [0]);
        assert_eq!(uint(300), [1, 44]);
        assert_eq!(iri_segment("traffic light"), "traffic%20light");
    }
}
