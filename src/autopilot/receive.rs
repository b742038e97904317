//! The autopilot link's receiving thread: it opens the link, reads each frame (checking its
//! signature when signing is on), hands what the vehicle says to the telemetry and what is
//! sensed, and every message to the components; a link that fails is opened again with
//! back-off.

use super::vehicle::{Update, Vehicle};
use super::{
    Connection, LinkStatus, OWN_COMPONENT, Outbox, Profile, Shared, driver, outgoing, port,
};
use crate::clock::clock_us;
use crate::policy::Peer;
use crate::supervise::{self, Locked};
use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, Message};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// Opens the link, reads it until it fails, again with back-off (1 s doubling to 10 s, back
/// to 1 s after a link that held 10 s).
pub(super) fn receive(shared: &Arc<Shared>) {
    let mut backoff = supervise::Backoff::new(Duration::from_secs(1), Duration::from_secs(10));
    let mut vehicle = Vehicle::new(shared.cfg.system_id);
    while !shared.stop.load(Ordering::Relaxed) {
        let why = match port::Port::open(&shared.address) {
            Ok(c) => {
                let opened = Instant::now();
                let Some(why) = read(shared, Arc::from(c), &mut vehicle) else {
                    return;
                };
                if opened.elapsed() > Duration::from_secs(10) {
                    backoff.held();
                }
                why
            }
            Err(e) => e.to_string(),
        };
        let wait = backoff.failed();
        warn!(
            "mavlink {}: {why}; retrying in {} s",
            shared.address,
            wait.as_secs()
        );
        supervise::sleep_unless(&shared.stop, wait);
    }
}

/// The link's connection while it is read: let go when the reading ends, a panic included,
/// so nothing is sent into a port no one reads and the port can be opened again.
struct Held<'a>(&'a Shared);

impl Drop for Held<'_> {
    fn drop(&mut self) {
        *self.0.connection.locked() = None;
        self.0.status.connected.store(false, Ordering::Relaxed);
    }
}

/// Reads an open link until it fails (why) or the link stops (None).
fn read(shared: &Arc<Shared>, connection: Connection, vehicle: &mut Vehicle) -> Option<String> {
    let out = Outbox::new(shared.clone());
    let fault = supervise::Fault::for_service("mavlink-rx");
    *shared.connection.locked() = Some(connection.clone());
    shared.status.connected.store(true, Ordering::Relaxed);
    let _held = Held(shared);
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            break None;
        }
        fault.check("mavlink-rx");
        match connection.recv_raw() {
            Ok(raw) => {
                let simulated = shared.status.drivers.is_demo(connection.sender_addr());
                take(
                    shared,
                    (&out, vehicle),
                    &raw,
                    (connection.sender(), simulated),
                );
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

/// One frame as read, from `from` (`simulated`: the demo's flight): checked (signing) and
/// parsed, given to the vehicle's path (on the autopilot's link) and to the components.
pub(super) fn take(
    shared: &Shared,
    (out, vehicle): (&Outbox, &mut Vehicle),
    raw: &MAVLinkMessageRaw,
    (from, simulated): (Option<std::net::IpAddr>, bool),
) {
    if let Some((header, msg)) = accept(shared, raw) {
        deliver(shared, (out, vehicle), (&header, &msg), (from, simulated));
    }
}

/// One message, as [`take`] gives it on.
pub(super) fn deliver(
    shared: &Shared,
    (out, vehicle): (&Outbox, &mut Vehicle),
    (header, msg): (&MavHeader, &MavMessage),
    (from, simulated): (Option<std::net::IpAddr>, bool),
) {
    let peer = Peer::Mavlink {
        system: u8::try_from(header.system_id).unwrap_or(u8::MAX),
        component: header.component_id,
        from,
        // With signing on, only signed messages are accepted.
        signed: shared.signing.is_some(),
    };
    if shared.profile == Profile::Payload {
        shared.status.messages.fetch_add(1, Ordering::Relaxed);
    } else {
        if let Some(news) = apply(shared, vehicle, (header, simulated), peer, msg) {
            out.send(OWN_COMPONENT, &outgoing::status_text(&news));
        }
        outgoing::refuse_own_command(out, header, msg);
    }
    if let Some(c) = &shared.components {
        c.handle(out, header, peer, msg);
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
    let Ok(msg) = MavMessage::parse(raw.version(), raw.message_id(), raw.payload()) else {
        unknown_command(shared, raw);
        return None;
    };
    let header = MavHeader {
        system_id: raw.system_id(),
        component_id: raw.component_id(),
        sequence: raw.sequence(),
    };
    Some((header, msg))
}

/// A command frame that did not parse because its command is not in MAVLink's common set
/// (an ArduPilot or vendor command, as the payload SDK's gimbal calibration, 42503): there is
/// no ACK to give it in the common set, so it is logged, once per sender and command.
fn unknown_command(shared: &Shared, raw: &MAVLinkMessageRaw) {
    if ![75, 76].contains(&raw.message_id()) {
        return;
    }
    let mut p = [0u8; 32];
    let n = raw.payload().len().min(32);
    p[..n].copy_from_slice(&raw.payload()[..n]);
    let command = u16::from_le_bytes([p[28], p[29]]);
    let key = (raw.system_id() as u8, raw.component_id(), command);
    let first = shared.unknown.locked().insert(key);
    if first {
        warn!(
            "mavlink: command {command} from {}/{} to {}/{} is not one DigiView knows (not in \
             MAVLink's common set): not answered",
            key.0, key.1, p[30], p[31]
        );
    }
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
            *status.clock.locked() = vehicle.clock.state();
            if let Err(e) = shared.sensed.set_attitude(attitude) {
                shared.policy.refusals.note(peer, "an attitude", &e.0);
            }
        }
        Update::TimeSync { remote_us, ours_us } => {
            // Only an answer to a request of ours, each once.
            let mut sent = shared.syncs_sent.locked();
            if let Some(i) = sent.iter().position(|&t| t == ours_us) {
                sent.remove(i);
                drop(sent);
                vehicle.clock.observe_sync(remote_us, ours_us, clock_us());
                *status.clock.locked() = vehicle.clock.state();
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
