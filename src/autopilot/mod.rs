//! The autopilot link, beside the frame path: MAVLink 2 (MAVLink 1 read too, common dialect)
//! from ArduPilot or PX4 over UDP, TCP or a serial port. It feeds the vehicle's attitude, on
//! the frame's own clock (`clock`), into the telemetry the frame loop renders each frame
//! with, and the attitude and position into the live state the control protocol reads
//! (`vehicle` makes sense of the messages). Its threads never touch the frame loop: a
//! receiving thread reopens the link with back-off whenever it fails, a sending thread
//! (`outgoing`) says DigiView is there (HEARTBEAT), asks the autopilot for the rates it needs
//! and for its time (TIMESYNC), and watches for the attitude going stale. Other components
//! of DigiView (the views as cameras and gimbals, `crate::cameras`) speak on the same link:
//! they see every message that arrives and send through an [`Outbox`], on a thread of theirs.

pub mod clock;
mod outgoing;
mod port;
pub mod probe;
pub mod sim;
pub mod vehicle;

use crate::head::config::MavlinkConfig;
use crate::head::telemetry::Telemetry;
use crate::protocol::params::Autopilot;
use crate::source::clock_us;
use crate::state::{Invalid, Live};
use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, Message, SigningConfig, SigningData};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tracing::{info, warn};
use vehicle::{Update, Vehicle};

/// No attitude for this long and the views hold the last one, reported.
pub const STALE: Duration = Duration::from_millis(500);
/// How often the link's state is logged, and when first.
const REPORT_EVERY: Duration = Duration::from_secs(30);
const FIRST_REPORT: Duration = Duration::from_secs(3);
/// DigiView's own component on the link (MAV_COMP_ID_ONBOARD_COMPUTER).
const OWN_COMPONENT: u8 = 191;
/// The live state's vehicle is brought up to date at most this often (the frames take the
/// attitude from the telemetry at every sample).
const LIVE_EVERY: Duration = Duration::from_millis(20);

/// Where the link goes: `off`, or an address the `mavlink` crate opens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    Off,
    Address(String),
}

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EndpointError {
    #[error(
        "mavlink endpoint {0:?}: use udpin:ADDR:PORT, udpout:HOST:PORT, tcpin:ADDR:PORT, \\
         tcpout:HOST:PORT, serial:DEVICE:BAUD or off"
    )]
    Form(String),
    #[error("mavlink endpoint {0:?}: {1}")]
    Part(String, &'static str),
}

impl std::str::FromStr for Endpoint {
    type Err = EndpointError;
    fn from_str(s: &str) -> Result<Endpoint, EndpointError> {
        if s.eq_ignore_ascii_case("off") {
            return Ok(Endpoint::Off);
        }
        let form = || EndpointError::Form(s.to_string());
        let (kind, rest) = s.split_once(':').ok_or_else(form)?;
        let (head, tail) = rest.rsplit_once(':').ok_or_else(form)?;
        match kind {
            "udpin" | "udpout" | "tcpin" | "tcpout" => {
                if head.is_empty() {
                    return Err(EndpointError::Part(s.into(), "no address"));
                }
                tail.parse::<u16>()
                    .map_err(|_| EndpointError::Part(s.into(), "the port is not 0..=65535"))?;
            }
            "serial" => {
                if head.is_empty() {
                    return Err(EndpointError::Part(s.into(), "no device"));
                }
                match tail.parse::<u32>() {
                    Ok(b) if b > 0 => {}
                    _ => {
                        return Err(EndpointError::Part(
                            s.into(),
                            "the baud rate is not a number",
                        ));
                    }
                }
            }
            _ => return Err(form()),
        }
        mavlink::ConnectionAddress::parse_address(s).map_err(|_| form())?;
        Ok(Endpoint::Address(s.to_string()))
    }
}

impl Endpoint {
    /// Where a peer on this machine sends to be heard by this endpoint: its own port on
    /// loopback when it listens (udpin, tcpin); None when it is off or goes elsewhere.
    pub fn loopback_peer(&self) -> Option<String> {
        let Endpoint::Address(a) = self else {
            return None;
        };
        let (kind, rest) = a.split_once(':')?;
        let (_, port) = rest.rsplit_once(':')?;
        match kind {
            "udpin" => Some(format!("udpout:127.0.0.1:{port}")),
            "tcpin" => Some(format!("tcpout:127.0.0.1:{port}")),
            _ => None,
        }
    }
}

type Connection = Arc<port::Port>;

