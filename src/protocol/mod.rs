//! The DigiView control protocol's codec: 80-byte little-endian frames (protocol.md) to typed
//! messages and back. The first layer of control, below the server and the `ctl` client;
//! nothing here knows about sockets or the live state.
//!
//! Decoding never panics: any 80 bytes are either a message or a [`DecodeError`] that says
//! which reply the server owes (CHECKSUM_ERROR, DATA_ERROR or UNKNOWN).

pub mod edit;
pub mod params;
pub mod text;
pub mod wire;

pub use params::{Param, ParamType};
pub use wire::{BoundingBox, DATA_LEN, TextValue, Unit, ViewBoxes, split_text};

/// Every frame is this long, in both directions and on both transports.
pub const FRAME_LEN: usize = 80;
/// The protocol version this codec speaks.
pub const VERSION: u8 = 0;
pub(crate) const CHECKSUM_AT: usize = 75;
pub(crate) const DATA_AT: usize = 11;

const CRC8: crc::Crc<u8> = crc::Crc::<u8>::new(&crc::CRC_8_BLUETOOTH);

/// CRC-8/BLUETOOTH (poly 0xA7, reflected): the frame checksum over bytes 0..=74.
pub fn crc8(bytes: &[u8]) -> u8 {
    CRC8.checksum(bytes)
}

/// The message_type byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[repr(u8)]
pub enum MessageType {
    Empty = 0,
    Quit = 1,
    GetParameters = 2,
    SetParameters = 3,
    CurrentParameters = 4,
    Acknowledgement = 5,
    ChecksumError = 6,
    DataError = 7,
    Forbidden = 8,
    Unknown = 9,
}

/// A reply that carries no data: how the server judged a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Verdict {
    Acknowledgement,
    ChecksumError,
    DataError,
    Forbidden,
    Unknown,
}

impl MessageType {
    pub const ALL: [MessageType; 10] = [
        MessageType::Empty,
        MessageType::Quit,
        MessageType::GetParameters,
        MessageType::SetParameters,
        MessageType::CurrentParameters,
        MessageType::Acknowledgement,
        MessageType::ChecksumError,
        MessageType::DataError,
        MessageType::Forbidden,
        MessageType::Unknown,
    ];

    /// The name as protocol.md writes it (`GET_PARAMETERS`).
    pub fn name(self) -> &'static str {
        match self {
            MessageType::Empty => "EMPTY",
            MessageType::Quit => "QUIT",
            MessageType::GetParameters => "GET_PARAMETERS",
            MessageType::SetParameters => "SET_PARAMETERS",
            MessageType::CurrentParameters => "CURRENT_PARAMETERS",
            MessageType::Acknowledgement => "ACKNOWLEDGEMENT",
            MessageType::ChecksumError => "CHECKSUM_ERROR",
            MessageType::DataError => "DATA_ERROR",
            MessageType::Forbidden => "FORBIDDEN",
            MessageType::Unknown => "UNKNOWN",
        }
    }
}

impl std::fmt::Display for MessageType {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Verdict {
    pub fn message_type(self) -> MessageType {
        match self {
            Verdict::Acknowledgement => MessageType::Acknowledgement,
            Verdict::ChecksumError => MessageType::ChecksumError,
            Verdict::DataError => MessageType::DataError,
            Verdict::Forbidden => MessageType::Forbidden,
            Verdict::Unknown => MessageType::Unknown,
        }
    }

    /// What the verdict tells a person.
    pub fn meaning(self) -> &'static str {
        match self {
            Verdict::Acknowledgement => "taken",
            Verdict::ChecksumError => "the request's checksum did not match; nothing was applied",
            Verdict::DataError => {
                "the request could not be interpreted (a cam_id outside 0..=3, a value out of \
                 range, a GET-only type, or nothing to report); nothing was applied"
            }
            Verdict::Forbidden => "this client is not permitted to do that",
            Verdict::Unknown => "the server does not know this message or parameter type",
        }
    }
}

/// What a frame says.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Body {
    /// Keep-alive; the param_type is echoed.
    Empty(u8),
    Quit(u8),
    Get(Param),
    Set(Param),
    Current(Param),
    /// A reply without data, echoing the request's param_type.
    Verdict(Verdict, u8),
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Message {
    /// Microseconds since the Unix epoch.
    pub timestamp: u64,
    pub body: Body,
}

