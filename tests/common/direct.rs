//! The control protocol in-process: request frames straight into `Controller::handle`, as the
//! server hands them over, on a live state built from the same flags `digiview serve` takes.
//! For the parameter rules; the server itself (sockets, framing across reads, permissions by
//! address, QUIT, load) is tested against a real `digiview serve`.

use super::frames::Client;
use super::lens_cal;
use clap::Parser;
use digiview::cli::StateArgs;
use digiview::control::Controller;
use digiview::protocol::{FRAME_LEN, Message};
use std::collections::VecDeque;
use std::net::{IpAddr, Ipv4Addr};

#[derive(Parser)]
struct Flags {
    #[command(flatten)]
    state: StateArgs,
}

/// A client of a controller on a live state without video, from a loopback address.
pub struct Direct {
    pub controller: Controller,
    /// Bytes of a frame not yet whole.
    pending: Vec<u8>,
    replies: VecDeque<Message>,
}

impl Direct {
    /// The state `digiview serve --no-video` makes of these state flags (`--track ...`).
    pub fn start(flags: &[&str]) -> Direct {
        let flags = Flags::try_parse_from(std::iter::once("serve").chain(flags.iter().copied()))
            .expect("valid flags");
        let cal = lens_cal();
        let state = flags.state.state(&cal).expect("a valid state");
        Direct {
            controller: Controller::direct(state, &cal),
            pending: Vec::new(),
            replies: VecDeque::new(),
        }
    }
}

impl Client for Direct {
    /// Every whole frame is handled, in order; a partial one waits for the rest.
    fn send_bytes(&mut self, bytes: &[u8]) {
        self.pending.extend_from_slice(bytes);
        let whole = self.pending.len() / FRAME_LEN * FRAME_LEN;
        let frames: Vec<u8> = self.pending.drain(..whole).collect();
        for frame in frames.chunks(FRAME_LEN) {
            let outcome = self
                .controller
                .handle(frame, IpAddr::V4(Ipv4Addr::LOCALHOST));
            for reply in outcome.replies {
                // Each reply goes out as a frame, as the server sends it.
                let back = Message::decode(&reply.encode()).expect("replies are valid frames");
                self.replies.push_back(back);
            }
        }
    }

    fn recv(&mut self) -> Message {
        self.replies.pop_front().expect("a reply")
    }
}
