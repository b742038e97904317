//! The MAVLink peers users have, as the tests run them: Python scripts in `tests/peers` on the
//! project's own environment (.venv, which scripts/setup.sh makes with the `mavsdk` and
//! `pymavlink` wheels), and a UDP relay that sits between such a peer and DigiView and counts
//! every command the peer sends, so a test can tell retries on the wire.

use mavlink::MavlinkReader;
use mavlink::dialects::common::{MavCmd, MavMessage};
use std::collections::BTreeMap;
use std::net::UdpSocket;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The project's Python, which has the peers; a missing one fails the test.
pub fn python() -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run scripts/setup.sh, which makes it with MAVSDK and pymavlink",
        p.display()
    );
    p
}

/// `tests/peers/NAME` run with [`python`] and `args`: its stdout (JSON lines) and stderr.
pub fn run_peer(name: &str, args: &[&str]) -> (String, String) {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/peers")
        .join(name);
    let out = Command::new(python())
        .arg("-u")
        .arg(&script)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("the peer runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{name} failed:\n{stdout}\n{stderr}");
    (stdout, stderr)
}

/// A peer in `tests/peers` that talks a line of JSON each way: its first line says it is
/// ready (or why not), then each line it is sent is answered with one. Killed when dropped.
pub struct LinePeer {
    child: std::process::Child,
    to: std::process::ChildStdin,
    from: std::io::BufReader<std::process::ChildStdout>,
}

impl LinePeer {
    /// `tests/peers/NAME` started with `args`, and its first line.
    pub fn start(name: &str, args: &[&str]) -> (LinePeer, serde_json::Value) {
        let script = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/peers")
            .join(name);
        let mut child = Command::new(python())
            .arg("-u")
            .arg(&script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{name} starts: {e}"));
        let (to, from) = (child.stdin.take().unwrap(), child.stdout.take().unwrap());
        let mut peer = LinePeer {
            child,
            to,
            from: std::io::BufReader::new(from),
        };
        let first = peer.line();
        (peer, first)
    }

    /// The next line, parsed.
    pub fn line(&mut self) -> serde_json::Value {
        use std::io::BufRead;
        let mut line = String::new();
        self.from.read_line(&mut line).expect("the peer answers");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line:?}"))
    }

    /// Sends `ask` and reads the answer.
    pub fn ask(&mut self, ask: &serde_json::Value) -> serde_json::Value {
        use std::io::Write;
        writeln!(self.to, "{ask}").expect("the peer reads");
        self.line()
    }
}

impl Drop for LinePeer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

const PITCHYAW: MavCmd = MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW;

/// What one command was: (target component, command id, param 1).
pub type CommandKey = (u8, u32, i64);

/// How often one command was sent, and how many of those were retries: sent again while
/// unanswered, between [`RETRY_AFTER`] and [`RETRY_WITHIN`] after the last send (MAVSDK
/// retransmits an unanswered command after half a second, with the same confirmation; its
/// plugins each ask for themselves, a few ms apart, and poll seconds apart).
#[derive(Clone, Copy, Debug, Default)]
pub struct Sent {
    pub count: u32,
    pub retries: u32,
    unanswered: Option<Instant>,
}

pub const RETRY_AFTER: Duration = Duration::from_millis(300);
pub const RETRY_WITHIN: Duration = Duration::from_millis(1500);

/// A relay between a peer (which sends to [`CountingRelay::port`]) and DigiView's MAVLink
/// port, counting the peer's COMMAND_LONGs and COMMAND_INTs and their retries.
pub struct CountingRelay {
    pub port: u16,
    pub sent: Arc<Mutex<BTreeMap<CommandKey, Sent>>>,
    /// Each gimbal command or message that sets a yaw rate, passed on: when, and the rate
    /// (deg/s).
    pub yaw_rates: Arc<Mutex<Vec<(Instant, f64)>>>,
    stop: Arc<AtomicBool>,
}

