//! A one-off look at the link for `digiview doctor`: opens the endpoint as the link would,
//! says hello once a second (an autopilot behind udpout or tcpout answers only someone it has
//! heard), and waits for another system's HEARTBEAT.

use super::port::Port;
use super::{OWN_COMPONENT, outgoing};
use mavlink::dialects::common::MavMessage;
use mavlink::error::MessageReadError;
use mavlink::{MavHeader, Message};
use std::io::ErrorKind;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Who answered: system, component, and its HEARTBEAT's type and autopilot.
pub struct Heard {
    pub system: u8,
    pub component: u8,
    pub what: String,
}

/// Why no HEARTBEAT came.
#[derive(Debug, thiserror::Error)]
pub enum Unheard {
    #[error("cannot open it: {0}")]
    Open(std::io::Error),
    #[error("the link failed: {0}")]
    Failed(std::io::Error),
    #[error("no HEARTBEAT within {0:.0} s")]
    Silent(f64),
    #[error("the link closed")]
    Closed,
}

/// Opens `endpoint` (as [`super::Endpoint`] checked it) and waits up to `wait` for a
/// HEARTBEAT; the error says why none came.
pub fn heartbeat(endpoint: &str, wait: Duration) -> Result<Heard, Unheard> {
    let port = Arc::new(Port::open(endpoint).map_err(Unheard::Open)?);
    let done = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel();
    {
        let (port, done) = (port.clone(), done.clone());
        // The crate's UDP receive has no timeout: the reading thread is left to end with the
        // process when nothing comes.
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                let raw = match port.recv_raw() {
                    Ok(raw) => raw,
                    Err(MessageReadError::Io(e))
                        if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) =>
                    {
                        continue;
                    }
                    Err(MessageReadError::Io(e)) => {
                        let _ = tx.send(Err(Unheard::Failed(e)));
                        return;
                    }
                    Err(_) => continue,
                };
                let Ok(MavMessage::HEARTBEAT(h)) =
                    MavMessage::parse(raw.version(), raw.message_id(), raw.payload())
                else {
                    continue;
                };
                let _ = tx.send(Ok(Heard {
                    system: raw.system_id() as u8,
                    component: raw.component_id(),
                    what: format!("{:?}, {:?}", h.mavtype, h.autopilot),
                }));
                return;
            }
        });
    }
    let deadline = Instant::now() + wait;
    let mut sequence = 0u8;
    let outcome = loop {
        let header = MavHeader {
            system_id: 1,
            component_id: OWN_COMPONENT,
            sequence,
        };
        sequence = sequence.wrapping_add(1);
        let _ = port.send(header, &outgoing::heartbeat());
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break Err(Unheard::Silent(wait.as_secs_f64()));
        }
        match rx.recv_timeout(left.min(Duration::from_secs(1))) {
            Ok(answer) => break answer,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break Err(Unheard::Closed),
        }
    };
    done.store(true, Ordering::Relaxed);
    outcome
}
