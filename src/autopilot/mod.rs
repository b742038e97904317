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
//! thread of theirs. A second link of the [`Profile::Payload`] kind carries only such
//! components (the payload SDK's, `crate::payload`): nothing of the vehicle is read there and
//! DigiView's own component says nothing.

pub mod checks;
pub mod clock;
mod config;
pub mod driver;
mod outgoing;
pub(crate) mod port;
pub mod probe;
mod receive;
pub mod sim;
pub mod vehicle;

pub use config::{Endpoint, EndpointError, MavlinkConfig, signing_key};

use crate::clock::clock_us;
use crate::policy::{Peer, Policy};
use crate::protocol::params::Autopilot;
use crate::state::{Report, Sensed};
use crate::supervise::{self, Locked};
use crate::telemetry::Telemetry;
use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, SigningConfig, SigningData};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;
use tracing::info;

/// No attitude for this long and the views hold the last one, reported.
pub const STALE: Duration = Duration::from_millis(500);
/// How often the link's state is logged, and when first.
const REPORT_EVERY: Duration = Duration::from_secs(30);
const FIRST_REPORT: Duration = Duration::from_secs(3);
/// DigiView's own component on the link (MAV_COMP_ID_ONBOARD_COMPUTER).
const OWN_COMPONENT: u8 = 191;

type Connection = Arc<port::Port>;

/// What a link is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Profile {
    /// The autopilot's: attitude, position and time read, rates asked for, DigiView's
    /// heartbeat sent, and the components beside.
    Autopilot,
    /// An app's that drives a payload (the payload SDK's port): only the components speak.
    Payload,
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
        let c = *self.clock.locked();
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
pub struct Outbox {
    shared: Arc<Shared>,
    /// The component each of DigiView's speaks as here (None: it is silent here).
    rename: Option<Rename>,
}

/// Which component speaks as which, on a link that shows some of them under other ids.
pub type Rename = Arc<dyn Fn(u8) -> Option<u8> + Send + Sync>;

impl Outbox {
    fn new(shared: Arc<Shared>) -> Outbox {
        Outbox {
            shared,
            rename: None,
        }
    }

    /// This outbox with each component sent from as `rename` says (or not at all).
    pub fn renamed(&self, rename: Rename) -> Outbox {
        Outbox {
            shared: self.shared.clone(),
            rename: Some(rename),
        }
    }

    /// The system DigiView's components belong to: the autopilot's, once it is known (1
    /// until then).
    pub fn system_id(&self) -> u8 {
        self.shared.ids.autopilot().map_or(1, |a| a.0)
    }

    /// Sends `msg` from `component` (signed when signing is on); false while the link is
    /// down or the component is silent here.
    pub fn send(&self, component: u8, msg: &MavMessage) -> bool {
        self.send_any(component, msg)
    }

    /// Sends a message of another dialect than the common set (the payload SDK's
    /// MOUNT_ORIENTATION), as [`Outbox::send`] does.
    pub fn send_any<M: mavlink::Message>(&self, component: u8, msg: &M) -> bool {
        let shared = &*self.shared;
        let component = match &self.rename {
            Some(rename) => match rename(component) {
                Some(c) => c,
                None => return false,
            },
            None => component,
        };
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
    /// Whose autopilot gives DigiView's components their system id: this link's own, or
    /// the autopilot link's for a payload link.
    ids: Arc<LinkStatus>,
    profile: Profile,
    /// The sequence number of the next message sent (`outgoing::send_one`).
    sequence: std::sync::atomic::AtomicU8,
    /// Commands not in the common set already logged: (system, component, command).
    unknown: Mutex<std::collections::HashSet<(u8, u8, u16)>>,
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
    /// A link's shared part at `address`, not open yet.
    fn new(
        (address, cfg, kind): (String, &MavlinkConfig, Kind),
        (sensed, report): (Arc<Sensed>, Arc<Report>),
        telemetry: Arc<Telemetry>,
        policy: Arc<Policy>,
        components: Option<Arc<dyn Components>>,
    ) -> Shared {
        let status = Arc::new(LinkStatus::default());
        Shared {
            address,
            cfg: cfg.clone(),
            sensed,
            report,
            telemetry,
            ids: kind.ids.unwrap_or_else(|| status.clone()),
            status,
            profile: kind.profile,
            sequence: Default::default(),
            unknown: Mutex::default(),
            connection: Mutex::new(None),
            syncs_sent: Mutex::new(VecDeque::new()),
            components,
            policy,
            signing: cfg.signing_key.as_deref().map(|k| {
                SigningData::from_config(SigningConfig::new(signing_key(k), 0, true, false))
            }),
            stop: Arc::new(AtomicBool::new(false)),
        }
    }

    /// The open connection, while there is one.
    fn connection(&self) -> Option<Connection> {
        self.connection.locked().clone()
    }
}

/// A link's kind and whose autopilot names its system (None: its own).
pub struct Kind {
    pub profile: Profile,
    pub ids: Option<Arc<LinkStatus>>,
}

impl Link {
    /// Starts the autopilot link of `cfg` (None when it is off), with `components` speaking
    /// on it.
    pub fn start(
        cfg: &MavlinkConfig,
        sensing: (Arc<Sensed>, Arc<Report>),
        telemetry: Arc<Telemetry>,
        policy: Arc<Policy>,
        components: Option<Arc<dyn Components>>,
    ) -> Result<Option<Link>, EndpointError> {
        let kind = Kind {
            profile: Profile::Autopilot,
            ids: None,
        };
        Link::start_kind(cfg, kind, sensing, telemetry, policy, components)
    }

    /// Starts a link of `kind` at `cfg`'s endpoint (None when it is off).
    pub fn start_kind(
        cfg: &MavlinkConfig,
        kind: Kind,
        (sensed, report): (Arc<Sensed>, Arc<Report>),
        telemetry: Arc<Telemetry>,
        policy: Arc<Policy>,
        components: Option<Arc<dyn Components>>,
    ) -> Result<Option<Link>, EndpointError> {
        let Endpoint::Address(address) = cfg.endpoint.parse()? else {
            return Ok(None);
        };
        let shared = Arc::new(Shared::new(
            (address, cfg, kind),
            (sensed, report),
            telemetry,
            policy,
            components,
        ));
        let (status, stop) = (shared.status.clone(), shared.stop.clone());
        // Each thread supervised: a panic is noted and the thread started again.
        let mut threads = vec![];
        let mut loops = vec![("mavlink-rx", receive::receive as fn(&Arc<Shared>))];
        if shared.profile == Profile::Autopilot {
            loops.push(("mavlink-tx", |s: &Arc<Shared>| outgoing::send(s)));
        }
        for (name, run) in loops {
            let shared = shared.clone();
            let report: Arc<dyn supervise::FailureLog> = shared.report.clone();
            threads.push(supervise::spawn(report, name, stop.clone(), move || {
                run(&shared)
            }));
        }
        if let Some(components) = shared.components.clone() {
            let out = Outbox::new(shared.clone());
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
        info!("mavlink ({:?}): {}", shared.profile, cfg.endpoint);
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