impl CountingRelay {
    pub fn start(digiview: u16) -> CountingRelay {
        let outer = UdpSocket::bind("127.0.0.1:0").unwrap();
        let inner = UdpSocket::bind("127.0.0.1:0").unwrap();
        inner.connect(("127.0.0.1", digiview)).unwrap();
        for s in [&outer, &inner] {
            s.set_read_timeout(Some(Duration::from_millis(100)))
                .unwrap();
        }
        let port = outer.local_addr().unwrap().port();
        let sent = Arc::new(Mutex::new(BTreeMap::new()));
        let yaw_rates = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let peer = Arc::new(Mutex::new(None));
        let (outer, inner) = (Arc::new(outer), Arc::new(inner));
        {
            let (outer, inner, stop, peer) =
                (outer.clone(), inner.clone(), stop.clone(), peer.clone());
            let (sent, yaw_rates) = (sent.clone(), yaw_rates.clone());
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !stop.load(Ordering::Relaxed) {
                    if let Ok((n, from)) = outer.recv_from(&mut buf) {
                        *peer.lock().unwrap() = Some(from);
                        count(&buf[..n], &sent, &yaw_rates);
                        let _ = inner.send(&buf[..n]);
                    }
                }
            });
        }
        {
            let (stop, sent) = (stop.clone(), sent.clone());
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !stop.load(Ordering::Relaxed) {
                    if let Ok(n) = inner.recv(&mut buf) {
                        answered(&buf[..n], &sent);
                        if let Some(to) = *peer.lock().unwrap() {
                            let _ = outer.send_to(&buf[..n], to);
                        }
                    }
                }
            });
        }
        CountingRelay {
            port,
            sent,
            yaw_rates,
            stop,
        }
    }
}

impl Drop for CountingRelay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Counts the commands in one datagram (one or more MAVLink frames), and notes the gimbal
/// yaw rates asked.
fn count(
    datagram: &[u8],
    sent: &Mutex<BTreeMap<CommandKey, Sent>>,
    yaw_rates: &Mutex<Vec<(Instant, f64)>>,
) {
    let mut reader = MavlinkReader::new(datagram);
    while let Ok((_, msg)) = reader.read_any_message::<MavMessage>() {
        let rate = match &msg {
            MavMessage::COMMAND_LONG(c) if c.command == PITCHYAW => Some(c.param4 as f64),
            MavMessage::COMMAND_INT(c) if c.command == PITCHYAW => Some(c.param4 as f64),
            MavMessage::GIMBAL_MANAGER_SET_PITCHYAW(m) => Some((m.yaw_rate as f64).to_degrees()),
            MavMessage::GIMBAL_MANAGER_SET_ATTITUDE(m) => {
                Some((m.angular_velocity_z as f64).to_degrees())
            }
            _ => None,
        };
        if let Some(rate) = rate {
            yaw_rates.lock().unwrap().push((Instant::now(), rate));
        }
        let key = match msg {
            MavMessage::COMMAND_LONG(c) => (c.target_component, c.command as u32, c.param1 as i64),
            MavMessage::COMMAND_INT(c) => (c.target_component, c.command as u32, c.param1 as i64),
            _ => continue,
        };
        let now = Instant::now();
        let mut sent = sent.lock().unwrap();
        let e = sent.entry(key).or_default();
        e.count += 1;
        let again = e.unanswered.map(|t| now - t);
        e.retries += again.is_some_and(|d| (RETRY_AFTER..RETRY_WITHIN).contains(&d)) as u32;
        e.unanswered = Some(now);
    }
}

/// Marks the commands a datagram from DigiView acknowledges as answered.
fn answered(datagram: &[u8], sent: &Mutex<BTreeMap<CommandKey, Sent>>) {
    let mut reader = MavlinkReader::new(datagram);
    while let Ok((header, msg)) = reader.read_any_message::<MavMessage>() {
        if let MavMessage::COMMAND_ACK(a) = msg {
            let mut sent = sent.lock().unwrap();
            for (_, s) in sent
                .iter_mut()
                .filter(|(k, _)| k.0 == header.component_id && k.1 == a.command as u32)
            {
                s.unanswered = None;
            }
        }
    }
}
