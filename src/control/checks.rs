//! Invariants of the codec and of the server's frame handling, asserted on arbitrary input:
//! the fuzz targets (`fuzz/`) call these, and a test replays the committed fuzz corpus
//! through them on every `cargo test`.

use super::Controller;
use crate::lens::LensCal;
use crate::protocol::text::annotate;
use crate::protocol::{Body, FRAME_LEN, Message, crc8};
use crate::state::capture::NoVideo;
use crate::state::{Gate, LiveSettings, Sensed, State};
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;

/// Any bytes: decoding never panics; what decodes re-encodes to a frame that decodes to the
/// same message; the `--hex` annotation never panics.
pub fn decode(data: &[u8]) {
    match Message::decode(data) {
        Ok(m) => {
            let again = Message::decode(&m.encode()).expect("our own encoding decodes");
            assert_eq!(again, m);
        }
        Err(e) => {
            let _ = e.reply();
        }
    }
    if let Ok(frame) = <&[u8; FRAME_LEN]>::try_from(data) {
        let _ = annotate(frame);
    }
}

impl Controller {
    /// A controller on `state` alone (no video, anyone may set, a thermal sensor assumed so
    /// that THERMAL and CAM_THERMAL are set too), as the rule tests and the fuzzers drive it
    /// in-process.
    pub fn direct(state: State, cal: &LensCal) -> Controller {
        let settings = LiveSettings::new(state.settings, cal).expect("valid settings");
        let sensed = Arc::new(Sensed::new(state.vehicle, state.tracked));
        let gate = Gate::new(Arc::new(settings), sensed, Arc::default());
        Controller {
            has_thermal: true,
            ..Controller::new(Arc::new(gate), Arc::default(), Arc::new(NoVideo))
        }
    }
}

/// A controller on the default state with two tracked objects.
pub fn controller(cal: &LensCal) -> Controller {
    let mut state = State::default();
    state
        .add_tracked("yaw=10deg,pitch=-40deg,size=3deg")
        .expect("valid");
    state
        .add_tracked("yaw=100deg,pitch=-60deg,size=2deg")
        .expect("valid");
    Controller::direct(state, cal)
}

/// Feeds `data` as a stream of frames: every request gets its replies (exactly one, or at
/// least one for DETECTED_ROI 254/255), every reply is a valid reply frame echoing the
/// request's param_type, and the live state stays valid. Most random frames would fail the
/// checksum, so a chunk whose last padding byte is even gets its checksum fixed.
pub fn handle_stream(controller: &Controller, data: &[u8]) {
    for (i, chunk) in data.chunks(FRAME_LEN).enumerate() {
        let mut frame = chunk.to_vec();
        if frame.len() == FRAME_LEN && frame[79] & 1 == 0 {
            frame[75] = crc8(&frame[..75]);
        }
        // Alternate a loopback peer and a foreign one (which may not QUIT).
        let peer = if i % 2 == 0 {
            IpAddr::V4(Ipv4Addr::LOCALHOST)
        } else {
            IpAddr::V4(Ipv4Addr::new(192, 0, 2, 1))
        };
        let out = controller.handle(&frame, peer);
        let full = frame.len() == FRAME_LEN;
        let multi = full && frame[9] == 2 && frame[10] == 4 && frame[11] >= 254;
        if multi {
            assert!(!out.replies.is_empty());
        } else {
            assert_eq!(out.replies.len(), 1, "one reply per request");
        }
        let echoed = if full { frame[10] } else { 0 };
        for r in &out.replies {
            let back = Message::decode(&r.encode()).expect("replies are valid frames");
            assert_eq!(back.body.param_type(), echoed, "replies echo param_type");
            assert!(matches!(back.body, Body::Current(_) | Body::Verdict(..)));
        }
        let settings = controller.gate.settings();
        settings
            .snapshot()
            .validate(settings.lenses())
            .expect("the settings stay valid");
    }
}
