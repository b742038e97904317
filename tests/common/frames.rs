//! Protocol frames and replies the control tests build and expect.

use digiview::protocol::{Body, FRAME_LEN, Message, Param, ParamType, Verdict, crc8};

/// Milliradian fixed point: a value read back is within half a step.
pub const MRAD: f64 = 0.0005 + 1e-9;

pub fn ack(pt: ParamType) -> Body {
    Body::Verdict(Verdict::Acknowledgement, pt as u8)
}

pub fn verdict(v: Verdict, pt: ParamType) -> Body {
    Body::Verdict(v, pt as u8)
}

/// A frame with arbitrary header bytes and a correct checksum.
pub fn raw_frame(version: u8, message_type: u8, param_type: u8) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[8] = version;
    f[9] = message_type;
    f[10] = param_type;
    f[75] = crc8(&f[..75]);
    f
}

/// A client of the control protocol: over a socket (`serve::Raw`) or in-process
/// (`direct::Direct`).
pub trait Client {
    /// Bytes as a TCP client writes them.
    fn send_bytes(&mut self, bytes: &[u8]);
    /// The next reply.
    fn recv(&mut self) -> Message;

    fn send(&mut self, body: Body) {
        self.send_bytes(&Message::new(body).encode());
    }

    /// One request, one reply.
    fn ask(&mut self, body: Body) -> Body {
        self.send(body);
        self.recv().body
    }

    fn get(&mut self, query: Param) -> Param {
        match self.ask(Body::Get(query)) {
            Body::Current(p) => p,
            other => panic!("GET {:?} answered {other:?}", query.param_type()),
        }
    }
}
