//! Where an access unit ends on the RTSP wire. The RTSP server hands each unit to the RTP
//! payloader after this: a leading access unit delimiter (AUD) is taken off, and one is put at
//! the unit's end instead, so the delimiter that opens unit N+1 travels in unit N's last
//! packet (with N's timestamp and the marker bit). The bytes in order are the same stream,
//! delimiter, picture, delimiter, picture; only when the delimiter is sent changes.
//!
//! Why: players built on FFmpeg (ffplay, mpv, OpenCV's capture, the `ffmpeg` program) do not
//! take an RTP packet's marker bit as the end of a picture. Their H.264 and H.265 parsers find
//! a picture's end at the first NAL unit of the next one, so each picture waited a whole frame
//! interval for its successor's first packet (33 ms at 30 fps: 86 ms glass to glass where
//! GStreamer's client, which uses the marker, had 20; docs/performance.md). A delimiter at
//! the end is the next unit's first NAL unit, sent as soon as the picture is.

use super::Codec;
use gstreamer as gst;

/// H.264's delimiter, primary_pic_type 1 (I and P slices: the head makes no B-frames).
const AUD_H264: [u8; 6] = [0, 0, 0, 1, 0x09, 0x30];
/// H.265's delimiter (NAL type 35, layer 0, temporal id 0), pic_type 2 (I, P and B).
const AUD_H265: [u8; 7] = [0, 0, 0, 1, 0x46, 0x01, 0x50];

/// Whether the NAL unit whose header starts `nal` is an access unit delimiter.
fn is_delimiter(codec: Codec, nal: &[u8]) -> bool {
    match (codec, nal.first()) {
        (Codec::H264, Some(b)) => b & 0x1f == 9,
        (Codec::H265, Some(b)) => (b >> 1) & 0x3f == 35,
        (_, None) => false,
    }
}

/// Where the NAL unit after the start code at `from` begins: its header's index.
fn header_after_start_code(bytes: &[u8], from: usize) -> Option<usize> {
    let rest = bytes.get(from..)?;
    let at = rest.windows(3).position(|w| w == [0, 0, 1])?;
    Some(from + at + 3)
}

/// `unit` (Annex B bytes) with a leading delimiter removed and one appended.
pub(crate) fn delimited_at_end(codec: Codec, unit: &[u8]) -> Vec<u8> {
    let aud: &[u8] = match codec {
        Codec::H264 => &AUD_H264,
        Codec::H265 => &AUD_H265,
    };
    let mut body = unit;
    if let Some(first) = header_after_start_code(unit, 0)
        && is_delimiter(codec, &unit[first..])
        && let Some(next) = header_after_start_code(unit, first + 1)
    {
        // The next NAL unit's start code, with its leading zero where it has four bytes.
        let start = next - 3;
        body = &unit[start - usize::from(start > first && unit[start - 1] == 0)..];
    }
    let mut out = Vec::with_capacity(body.len() + aud.len());
    out.extend_from_slice(body);
    out.extend_from_slice(aud);
    out
}

/// As [`delimited_at_end`], for a buffer: its timestamps and flags kept.
pub(crate) fn delimited_buffer(codec: Codec, unit: &gst::Buffer) -> gst::Buffer {
    let Ok(map) = unit.map_readable() else {
        return unit.clone();
    };
    let mut out = gst::Buffer::from_mut_slice(delimited_at_end(codec, &map));
    if let Some(b) = out.get_mut() {
        let keep = gst::BufferCopyFlags::FLAGS | gst::BufferCopyFlags::TIMESTAMPS;
        let _ = unit.copy_into(b, keep, ..);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPS: [u8; 6] = [0, 0, 0, 1, 0x67, 0x42];
    const SLICE: [u8; 7] = [0, 0, 1, 0x41, 0x9a, 0x00, 0x01];

    #[test]
    fn the_delimiter_moves_from_the_units_start_to_its_end() {
        let unit = [&[0, 0, 0, 1, 0x09, 0x10][..], &SPS, &SLICE].concat();
        let out = delimited_at_end(Codec::H264, &unit);
        assert_eq!(out, [&SPS[..], &SLICE, &AUD_H264].concat());
    }

    #[test]
    fn a_unit_without_a_delimiter_gains_one_at_its_end_and_loses_nothing() {
        let unit = [&SPS[..], &SLICE].concat();
        assert_eq!(
            delimited_at_end(Codec::H264, &unit),
            [&unit[..], &AUD_H264].concat()
        );
        // A three-byte start code before the next unit keeps its three bytes.
        let unit = [&[0, 0, 1, 0x09, 0x30][..], &SLICE].concat();
        assert_eq!(
            delimited_at_end(Codec::H264, &unit),
            [&SLICE[..], &AUD_H264].concat()
        );
    }

    #[test]
    fn h265_delimiters_are_told_by_their_two_byte_header() {
        let vps = [0u8, 0, 0, 1, 0x40, 0x01, 0x0c];
        let unit = [&AUD_H265[..], &vps].concat();
        assert_eq!(
            delimited_at_end(Codec::H265, &unit),
            [&vps[..], &AUD_H265].concat()
        );
        // An H.264 delimiter's header byte is not an H.265 delimiter.
        let unit = [&[0, 0, 0, 1, 0x09, 0x30][..], &vps].concat();
        assert_eq!(
            delimited_at_end(Codec::H265, &unit),
            [&unit[..], &AUD_H265].concat()
        );
    }

    #[test]
    fn a_unit_that_is_only_a_delimiter_or_garbage_is_kept_whole() {
        for unit in [&[0u8, 0, 0, 1, 0x09, 0x30][..], &[1, 2, 3], &[]] {
            assert_eq!(
                delimited_at_end(Codec::H264, unit),
                [unit, &AUD_H264].concat()
            );
        }
    }

    #[test]
    fn a_buffer_keeps_its_timestamps_and_flags() {
        crate::gst::init().unwrap();
        let mut unit = gst::Buffer::from_slice([&SPS[..], &SLICE].concat());
        {
            let b = unit.get_mut().unwrap();
            b.set_pts(gst::ClockTime::from_mseconds(40));
            b.set_dts(gst::ClockTime::from_mseconds(40));
            b.set_flags(gst::BufferFlags::DELTA_UNIT);
        }
        let out = delimited_buffer(Codec::H264, &unit);
        assert_eq!(out.pts(), Some(gst::ClockTime::from_mseconds(40)));
        assert_eq!(out.dts(), Some(gst::ClockTime::from_mseconds(40)));
        assert!(out.flags().contains(gst::BufferFlags::DELTA_UNIT));
        assert!(out.map_readable().unwrap().ends_with(&AUD_H264));
    }
}
