//! The blocking control client behind `digiview ctl`: one request, its replies, on the same
//! codec as the server. TCP by default; UDP sends one datagram and waits for the answer.

use crate::protocol::{Body, DecodeError, FRAME_LEN, Message, Param, ParamType, Verdict};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs, UdpSocket};
use std::time::Duration;

#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("`{0}` is not a HOST:PORT address")]
    Address(String),
    #[error(
        "cannot reach the DigiView control server at {addr}: {source} (is `digiview serve` running there?)"
    )]
    Connect {
        addr: String,
        source: std::io::Error,
    },
    #[error("no reply from {addr} within {secs:.1} s{hint}")]
    Timeout {
        addr: String,
        secs: f64,
        hint: &'static str,
    },
    #[error("connection to {addr}: {source}")]
    Io {
        addr: String,
        source: std::io::Error,
    },
    #[error(
        "the server answered {} to {request}: {}",
        verdict.message_type(),
        reason.as_deref().unwrap_or(verdict.meaning())
    )]
    Refused {
        request: String,
        verdict: Verdict,
        /// The server's reason (REFUSAL), where it gives one.
        reason: Option<String>,
    },
    #[error("the server's reply is not a valid frame: {0}")]
    Decode(#[from] DecodeError),
    #[error("unexpected reply to {request}: {got:?}")]
    Unexpected { request: String, got: Body },
}

/// Sees every frame sent (`true`) and received (`false`).
pub type Trace = Box<dyn FnMut(bool, &[u8; FRAME_LEN])>;

enum Link {
    Tcp(TcpStream),
    Udp(UdpSocket),
}

pub struct Client {
    link: Link,
    addr: String,
    timeout: Duration,
    /// For `--hex`.
    pub trace: Option<Trace>,
}

impl Client {
    pub fn connect(addr: &str, udp: bool, timeout: Duration) -> Result<Client, ClientError> {
        let target = resolve(addr)?;
        let connect_err = |source| ClientError::Connect {
            addr: addr.to_string(),
            source,
        };
        let link = if udp {
            let any: SocketAddr = if target.is_ipv4() {
                "0.0.0.0:0".parse().expect("literal")
            } else {
                "[::]:0".parse().expect("literal")
            };
            let s = UdpSocket::bind(any).map_err(connect_err)?;
            s.connect(target).map_err(connect_err)?;
            s.set_read_timeout(Some(timeout)).map_err(connect_err)?;
            Link::Udp(s)
        } else {
            let s = TcpStream::connect_timeout(&target, timeout).map_err(connect_err)?;
            s.set_read_timeout(Some(timeout)).map_err(connect_err)?;
            s.set_write_timeout(Some(timeout)).map_err(connect_err)?;
            let _ = s.set_nodelay(true);
            Link::Tcp(s)
        };
        Ok(Client {
            link,
            addr: addr.to_string(),
            timeout,
            trace: None,
        })
    }

    fn io_err(&self, source: std::io::Error) -> ClientError {
        use std::io::ErrorKind::{TimedOut, WouldBlock};
        if matches!(source.kind(), WouldBlock | TimedOut) {
            return ClientError::Timeout {
                addr: self.addr.clone(),
                secs: self.timeout.as_secs_f64(),
                hint: match self.link {
                    Link::Udp(_) => " (over UDP an absent server looks like this)",
                    Link::Tcp(_) => "",
                },
            };
        }
        if let Link::Udp(_) = self.link
            && source.kind() == std::io::ErrorKind::ConnectionRefused
        {
            return ClientError::Connect {
                addr: self.addr.clone(),
                source,
            };
        }
        ClientError::Io {
            addr: self.addr.clone(),
            source,
        }
    }

    pub fn send(&mut self, body: Body) -> Result<(), ClientError> {
        let frame = Message::new(body).encode();
        if let Some(t) = &mut self.trace {
            t(true, &frame);
        }
        let sent = match &mut self.link {
            Link::Tcp(s) => s.write_all(&frame),
            Link::Udp(s) => s.send(&frame).map(|_| ()),
        };
        sent.map_err(|e| self.io_err(e))
    }

