//! The autopilot link, a service beside the frame path: MAVLink 2 (MAVLink 1 read too,
//! common dialect) from ArduPilot or PX4 over UDP, TCP or a serial port. It feeds the
//! vehicle's attitude, on the frame's own clock (`clock`), into the shared telemetry the frame
//! loop renders each frame with, and each attitude and position into what is sensed
//! (`crate::state::Sensed`), which the control paths read (`vehicle` makes sense of the
//! messages). Its threads never touch the frame loop: a
//! receiving thread reopens the link with back-off whenever it fails, a sending thread
//! (`outgoing`) says DigiView is there (HEARTBEAT), asks the autopilot for the rates it needs
//! and for its time (TIMESYNC), and watches for the attitude going stale. Other components
//! of DigiView (the views as MAVLink cameras and gimbals) speak on the same link as
//! [`Components`]: they see every message that arrives and send through an [`Outbox`], on a
//! thread of theirs.

pub mod clock;
mod config;
pub mod driver;
mod outgoing;
mod port;
pub mod probe;
pub mod sim;
pub mod vehicle;

pub use config::{Endpoint, EndpointError, MavlinkConfig, signing_key};

use crate::clock::clock_us;
use crate::policy::{Peer, Policy};
use crate::protocol::params::Autopilot;
use crate::state::{Report, Sensed};
use crate::supervise;
use crate::telemetry::Telemetry;
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

type Connection = Arc<port::Port>;

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
    /// Who drives the views (the autopilot, or the demo's flight) and other senders of
    /// attitude.
    pub drivers: driver::Drivers,
    pub clock: Mutex<clock::ClockState>,
    pub connected: AtomicBool,
}

impl LinkStatus {
    /// The system and component whose attitude the views follow, once one is found.
    pub fn autopilot(&self) -> Option<(u8, u8)> {
        self.drivers.driver().map(|d| (d.system, d.component))
    }

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
        let (system_id, component_id) = self.autopilot().unwrap_or_default();
        let c = *self.clock.lock().unwrap_or_else(|e| e.into_inner());
        let others = self.drivers.others();
        let (other_system, other_component) = others.first().copied().unwrap_or_default();
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
            simulated: self.drivers.driver().is_some_and(|d| d.simulated).into(),
            others: others.len().min(255) as u8,
            other_system,
            other_component,
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
/// message that arrives, with who sent it as the policy knows peers, and is ticked every
/// [`TICK`] on a thread of its own.
pub trait Components: Send + Sync {
    fn handle(&self, out: &Outbox, from: &MavHeader, peer: Peer, msg: &MavMessage);
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
        self.0.status.autopilot().map_or(1, |a| a.0)
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
    /// Where each attitude and position goes, checked against the vehicle's rules.
    sensed: Arc<Sensed>,
    /// Where a stale attitude and the threads' failures are reported.
    report: Arc<Report>,
    telemetry: Arc<Telemetry>,
    status: Arc<LinkStatus>,
    connection: Mutex<Option<Connection>>,
    /// The local times (µs) of the TIMESYNC requests not answered yet, newest last.
    syncs_sent: Mutex<VecDeque<u64>>,
    components: Option<Arc<dyn Components>>,
    /// With signing on: the key, checking what comes in and signing what goes out.
    signing: Option<SigningData>,
    /// Where refused samples are noted (rate-limited, with every other path's refusals).
    policy: Arc<Policy>,
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
        (sensed, report): (Arc<Sensed>, Arc<Report>),
        telemetry: Arc<Telemetry>,
        policy: Arc<Policy>,
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
            sensed,
            report,
            telemetry,
            status: status.clone(),
            connection: Mutex::new(None),
            syncs_sent: Mutex::new(VecDeque::new()),
            components,
            policy,
            signing: cfg.signing_key.as_deref().map(|k| {
                SigningData::from_config(SigningConfig::new(signing_key(k), 0, true, false))
            }),
            stop: stop.clone(),
        });
        // Each thread supervised: a panic is noted and the thread started again.
        let mut threads = vec![];
        for (name, run) in [
            ("mavlink-rx", receive as fn(&Arc<Shared>)),
            ("mavlink-tx", |s: &Arc<Shared>| outgoing::send(s)),
        ] {
            let shared = shared.clone();
            let report: Arc<dyn supervise::FailureLog> = shared.report.clone();
            threads.push(supervise::spawn(report, name, stop.clone(), move || {
                run(&shared)
            }));
        }
        if let Some(components) = shared.components.clone() {
            let out = Outbox(shared.clone());
            let stop = stop.clone();
            let fault = supervise::Fault::for_service("mavlink-components");
            let report: Arc<dyn supervise::FailureLog> = shared.report.clone();
            threads.push(supervise::spawn(
                report,
                "mavlink-components",
                stop.clone(),
                move || {
                    while !stop.load(Ordering::Relaxed) {
                        std::thread::sleep(TICK);
                        fault.check("mavlink-components");
                        components.tick(&out);
                    }
                },
            ));
        }
        let threads = threads.into_iter().flatten().collect();
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

