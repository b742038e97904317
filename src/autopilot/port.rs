//! One open link to the autopilot, whatever carries it: udpout through the `mavlink` crate's
//! own transport, the rest opened here. TCP is opened here to turn Nagle's algorithm off
//! (small frames go both ways; with it on, each end waits for the other's delayed ACK). The crate's serial transport retries
//! every read error inside its receive call, a timeout and a vanished device alike, so an
//! unplugged USB adapter would spin there unseen and the link could never reopen: here a
//! serial read waits at most [`SERIAL_WAIT`] and a hang-up ends the link like any other
//! failure. A listening UDP port (`udpin`) is opened here too: the crate's replies go to
//! whoever sent last, but a companion computer's port is shared by the autopilot and the
//! ground stations (each camera and gimbal must reach the ground station, the rate requests
//! the autopilot), so here everything sent goes to every peer a whole frame came from in the
//! last [`PEER_SILENCE`], as mavlink-router does.

use crate::supervise::Locked;
use mavlink::dialects::common::MavMessage;
use mavlink::error::{MessageReadError, MessageWriteError};
use mavlink::{MAVLinkMessageRaw, MavConnection, MavHeader, MavlinkReader, MavlinkVersion};
use std::io::{self, Read, Write};
use std::net::{IpAddr, SocketAddr, TcpListener, TcpStream, ToSocketAddrs, UdpSocket};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long a serial read waits for a byte before the link's loop looks around.
const SERIAL_WAIT: Duration = Duration::from_millis(100);
/// A UDP peer silent for this long is sent nothing more until it is heard again.
pub const PEER_SILENCE: Duration = Duration::from_secs(10);
/// The most UDP peers sent to at once (the newest kept).
const MAX_PEERS: usize = 16;

pub enum Port {
    /// The crate's transport (udpout), and the address it sends to.
    Net(
        Box<dyn MavConnection<MavMessage> + Send + Sync>,
        Option<IpAddr>,
    ),
    Listening {
        reader: Mutex<MavlinkReader<PeerRead>>,
        socket: UdpSocket,
        peers: Peers,
    },
    /// A UDP socket of ours sending to one address (the demo's simulated flight: the link
    /// it sends to tells it from a real autopilot by the address it sends from).
    Sending {
        reader: Mutex<MavlinkReader<PeerRead>>,
        socket: UdpSocket,
    },
    /// A byte stream: a serial port, or a TCP connection (and its peer's address).
    Serial {
        reader: Mutex<MavlinkReader<Box<dyn Read + Send>>>,
        writer: Mutex<Box<dyn Write + Send>>,
        remote: Option<IpAddr>,
    },
}

