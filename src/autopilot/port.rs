//! One open link to the autopilot, whatever carries it: UDP and TCP through the `mavlink`
//! crate's own transports, a serial port opened here. The crate's serial transport retries
//! every read error inside its receive call, a timeout and a vanished device alike, so an
//! unplugged USB adapter would spin there unseen and the link could never reopen: here a
//! serial read waits at most [`SERIAL_WAIT`] and a hang-up ends the link like any other
//! failure.

use mavlink::dialects::common::MavMessage;
use mavlink::error::{MessageReadError, MessageWriteError};
use mavlink::{MAVLinkMessageRaw, MavConnection, MavHeader, MavlinkReader, MavlinkVersion};
use serialport::TTYPort;
use std::io::{self, Write};
use std::sync::Mutex;
use std::time::Duration;

/// How long a serial read waits for a byte before the link's loop looks around.
const SERIAL_WAIT: Duration = Duration::from_millis(100);

pub enum Port {
    Net(Box<dyn MavConnection<MavMessage> + Send + Sync>),
    Serial {
        reader: Mutex<MavlinkReader<TTYPort>>,
        writer: Mutex<TTYPort>,
    },
}

impl Port {
    /// Opens `address` (an endpoint as [`super::Endpoint`] checked it).
    pub fn open(address: &str) -> io::Result<Port> {
        let Some(serial) = address.strip_prefix("serial:") else {
            return mavlink::connect::<MavMessage>(address).map(|c| Port::Net(Box::new(c)));
        };
        let (device, baud) = serial
            .rsplit_once(':')
            .and_then(|(d, b)| Some((d, b.parse::<u32>().ok()?)))
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "serial:DEVICE:BAUD"))?;
        let port = serialport::new(device, baud)
            .timeout(SERIAL_WAIT)
            .open_native()?;
        let writer = port.try_clone_native()?;
        Ok(Port::Serial {
            reader: Mutex::new(MavlinkReader::new(port)),
            writer: Mutex::new(writer),
        })
    }

    /// The next frame. `Io` errors of kind TimedOut or WouldBlock mean nothing came yet;
    /// other `Io` errors mean the link is gone; the rest are frames that did not parse.
    pub fn recv_raw(&self) -> Result<MAVLinkMessageRaw, MessageReadError> {
        match self {
            Port::Net(c) => c.recv_raw(),
            Port::Serial { reader, .. } => reader
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .read_any_raw_message::<MavMessage>(),
        }
    }

    pub fn send_raw(&self, raw: &MAVLinkMessageRaw) -> Result<(), MessageWriteError> {
        match self {
            Port::Net(c) => c.send_raw(raw).map(drop),
            Port::Serial { writer, .. } => {
                let bytes = match raw {
                    MAVLinkMessageRaw::V1(r) => r.raw_bytes(),
                    MAVLinkMessageRaw::V2(r) => r.raw_bytes(),
                };
                let mut w = writer.lock().unwrap_or_else(|e| e.into_inner());
                Ok(w.write_all(bytes)?)
            }
        }
    }

    pub fn send(&self, header: MavHeader, msg: &MavMessage) -> Result<(), MessageWriteError> {
        match self {
            Port::Net(c) => c.send(&header, msg).map(drop),
            Port::Serial { writer, .. } => {
                let mut w = writer.lock().unwrap_or_else(|e| e.into_inner());
                mavlink::write_versioned_msg(&mut *w, MavlinkVersion::V2, header, msg).map(drop)
            }
        }
    }
}