/// The 32-byte signing key of `signing_key`: 64 hex digits as they are, anything else a
/// passphrase hashed with SHA-256 (as MAVProxy's `signing setup` and Mission Planner do).
pub fn signing_key(text: &str) -> [u8; 32] {
    let hex = |i: usize| u8::from_str_radix(text.get(2 * i..2 * i + 2)?, 16).ok();
    if text.len() == 64
        && let Some(bytes) = (0..32).map(hex).collect::<Option<Vec<u8>>>()
    {
        return bytes.try_into().expect("32 bytes");
    }
    use sha2::Digest;
    sha2::Sha256::digest(text.as_bytes()).into()
}

/// What the link knows now, for the health line and the docs' `ctl`.
#[derive(Default)]
pub struct LinkStatus {
    pub messages: AtomicU64,
    /// With signing on: messages ignored for a missing or wrong signature.
    pub unsigned: AtomicU64,
    /// Local time of the newest attitude sample, µs (0: none yet).
    pub attitude_us: AtomicU64,
    pub attitudes: AtomicU64,
    /// Attitude samples over the last second, millihertz.
    pub attitude_mhz: AtomicU64,
    pub autopilot: Mutex<Option<(u8, u8)>>,
    pub clock: Mutex<clock::ClockState>,
    pub connected: AtomicBool,
}

impl LinkStatus {
    /// The link's state as the control protocol's AUTOPILOT reports it.
    pub fn param(&self) -> Autopilot {
        let newest = self.attitude_us.load(Ordering::Relaxed);
        let age = clock_us().saturating_sub(newest);
        let link = match (self.connected.load(Ordering::Relaxed), newest) {
            (false, _) => 1,
            (true, 0) => 2,
            _ if age > STALE.as_micros() as u64 => 4,
            _ => 3,
        };
        let (system_id, component_id) = self
            .autopilot
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .unwrap_or_default();
        let c = *self.clock.lock().unwrap_or_else(|e| e.into_inner());
        Autopilot {
            link,
            system_id,
            component_id,
            attitude_rate: (self.attitude_mhz.load(Ordering::Relaxed) as f64 / 1e3).round() as u16,
            attitude_age: if newest == 0 { 0.0 } else { age as f64 / 1e6 },
            clock: match (c.samples, c.fitted) {
                (0, _) => 0,
                (_, false) => 1,
                (_, true) => 2,
            },
            clock_offset: c.offset_us as f64 / 1e6,
            clock_drift_ppm: c.drift_ppm.round() as i16,
            clock_span: c.span_us as f64 / 1e6,
            timesync_trips: c.trips.min(255) as u8,
            link_delay_us: c.link_delay_us.map_or(0, |d| d.round() as u32),
            messages: self.messages.load(Ordering::Relaxed) as u32,
            unsigned: self.unsigned.load(Ordering::Relaxed) as u32,
        }
    }
}

/// The running link; dropping it stops its threads.
pub struct Link {
    pub status: Arc<LinkStatus>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// A part of DigiView that speaks on the link as components of its own: it sees every
/// message that arrives and is ticked every [`TICK`] on a thread of its own.
pub trait Components: Send + Sync {
    fn handle(&self, out: &Outbox, from: &MavHeader, msg: &MavMessage);
    fn tick(&self, out: &Outbox);
}

/// How often [`Components::tick`] runs.
pub const TICK: Duration = Duration::from_millis(20);

/// Sends on the link as one of DigiView's components.
#[derive(Clone)]
pub struct Outbox(Arc<Shared>);

impl Outbox {
    /// The system DigiView's components belong to: the autopilot's, once it is known (1
    /// until then).
    pub fn system_id(&self) -> u8 {
        self.0
            .status
            .autopilot
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .map_or(1, |a| a.0)
    }