impl Port {
    /// Opens `address` (an endpoint as [`super::Endpoint`] checked it).
    pub fn open(address: &str) -> io::Result<Port> {
        if let Some(bind) = address.strip_prefix("udpin:") {
            let socket = UdpSocket::bind(bind)?;
            socket.set_read_timeout(Some(SERIAL_WAIT))?;
            let peers = Peers::default();
            return Ok(Port::Listening {
                reader: Mutex::new(MavlinkReader::new(PeerRead {
                    socket: socket.try_clone()?,
                    last_from: None,
                })),
                socket,
                peers,
            });
        }
        if let Some(to) = address.strip_prefix("tcpout:") {
            return Port::tcp(TcpStream::connect(to)?);
        }
        if let Some(bind) = address.strip_prefix("tcpin:") {
            let (stream, _) = TcpListener::bind(bind)?.accept()?;
            return Port::tcp(stream);
        }
        let Some(serial) = address.strip_prefix("serial:") else {
            let remote = address
                .split_once(':')
                .and_then(|(_, to)| to.to_socket_addrs().ok()?.next())
                .map(|a| a.ip());
            return mavlink::connect::<MavMessage>(address).map(|c| Port::Net(Box::new(c), remote));
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
            reader: Mutex::new(MavlinkReader::new(Box::new(port))),
            writer: Mutex::new(Box::new(writer)),
            remote: None,
        })
    }

    /// A UDP socket on loopback sending to `to` (host:port), its own address known.
    pub fn udp_to(to: &str) -> io::Result<Port> {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        socket.connect(to)?;
        socket.set_read_timeout(Some(SERIAL_WAIT))?;
        Ok(Port::Sending {
            reader: Mutex::new(MavlinkReader::new(PeerRead {
                socket: socket.try_clone()?,
                last_from: None,
            })),
            socket,
        })
    }

    /// The address this end sends from, on a UDP socket of ours sending to one address.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match self {
            Port::Sending { socket, .. } => socket.local_addr().ok(),
            _ => None,
        }
    }

    /// A TCP connection, with Nagle's algorithm off: both ends send small frames both ways,
    /// and with it on each end's next frame waits for the other's delayed ACK (the attitude
    /// arrived up to 40 ms late once DigiView's cameras spoke on the link).
    fn tcp(stream: TcpStream) -> io::Result<Port> {
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(SERIAL_WAIT))?;
        let writer = stream.try_clone()?;
        let remote = stream.peer_addr().ok().map(|a| a.ip());
        Ok(Port::Serial {
            reader: Mutex::new(MavlinkReader::new(Box::new(stream))),
            writer: Mutex::new(Box::new(writer)),
            remote,
        })
    }

    /// The next frame. `Io` errors of kind TimedOut or WouldBlock mean nothing came yet;
    /// other `Io` errors mean the link is gone; the rest are frames that did not parse.
    pub fn recv_raw(&self) -> Result<MAVLinkMessageRaw, MessageReadError> {
        match self {
            Port::Net(c, _) => c.recv_raw(),
            Port::Sending { reader, .. } => reader.locked().read_any_raw_message::<MavMessage>(),
            Port::Listening { reader, peers, .. } => {
                // A sender becomes a peer with its first whole frame: noise from any port
                // cannot crowd the autopilot or a ground station out.
                let mut reader = reader.locked();
                let raw = reader.read_any_raw_message::<MavMessage>()?;
                if let Some(from) = reader.get_ref().last_from {
                    peers.heard(from);
                }
                Ok(raw)
            }
            Port::Serial { reader, .. } => reader.locked().read_any_raw_message::<MavMessage>(),
        }
    }

    /// The address the last frame [`Port::recv_raw`] gave came from: the sender of a
    /// listening UDP port's datagram, a TCP or udpout link's peer; None on a serial line.
    pub fn sender(&self) -> Option<IpAddr> {
        match self {
            Port::Net(_, remote) | Port::Serial { remote, .. } => *remote,
            Port::Listening { .. } | Port::Sending { .. } => self.sender_addr().map(|a| a.ip()),
        }
    }

    /// The address and port the last frame came from, on a UDP socket of ours.
    pub fn sender_addr(&self) -> Option<SocketAddr> {
        match self {
            Port::Listening { reader, .. } | Port::Sending { reader, .. } => {
                reader.locked().get_ref().last_from
            }
            _ => None,
        }
    }

    pub fn send_raw(&self, raw: &MAVLinkMessageRaw) -> Result<(), MessageWriteError> {
        let bytes = match raw {
            MAVLinkMessageRaw::V1(r) => r.raw_bytes(),
            MAVLinkMessageRaw::V2(r) => r.raw_bytes(),
        };
        match self {
            Port::Net(c, _) => c.send_raw(raw).map(drop),
            Port::Listening { socket, peers, .. } => Ok(peers.send(socket, bytes)?),
            Port::Sending { socket, .. } => Ok(socket.send(bytes).map(drop)?),
            Port::Serial { writer, .. } => {
                let mut w = writer.locked();
                Ok(w.write_all(bytes)?)
            }
        }
    }

    /// Sends `msg`, of any dialect, as MAVLink 2.
    pub fn send<M: mavlink::Message>(
        &self,
        header: MavHeader,
        msg: &M,
    ) -> Result<(), MessageWriteError> {
        match self {
            Port::Net(c, _) => {
                let mut raw = mavlink::MAVLinkV2MessageRaw::new();
                raw.serialize_message(header, msg);
                c.send_raw(&MAVLinkMessageRaw::V2(raw)).map(drop)
            }
            Port::Listening { socket, peers, .. } => {
                let mut bytes = Vec::with_capacity(280);
                mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, msg)?;
                Ok(peers.send(socket, &bytes)?)
            }
            Port::Sending { socket, .. } => {
                let mut bytes = Vec::with_capacity(280);
                mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, msg)?;
                Ok(socket.send(&bytes).map(drop)?)
            }
            Port::Serial { writer, .. } => {
                let mut w = writer.locked();
                mavlink::write_versioned_msg(&mut *w, MavlinkVersion::V2, header, msg).map(drop)
            }
        }
    }
}

/// The addresses a listening UDP port has heard from, and when last.
#[derive(Clone, Default)]
pub struct Peers(Arc<Mutex<Vec<(SocketAddr, Instant)>>>);

impl Peers {
    fn heard(&self, from: SocketAddr) {
        let mut peers = self.0.locked();
        match peers.iter_mut().find(|(a, _)| *a == from) {
            Some(p) => p.1 = Instant::now(),
            None => {
                if peers.len() == MAX_PEERS {
                    peers.sort_by_key(|p| std::cmp::Reverse(p.1));
                    peers.pop();
                }
                peers.push((from, Instant::now()));
            }
        }
    }

    /// `bytes` to every peer heard lately; an unreachable one does not stop the others.
    fn send(&self, socket: &UdpSocket, bytes: &[u8]) -> io::Result<()> {
        let mut peers = self.0.locked();
        peers.retain(|p| p.1.elapsed() < PEER_SILENCE);
        for (to, _) in peers.iter() {
            let _ = socket.send_to(bytes, to);
        }
        Ok(())
    }
}

/// A listening UDP socket read as a byte stream (each datagram whole, as MAVLink over UDP
/// sends them), remembering who sent the last one.
pub struct PeerRead {
    socket: UdpSocket,
    last_from: Option<SocketAddr>,
}

impl Read for PeerRead {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let (n, from) = self.socket.recv_from(buf)?;
        self.last_from = Some(from);
        Ok(n)
    }
}