/// Why 80 bytes (or a datagram) are not a message, and which reply that earns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("a frame is {FRAME_LEN} bytes, not {0}")]
    Length(usize),
    #[error("checksum 0x{found:02x} does not match the frame's CRC-8 0x{expected:02x}")]
    Checksum {
        param_type: u8,
        expected: u8,
        found: u8,
    },
    #[error("protocol version {version} is not supported (only {VERSION})")]
    Version { version: u8, param_type: u8 },
    #[error("message_type {message_type} does not exist")]
    UnknownMessage { message_type: u8, param_type: u8 },
    #[error("param_type {param_type} does not exist")]
    UnknownParam { message_type: u8, param_type: u8 },
}

impl DecodeError {
    /// The reply protocol.md prescribes, and the param_type it echoes.
    pub fn reply(&self) -> (Verdict, u8) {
        match *self {
            DecodeError::Length(_) => (Verdict::DataError, 0),
            DecodeError::Checksum { param_type, .. } => (Verdict::ChecksumError, param_type),
            DecodeError::Version { param_type, .. } => (Verdict::DataError, param_type),
            DecodeError::UnknownMessage { param_type, .. }
            | DecodeError::UnknownParam { param_type, .. } => (Verdict::Unknown, param_type),
        }
    }
}

impl Body {
    pub fn message_type(&self) -> MessageType {
        match self {
            Body::Empty(_) => MessageType::Empty,
            Body::Quit(_) => MessageType::Quit,
            Body::Get(_) => MessageType::GetParameters,
            Body::Set(_) => MessageType::SetParameters,
            Body::Current(_) => MessageType::CurrentParameters,
            Body::Verdict(v, _) => v.message_type(),
        }
    }

    pub fn param_type(&self) -> u8 {
        match self {
            Body::Empty(p) | Body::Quit(p) | Body::Verdict(_, p) => *p,
            Body::Get(p) | Body::Set(p) | Body::Current(p) => p.param_type() as u8,
        }
    }
}

impl Message {
    pub fn new(body: Body) -> Message {
        Message {
            timestamp: crate::clock::utc_us(),
            body,
        }
    }

    pub fn encode(&self) -> [u8; FRAME_LEN] {
        let mut f = [0u8; FRAME_LEN];
        f[..8].copy_from_slice(&self.timestamp.to_le_bytes());
        f[8] = VERSION;
        f[9] = self.body.message_type() as u8;
        f[10] = self.body.param_type();
        if let Body::Get(p) | Body::Set(p) | Body::Current(p) = &self.body {
            f[DATA_AT..DATA_AT + DATA_LEN].copy_from_slice(&p.encode());
        }
        f[CHECKSUM_AT] = crc8(&f[..CHECKSUM_AT]);
        f
    }

    /// Decodes one frame. The 4 padding bytes are ignored, as are the data bytes of messages
    /// that carry none.
    pub fn decode(frame: &[u8]) -> Result<Message, DecodeError> {
        let f: &[u8; FRAME_LEN] = frame
            .try_into()
            .map_err(|_| DecodeError::Length(frame.len()))?;
        let (message_type, param_type) = (f[9], f[10]);
        let expected = crc8(&f[..CHECKSUM_AT]);
        if f[CHECKSUM_AT] != expected {
            return Err(DecodeError::Checksum {
                param_type,
                expected,
                found: f[CHECKSUM_AT],
            });
        }
        if f[8] != VERSION {
            return Err(DecodeError::Version {
                version: f[8],
                param_type,
            });
        }
        let timestamp = u64::from_le_bytes(f[..8].try_into().expect("8 bytes"));
        let data: &[u8; DATA_LEN] = f[DATA_AT..DATA_AT + DATA_LEN].try_into().expect("64 bytes");
        let param = || {
            ParamType::from_u8(param_type)
                .map(|t| Param::decode(t, data))
                .ok_or(DecodeError::UnknownParam {
                    message_type,
                    param_type,
                })
        };
        let verdict = |v| Ok(Body::Verdict(v, param_type));
        let body = match message_type {
            0 => Ok(Body::Empty(param_type)),
            1 => Ok(Body::Quit(param_type)),
            2 => param().map(Body::Get),
            3 => param().map(Body::Set),
            4 => param().map(Body::Current),
            5 => verdict(Verdict::Acknowledgement),
            6 => verdict(Verdict::ChecksumError),
            7 => verdict(Verdict::DataError),
            8 => verdict(Verdict::Forbidden),
            9 => verdict(Verdict::Unknown),
            _ => Err(DecodeError::UnknownMessage {
                message_type,
                param_type,
            }),
        }?;
        Ok(Message { timestamp, body })
    }
}

#[cfg(test)]
mod golden;
