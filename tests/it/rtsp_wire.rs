//! How each picture ends on the RTSP wire, as FFmpeg's players need it. Their H.264 parser
//! (ffplay, mpv, OpenCV's capture, the `ffmpeg` program) ignores the RTP marker bit and closes
//! a picture only at the next picture's first NAL unit; the head sends that unit, the access
//! unit delimiter, in the picture's own last packet, so each picture is whole on arrival
//! rather than a frame interval later (glass to glass 87 → 53 ms with `ffmpeg`, 53 → 20 ms
//! with OpenCV's capture on one decoding thread; docs/performance.md). A GStreamer client takes the RTP packets as they come.

use crate::common;
use crate::players::still_and_render;
use common::serve::{Serve, until_running};
use gstreamer as gst;
use gstreamer::prelude::*;
use std::collections::BTreeMap;

/// One RTP packet: its timestamp, marker bit and the NAL unit types it carries (an FU-A
/// fragment as its unit's type, a STAP-A as each aggregated unit's).
fn packet(rtp: &[u8]) -> (u32, bool, Vec<u8>) {
    assert!(rtp.len() > 12 && rtp[0] >> 6 == 2, "not an RTP packet");
    let mut at = 12 + 4 * (rtp[0] & 0x0f) as usize;
    if rtp[0] & 0x10 != 0 {
        at += 4 + 4 * u16::from_be_bytes([rtp[at + 2], rtp[at + 3]]) as usize;
    }
    let payload = &rtp[at..];
    let types = match payload[0] & 0x1f {
        28 => vec![payload[1] & 0x1f],
        24 => {
            let (mut t, mut i) = (vec![], 1);
            while i + 2 < payload.len() {
                let n = u16::from_be_bytes([payload[i], payload[i + 1]]) as usize;
                t.push(payload[i + 2] & 0x1f);
                i += 2 + n;
            }
            t
        }
        t => vec![t],
    };
    let ts = u32::from_be_bytes([rtp[4], rtp[5], rtp[6], rtp[7]]);
    (ts, rtp[1] & 0x80 != 0, types)
}

#[test]
fn each_pictures_last_rtp_packet_is_the_next_pictures_delimiter_and_each_picture_has_one() {
    let dir = tempfile::tempdir().unwrap();
    let (source, _) = still_and_render(dir.path());
    let serve = Serve::start_video(&["--source", &source, "--size", "640x480"]);
    until_running(&serve);
    let url = serve.rtsp.clone().unwrap();
    // The RTP packets as they come, before any depayloader.
    let (pipeline, sink) = common::viewer::play(&url, "application/x-rtp,media=video");
    // Each picture's packets by timestamp, in order of arrival.
    let mut pictures: BTreeMap<u32, Vec<(bool, Vec<u8>)>> = BTreeMap::new();
    let mut order = vec![];
    while order.len() < 40 {
        let sample = sink
            .try_pull_sample(gst::ClockTime::from_seconds(10))
            .expect("RTP packets within 10 s");
        let map = sample.buffer().unwrap().map_readable().unwrap();
        let (ts, marker, types) = packet(&map);
        if !pictures.contains_key(&ts) {
            order.push(ts);
        }
        pictures.entry(ts).or_default().push((marker, types));
    }
    pipeline.set_state(gst::State::Null).unwrap();

    // The last picture may be cut short: the others are whole.
    for (n, ts) in order[..order.len() - 1].iter().enumerate() {
        let packets = &pictures[ts];
        let (marker, last) = packets.last().unwrap();
        assert!(*marker, "picture {n}: its last packet has no marker bit");
        assert_eq!(
            last,
            &vec![9],
            "picture {n}: its last packet is not the delimiter alone ({packets:?})"
        );
        let delimiters = packets.iter().flat_map(|(_, t)| t).filter(|&&t| t == 9);
        assert_eq!(delimiters.count(), 1, "picture {n}: {packets:?}");
        let slices = packets
            .iter()
            .flat_map(|(_, t)| t)
            .filter(|&&t| t == 1 || t == 5);
        assert!(slices.count() >= 1, "picture {n} has no slice: {packets:?}");
    }
}
