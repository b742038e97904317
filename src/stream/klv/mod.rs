//! KLV metadata for the streams (MISB ST 0601, the UAS Datalink Local Set): what a view of a
//! frame shows and from where, as mapping and ISR software reads it. `view` works out a
//! view's metadata from the frame's plan and the vehicle's pose at capture (where it looks,
//! its footprint on the ground, the tracked objects it shows); `st0601` encodes it as one
//! packet, with `vmti`'s ST 0903 set of the objects nested in it. Here: the local set's
//! byte-level pieces, the BER lengths and tags and the checksum (SMPTE ST 336).

pub mod st0601;
pub mod view;
pub mod vmti;

pub use st0601::UAS_LS_KEY;
pub use view::ViewMetadata;

use gstreamer as gst;

/// The KLV input of an MPEG-TS muxer named `mux`: an appsrc named `klv` (live where the
/// pipeline is), asynchronous KLV as GStreamer 1.22's mpegtsmux writes it.
pub fn muxer_input(live: bool) -> String {
    format!("appsrc name=klv is-live={live} format=time caps=meta/x-klv,parsed=true ! mux.")
}

/// A packet as a buffer for [`muxer_input`], shown at `pts` (its picture's).
pub fn buffer(packet: &[u8], pts: Option<gst::ClockTime>) -> gst::Buffer {
    let mut b = gst::Buffer::from_slice(packet.to_vec());
    b.get_mut().expect("a new buffer").set_pts(pts);
    b
}

/// A BER length: the short form up to 127, else `0x80 | n` and the length in n bytes.
pub fn ber_length(len: usize, out: &mut Vec<u8>) {
    if len < 128 {
        out.push(len as u8);
        return;
    }
    let bytes = len.to_be_bytes();
    let skip = bytes.iter().take_while(|&&b| b == 0).count();
    out.push(0x80 | (bytes.len() - skip) as u8);
    out.extend_from_slice(&bytes[skip..]);
}

/// A BER-OID tag: 7 bits a byte, high bit set on all but the last.
pub fn ber_oid(tag: u32, out: &mut Vec<u8>) {
    let mut groups = vec![(tag & 0x7f) as u8];
    let mut rest = tag >> 7;
    while rest > 0 {
        groups.push(0x80 | (rest & 0x7f) as u8);
        rest >>= 7;
    }
    out.extend(groups.iter().rev());
}

/// The 16-bit checksum of ST 0601's tag 1 over `bytes` (the packet from the first byte of
/// its key through the checksum's own tag and length): a running sum of big-endian 16-bit
/// words, the byte at an even offset the high byte.
pub fn checksum(bytes: &[u8]) -> u16 {
    bytes.iter().enumerate().fold(0u16, |sum, (i, &b)| {
        let b = b as u16;
        sum.wrapping_add(if i % 2 == 0 { b << 8 } else { b })
    })
}

/// A local set's items in the order pushed, closed by [`LocalSet::packet`].
#[derive(Default)]
pub struct LocalSet {
    items: Vec<u8>,
}

impl LocalSet {
    /// Appends item `tag` with `value`.
    pub fn push(&mut self, tag: u32, value: &[u8]) {
        ber_oid(tag, &mut self.items);
        ber_length(value.len(), &mut self.items);
        self.items.extend_from_slice(value);
    }

    /// The items as they are: a local set nested in another's item.
    pub fn into_items(self) -> Vec<u8> {
        self.items
    }

    /// The packet: `key`, the BER length, the items and, last, the checksum (tag 1).
    pub fn packet(mut self, key: &[u8; 16]) -> Vec<u8> {
        self.items.extend_from_slice(&[1, 2]);
        let mut out = key.to_vec();
        ber_length(self.items.len() + 2, &mut out);
        out.extend_from_slice(&self.items);
        let sum = checksum(&out);
        out.extend_from_slice(&sum.to_be_bytes());
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_and_tags_take_the_short_form_up_to_127() {
        let enc = |f: fn(usize, &mut Vec<u8>), n| {
            let mut v = vec![];
            f(n, &mut v);
            v
        };
        assert_eq!(enc(ber_length, 5), [5]);
        assert_eq!(enc(ber_length, 127), [127]);
        assert_eq!(enc(ber_length, 128), [0x81, 128]);
        assert_eq!(enc(ber_length, 300), [0x82, 1, 44]);
        let oid = |t| {
            let mut v = vec![];
            ber_oid(t, &mut v);
            v
        };
        assert_eq!(oid(65), [65]);
        assert_eq!(oid(128), [0x81, 0x00]);
        assert_eq!(oid(300), [0x82, 0x2c]);
    }

    #[test]
    fn the_checksum_covers_key_to_its_own_length_and_odd_lengths_end_high() {
        assert_eq!(checksum(&[0x12, 0x34, 0x56]), 0x1234 + 0x5600);
        assert_eq!(checksum(&[0xff, 0xff, 0x00, 0x02]), 0x0001);
        let mut set = LocalSet::default();
        set.push(65, &[19]);
        let p = set.packet(&UAS_LS_KEY);
        let (body, sum) = p.split_at(p.len() - 2);
        assert_eq!(&body[body.len() - 2..], [1, 2]);
        assert_eq!(u16::from_be_bytes([sum[0], sum[1]]), checksum(body));
        assert_eq!(p[16] as usize, p.len() - 17, "the BER length after the key");
    }
}