    pub fn receive(&mut self) -> Result<Message, ClientError> {
        let mut frame = [0u8; FRAME_LEN];
        let got = match &mut self.link {
            Link::Tcp(s) => s.read_exact(&mut frame).map(|_| FRAME_LEN),
            Link::Udp(s) => s.recv(&mut frame),
        };
        let n = got.map_err(|e| self.io_err(e))?;
        if let Some(t) = &mut self.trace {
            t(false, &frame);
        }
        Ok(Message::decode(&frame[..n])?)
    }

    /// Sends a request and reads its replies: one, or for DETECTED_ROI 254/255 as many as
    /// the first reply's total_detections says.
    pub fn request(&mut self, body: Body) -> Result<Vec<Message>, ClientError> {
        self.send(body)?;
        let first = self.receive()?;
        let expected = match (&body, &first.body) {
            (Body::Get(Param::DetectedRoi(q)), Body::Current(Param::DetectedRoi(r)))
                if q.index >= 254 =>
            {
                (r.total_detections as usize).max(1)
            }
            _ => 1,
        };
        let mut replies = vec![first];
        while replies.len() < expected {
            replies.push(self.receive()?);
        }
        Ok(replies)
    }

    /// GET: the current values (several for DETECTED_ROI 254/255).
    pub fn get(&mut self, query: Param) -> Result<Vec<Param>, ClientError> {
        let request = format!("GET {}", query.param_type());
        let mut params = Vec::new();
        for m in self.request(Body::Get(query))? {
            match m.body {
                Body::Current(p) if p.param_type() == query.param_type() => params.push(p),
                Body::Verdict(verdict, _) => return Err(self.refused(request, verdict)),
                got => return Err(ClientError::Unexpected { request, got }),
            }
        }
        Ok(params)
    }

    /// A refusal, with the server's reason for it where the server gives one (REFUSAL;
    /// older servers answer UNKNOWN to it and the verdict's meaning stands).
    fn refused(&mut self, request: String, verdict: Verdict) -> ClientError {
        let reason = self.reason().filter(|t| !t.is_empty());
        ClientError::Refused {
            request,
            verdict,
            reason,
        }
    }

    /// REFUSAL, all its parts.
    fn reason(&mut self) -> Option<String> {
        let mut text = String::new();
        let mut part = 0u8;
        loop {
            let mut q = ParamType::RefusalReason.zeroed();
            q.set_field("part", part as f64).ok()?;
            let replies = self.request(Body::Get(q)).ok()?;
            let Some(Body::Current(Param::RefusalReason(r))) = replies.first().map(|m| m.body)
            else {
                return None;
            };
            text.push_str(&r.reason.text());
            part += 1;
            if part >= r.parts {
                return Some(text);
            }
        }
    }

    /// GET of a type that has exactly one reply.
    pub fn get_one(&mut self, query: Param) -> Result<Param, ClientError> {
        Ok(self.get(query)?.remove(0))
    }

    pub fn set(&mut self, param: Param) -> Result<(), ClientError> {
        self.expect_ack(Body::Set(param), format!("SET {}", param.param_type()))
    }

    pub fn quit(&mut self) -> Result<(), ClientError> {
        self.expect_ack(Body::Quit(0), "QUIT".into())
    }

    /// EMPTY: a keep-alive that the server acknowledges.
    pub fn ping(&mut self) -> Result<(), ClientError> {
        self.expect_ack(Body::Empty(0), "EMPTY".into())
    }

    fn expect_ack(&mut self, body: Body, request: String) -> Result<(), ClientError> {
        let reply = self.request(body)?.remove(0);
        match reply.body {
            Body::Verdict(Verdict::Acknowledgement, _) => Ok(()),
            Body::Verdict(verdict, _) => Err(self.refused(request, verdict)),
            got => Err(ClientError::Unexpected { request, got }),
        }
    }
}

/// The first socket address `HOST:PORT` names.
pub fn resolve(addr: &str) -> Result<SocketAddr, ClientError> {
    addr.to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| ClientError::Address(addr.to_string()))
}

/// A GET query for `kind` addressed to camera `cam` (ignored by whole-system types).
pub fn query(kind: ParamType, cam: u8) -> Param {
    let mut q = kind.zeroed();
    if kind.per_camera() {
        q.set_field("cam_id", cam as f64)
            .expect("per-camera types have cam_id");
    }
    q
}