/// The link's connection while it is read: let go when the reading ends, a panic included,
/// so nothing is sent into a port no one reads and the port can be opened again.
struct Held<'a>(&'a Shared);

impl Drop for Held<'_> {
    fn drop(&mut self) {
        *self.0.connection.lock().unwrap_or_else(|e| e.into_inner()) = None;
        self.0.status.connected.store(false, Ordering::Relaxed);
    }
}

/// Reads an open link until it fails (why) or the link stops (None).
fn read(shared: &Arc<Shared>, connection: Connection, vehicle: &mut Vehicle) -> Option<String> {
    let out = Outbox(shared.clone());
    let fault = supervise::Fault::for_service("mavlink-rx");
    *shared.connection.lock().unwrap_or_else(|e| e.into_inner()) = Some(connection.clone());
    shared.status.connected.store(true, Ordering::Relaxed);
    let _held = Held(shared);
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            break None;
        }
        fault.check("mavlink-rx");
        match connection.recv_raw() {
            Ok(raw) => {
                if let Some((header, msg)) = accept(shared, &raw) {
                    let simulated = shared.status.drivers.is_demo(connection.sender_addr());
                    let peer = Peer::Mavlink {
                        system: u8::try_from(header.system_id).unwrap_or(u8::MAX),
                        component: header.component_id,
                        from: connection.sender(),
                        // With signing on, only signed messages are accepted.
                        signed: shared.signing.is_some(),
                    };
                    if let Some(news) = apply(shared, vehicle, (&header, simulated), peer, &msg) {
                        out.send(OWN_COMPONENT, &outgoing::status_text(&news));
                    }
                    outgoing::refuse_own_command(&out, &header, &msg);
                    if let Some(c) = &shared.components {
                        c.handle(&out, &header, peer, &msg);
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
    }
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

/// One message: into the telemetry and what is sensed (a sample outside the vehicle's rules
/// is refused there, noted, and the last one kept). What the operator must hear of it, as
/// a warning for ground stations too.
fn apply(
    shared: &Shared,
    vehicle: &mut Vehicle,
    (header, simulated): (&MavHeader, bool),
    peer: Peer,
    msg: &MavMessage,
) -> Option<String> {
    let status = &shared.status;
    status.messages.fetch_add(1, Ordering::Relaxed);
    match vehicle.handle(header, msg, clock_us(), simulated)? {
        Update::Found(driver) => return found(status, driver, peer),
        Update::OtherAttitude(system, component) => {
            if status.drivers.other(system, component) {
                warn!(
                    "mavlink: two senders of attitude: {peer} is ignored, the views follow {}",
                    driver_name(status.drivers.driver())
                );
                return Some(format!(
                    "DigiView: attitude from {system}/{component} ignored"
                ));
            }
        }
        Update::Attitude { t_us, attitude } => {
            shared.telemetry.external_attitude(t_us, attitude);
            status.attitude_us.fetch_max(t_us, Ordering::Relaxed);
            status.attitudes.fetch_add(1, Ordering::Relaxed);
            *status.clock.lock().unwrap_or_else(|e| e.into_inner()) = vehicle.clock.state();
            if let Err(e) = shared.sensed.set_attitude(attitude) {
                shared.policy.refusals.note(peer, "an attitude", &e.0);
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
            if let Err(e) = shared.sensed.set_position(p.position) {
                shared.policy.refusals.note(peer, "a position", &e.0);
            }
        }
    }
    None
}

/// The autopilot found, or a real one in the demo's place: said in the log, and to ground
/// stations when the demo's flight steps aside.
fn found(status: &LinkStatus, driver: driver::Driver, peer: Peer) -> Option<String> {
    let was_demo = status.drivers.driver().is_some_and(|d| d.simulated);
    status.drivers.set(driver);
    let (system, component) = (driver.system, driver.component);
    if driver.simulated {
        info!(
            "mavlink: the demo's simulated flight drives the views as system {system}, component {component}"
        );
        return None;
    }
    info!("mavlink: the autopilot is system {system}, component {component} ({peer})");
    was_demo.then(|| {
        info!("mavlink: the autopilot drives the views; the demo's simulated flight steps aside");
        format!("DigiView: autopilot {system}/{component} replaces demo flight")
    })
}

/// Who drives the views, in words.
fn driver_name(driver: Option<driver::Driver>) -> String {
    match driver {
        None => "no autopilot yet".into(),
        Some(d) if d.simulated => {
            format!("the demo's simulated flight ({}/{})", d.system, d.component)
        }
        Some(d) => format!("the autopilot {}/{}", d.system, d.component),
    }
}