    /// Sends `msg` from `component` (signed when signing is on); false while the link is
    /// down.
    pub fn send(&self, component: u8, msg: &MavMessage) -> bool {
        let shared = &*self.0;
        let Some(c) = shared.connection() else {
            return false;
        };
        let header = MavHeader {
            system_id: self.system_id().into(),
            component_id: component,
            sequence: 0,
        };
        outgoing::send_one(shared, &c, header, msg);
        true
    }
}

/// What both threads share.
struct Shared {
    address: String,
    cfg: MavlinkConfig,
    live: Arc<Live>,
    telemetry: Arc<Telemetry>,
    status: Arc<LinkStatus>,
    connection: Mutex<Option<Connection>>,
    /// The local times (µs) of the TIMESYNC requests not answered yet, newest last.
    syncs_sent: Mutex<VecDeque<u64>>,
    components: Option<Arc<dyn Components>>,
    /// With signing on: the key, checking what comes in and signing what goes out.
    signing: Option<SigningData>,
    stop: Arc<AtomicBool>,
}

impl Shared {
    /// The open connection, while there is one.
    fn connection(&self) -> Option<Connection> {
        self.connection
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

impl Link {
    /// Starts the link of `cfg` (None when it is off), with `components` speaking on it.
    pub fn start(
        cfg: &MavlinkConfig,
        live: Arc<Live>,
        telemetry: Arc<Telemetry>,
        components: Option<Arc<dyn Components>>,
    ) -> Result<Option<Link>, EndpointError> {
        let Endpoint::Address(address) = cfg.endpoint.parse()? else {
            return Ok(None);
        };
        let status = Arc::new(LinkStatus::default());
        let stop = Arc::new(AtomicBool::new(false));
        let shared = Arc::new(Shared {
            address,
            cfg: cfg.clone(),
            live,
            telemetry,
            status: status.clone(),
            connection: Mutex::new(None),
            syncs_sent: Mutex::new(VecDeque::new()),
            components,
            signing: cfg.signing_key.as_deref().map(|k| {
                SigningData::from_config(SigningConfig::new(signing_key(k), 0, true, false))
            }),
            stop: stop.clone(),
        });
        let mut threads = vec![];
        for (name, run) in [
            ("mavlink-rx", receive as fn(&Arc<Shared>)),
            ("mavlink-tx", |s: &Arc<Shared>| outgoing::send(s)),
        ] {
            let shared = shared.clone();
            if let Ok(t) = std::thread::Builder::new()
                .name(name.into())
                .spawn(move || run(&shared))
            {
                threads.push(t);
            }
        }
        if let Some(components) = shared.components.clone() {
            let out = Outbox(shared.clone());
            let stop = stop.clone();
            if let Ok(t) = std::thread::Builder::new()
                .name("mavlink-components".into())
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        std::thread::sleep(TICK);
                        components.tick(&out);
                    }
                })
            {
                threads.push(t);
            }
        }
        info!("mavlink: {}", cfg.endpoint);
        Ok(Some(Link {
            status,
            stop,
            threads,
        }))
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // A receiving thread blocked on a silent link is left to end with the process.
        for t in self.threads.drain(..) {
            if t.is_finished() {
                let _ = t.join();
            }
        }
    }
}

/// Opens the link, reads it until it fails, again with back-off (1 s doubling to 10 s, back
/// to 1 s after a link that held 10 s).
fn receive(shared: &Arc<Shared>) {
    let mut backoff = Duration::from_secs(1);
    let mut vehicle = Vehicle::new(shared.cfg.system_id);
    while !shared.stop.load(Ordering::Relaxed) {
        let why = match port::Port::open(&shared.address) {
            Ok(c) => {
                let opened = Instant::now();
                let Some(why) = read(shared, Arc::from(c), &mut vehicle) else {
                    return;
                };
                if opened.elapsed() > Duration::from_secs(10) {
                    backoff = Duration::from_secs(1);
                }
                why
            }
            Err(e) => e.to_string(),
        };
        warn!(
            "mavlink {}: {why}; retrying in {} s",
            shared.address,
            backoff.as_secs()
        );
        std::thread::sleep(backoff);
        backoff = (backoff * 2).min(Duration::from_secs(10));
    }
}

/// Reads an open link until it fails (why) or the link stops (None).
fn read(shared: &Arc<Shared>, connection: Connection, vehicle: &mut Vehicle) -> Option<String> {
    let out = Outbox(shared.clone());
    *shared.connection.lock().unwrap_or_else(|e| e.into_inner()) = Some(connection.clone());
    shared.status.connected.store(true, Ordering::Relaxed);
    let mut last_live = Instant::now() - LIVE_EVERY;
    let why = loop {
        if shared.stop.load(Ordering::Relaxed) {
            break None;
        }
        match connection.recv_raw() {
            Ok(raw) => {
                if let Some((header, msg)) = accept(shared, &raw) {
                    apply(shared, vehicle, &header, &msg, &mut last_live);
                    if let Some(c) = &shared.components {
                        c.handle(&out, &header, &msg);
                    }
                }
            }
            Err(mavlink::error::MessageReadError::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock
                        | std::io::ErrorKind::TimedOut
                        | std::io::ErrorKind::Interrupted
                ) => {}
            Err(mavlink::error::MessageReadError::Io(e)) => break Some(e.to_string()),
            // A frame that does not parse (unknown id, bad field): skipped.
            Err(_) => {}
        }
    };
    *shared.connection.lock().unwrap_or_else(|e| e.into_inner()) = None;
    shared.status.connected.store(false, Ordering::Relaxed);
    why
}

/// A frame's header and message, if it passes signing (when on) and parses.
fn accept(shared: &Shared, raw: &MAVLinkMessageRaw) -> Option<(MavHeader, MavMessage)> {
    if let Some(signing) = &shared.signing {
        let signed = match raw {
            MAVLinkMessageRaw::V2(v2) => signing.verify_signature(v2),
            MAVLinkMessageRaw::V1(_) => false,
        };
        if !signed {
            shared.status.unsigned.fetch_add(1, Ordering::Relaxed);
            return None;
        }
    }
    let msg = MavMessage::parse(raw.version(), raw.message_id(), raw.payload()).ok()?;
    let header = MavHeader {
        system_id: raw.system_id(),
        component_id: raw.component_id(),
        sequence: raw.sequence(),
    };
    Some((header, msg))
}

/// One message: into the telemetry and, at most every [`LIVE_EVERY`], the live state.
fn apply(
    shared: &Shared,
    vehicle: &mut Vehicle,
    header: &MavHeader,
    msg: &MavMessage,
    last_live: &mut Instant,
) {
    let status = &shared.status;
    status.messages.fetch_add(1, Ordering::Relaxed);
    let Some(update) = vehicle.handle(header, msg, clock_us()) else {
        return;
    };
    match update {
        Update::Found(system, component) => {
            info!("mavlink: the autopilot is system {system}, component {component}");
            *status.autopilot.lock().unwrap_or_else(|e| e.into_inner()) = Some((system, component));
        }
        Update::Attitude { t_us, attitude } => {
            shared.telemetry.external_attitude(t_us, attitude);
            status.attitude_us.fetch_max(t_us, Ordering::Relaxed);
            status.attitudes.fetch_add(1, Ordering::Relaxed);
            *status.clock.lock().unwrap_or_else(|e| e.into_inner()) = vehicle.clock.state();
            if last_live.elapsed() >= LIVE_EVERY {
                *last_live = Instant::now();
                let written = shared.live.update(|s| {
                    (
                        s.vehicle.attitude.yaw,
                        s.vehicle.attitude.pitch,
                        s.vehicle.attitude.roll,
                    ) = (attitude.yaw, attitude.pitch, attitude.roll);
                    Ok::<_, Invalid>(())
                });
                if let Err(e) = written {
                    tracing::warn!("mavlink: the attitude was refused: {e}");
                }
            }
        }
        Update::TimeSync { remote_us, ours_us } => {
            // Only an answer to a request of ours, each once.
            let mut sent = shared.syncs_sent.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(i) = sent.iter().position(|&t| t == ours_us) {
                sent.remove(i);
                drop(sent);
                vehicle.clock.observe_sync(remote_us, ours_us, clock_us());
                *status.clock.lock().unwrap_or_else(|e| e.into_inner()) = vehicle.clock.state();
            }
        }
        Update::TimeSyncRequest { ts1 } => outgoing::answer_timesync(shared, header, ts1),
        Update::Position(p) => {
            shared.telemetry.position(p);
            let written = shared.live.update(|s| {
                s.vehicle.position = p;
                Ok::<_, Invalid>(())
            });
            if let Err(e) = written {
                tracing::warn!("mavlink: the position was refused: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signing_key_is_64_hex_digits_or_a_passphrase() {
        let hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
        assert_eq!(signing_key(hex)[..4], [0x00, 0x11, 0x22, 0x33]);
        // SHA-256("abc"), the standard's own test vector.
        assert_eq!(signing_key("abc")[..4], [0xba, 0x78, 0x16, 0xbf]);
    }

    #[test]
    fn endpoints_are_checked() {
        for ok in [
            "udpin:0.0.0.0:14550",
            "udpout:192.168.1.10:14550",
            "tcpin:0.0.0.0:5760",
            "tcpout:127.0.0.1:5760",
            "serial:/dev/ttyAMA0:921600",
        ] {
            assert_eq!(ok.parse(), Ok(Endpoint::Address(ok.into())), "{ok}");
        }
        assert_eq!("off".parse(), Ok(Endpoint::Off));
        let peer = |e: &str| e.parse::<Endpoint>().unwrap().loopback_peer();
        assert_eq!(
            peer("udpin:0.0.0.0:14550").as_deref(),
            Some("udpout:127.0.0.1:14550")
        );
        assert_eq!(
            peer("tcpin:0.0.0.0:5760").as_deref(),
            Some("tcpout:127.0.0.1:5760")
        );
        assert_eq!(peer("udpout:10.0.0.2:14550"), None);
        assert_eq!(peer("off"), None);
        for bad in [
            "udp:1.2.3.4:5",
            "udpin:0.0.0.0",
            "udpin:0.0.0.0:99999",
            "tcpout::5760",
            "serial:/dev/ttyS0:fast",
            "serial:/dev/ttyS0",
            "file:log.tlog",
            "",
        ] {
            assert!(bad.parse::<Endpoint>().is_err(), "{bad}");
        }
    }
}
