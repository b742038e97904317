//! What the autopilot link sends, on its own thread every 100 ms: DigiView's HEARTBEAT each
//! second, the message rates it asks the autopilot for, TIMESYNC requests ten times a second
//! (the clock mapping's round trips), the attitude's staleness, reported once each way, and
//! what has failed (SYSTEM_STATUS's error) as a STATUSTEXT each time it changes.
//! Everything sent is signed when signing is on.

use super::driver::Driver;
use super::{
    Connection, FIRST_REPORT, LinkStatus, OWN_COMPONENT, Outbox, REPORT_EVERY, STALE, Shared,
};
use crate::clock::clock_us;
use crate::supervise::Locked;
use mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage,
    MavModeFlag, MavResult, MavSeverity, MavState, MavType, STATUSTEXT_DATA, TIMESYNC_DATA,
};
use mavlink::{MAVLinkMessageRaw, MAVLinkV2MessageRaw, MavHeader};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// `msg` on `connection`, signed when signing is on, numbered by the link's sequence (one
/// counter for everything DigiView sends on the link, whatever carries it).
pub(super) fn send_one<M: mavlink::Message>(
    shared: &Shared,
    connection: &Connection,
    header: MavHeader,
    msg: &M,
) {
    let header = MavHeader {
        sequence: shared.sequence.fetch_add(1, Ordering::Relaxed),
        ..header
    };
    let _ = match &shared.signing {
        Some(signing) => {
            let mut raw = MAVLinkV2MessageRaw::new();
            raw.serialize_message_for_signing(header, msg);
            signing.sign_message(&mut raw);
            connection.send_raw(&MAVLinkMessageRaw::V2(raw))
        }
        None => connection.send(header, msg),
    };
}

/// What the sending thread keeps from one round to the next.
struct Sending {
    beat: Instant,
    /// When the rates were last asked for, and of whom.
    asked: Option<(Instant, Option<Driver>)>,
    /// Attitudes counted since when, for the rate they come at (each 5 s, and each second).
    counted: (Instant, u64),
    second: (Instant, u64),
    lost: bool,
    /// What ground stations were last told had failed (None: nothing).
    told: Option<String>,
}

/// Every 100 ms: HEARTBEAT each second, the rate requests, and the attitude's staleness.
pub(super) fn send(shared: &Shared) {
    let now = Instant::now();
    let mut s = Sending {
        beat: now - Duration::from_secs(1),
        asked: None,
        counted: (now, 0),
        second: (now, 0),
        lost: false,
        told: None,
    };
    // The first report comes soon after the start, so the log shows the mapping settled.
    let mut next_report = now + FIRST_REPORT;
    let mut reported = (now, 0u64, 0u64);
    let fault = crate::supervise::Fault::for_service("mavlink-tx");
    while !shared.stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
        fault.check("mavlink-tx");
        if s.second.0.elapsed() >= Duration::from_secs(1) {
            let n = shared.status.attitudes.load(Ordering::Relaxed);
            let hz = (n - s.second.1) as f64 / s.second.0.elapsed().as_secs_f64();
            shared
                .status
                .attitude_mhz
                .store((hz * 1e3) as u64, Ordering::Relaxed);
            s.second = (Instant::now(), n);
        }
        if Instant::now() >= next_report {
            next_report += REPORT_EVERY;
            reported = report(&shared.status, reported);
        }
        if let Some(c) = shared.connection() {
            speak(shared, &c, &mut s);
        }
        watch_staleness(shared, &mut s.lost);
    }
}

/// What DigiView says on an open link: its HEARTBEAT each second, TIMESYNC requests, and the
/// rates it needs, asked for when the autopilot is found (or replaces the demo's flight) and
/// again every 10 s while the attitude comes at less than half the rate asked.
fn speak(shared: &Shared, c: &Connection, s: &mut Sending) {
    let autopilot = shared.status.autopilot();
    let header = MavHeader {
        system_id: autopilot.map_or(1, |a| a.0).into(),
        component_id: OWN_COMPONENT,
        sequence: 0,
    };
    if autopilot.is_some() {
        request_timesync(shared, c, header);
    }
    if s.beat.elapsed() >= Duration::from_secs(1) {
        s.beat = Instant::now();
        send_one(shared, c, header, &heartbeat());
    }
    tell_failures(shared, c, header, &mut s.told);
    let Some((system, component)) = autopilot else {
        return;
    };
    let n = shared.status.attitudes.load(Ordering::Relaxed);
    let rate = (n - s.counted.1) as f64 / s.counted.0.elapsed().as_secs_f64().max(1e-3);
    if s.counted.0.elapsed() >= Duration::from_secs(5) {
        s.counted = (Instant::now(), n);
    }
    // A real autopilot in the demo's place is asked at once.
    let driver = shared.status.drivers.driver();
    let due = s.asked.is_none_or(|(t, of)| {
        of != driver
            || t.elapsed() >= Duration::from_secs(10) && rate < shared.cfg.attitude_hz / 2.0
    });
    if due {
        s.asked = Some((Instant::now(), driver));
        for (id, hz) in [(30, shared.cfg.attitude_hz), (33, shared.cfg.position_hz)] {
            send_one(
                shared,
                c,
                header,
                &message_interval(system, component, id, hz),
            );
        }
    }
}

/// Reports the attitude going stale (none for [`STALE`]) and coming again.
fn watch_staleness(shared: &Shared, lost: &mut bool) {
    let newest = shared.status.attitude_us.load(Ordering::Relaxed);
    let stale = newest != 0 && clock_us().saturating_sub(newest) > STALE.as_micros() as u64;
    if stale == *lost {
        return;
    }
    *lost = stale;
    shared.report.set_attitude_lost(stale);
    if stale {
        warn!(
            "mavlink: no attitude for {} ms: the views hold the last one",
            STALE.as_millis()
        );
    } else {
        info!("mavlink: attitude again");
    }
}

/// The autopilot's clock going back more often than this between two reports is not
/// reboots: two clocks take turns, most likely two autopilots sending as one system.
const CLOCKS_TAKING_TURNS: u64 = 3;

/// The link's state in one log line: the autopilot, the attitude rate, the clock mapping;
/// and a warning when the clock went back too often to be reboots. `before`: when the last
/// report was, and the attitudes and clock resets counted then.
fn report(
    status: &LinkStatus,
    (since, before, resets): (Instant, u64, u64),
) -> (Instant, u64, u64) {
    let n = status.attitudes.load(Ordering::Relaxed);
    let hz = (n - before) as f64 / since.elapsed().as_secs_f64();
    let c = *status.clock.locked();
    let autopilot = status.autopilot();
    let went_back = c.resets.saturating_sub(resets);
    if went_back > CLOCKS_TAKING_TURNS
        && let Some((system, _)) = autopilot
    {
        warn!(
            "mavlink: the autopilot's clock went back {went_back} times in {:.0} s: two \
             autopilots (or simulators) are sending as system {system}, each with its own \
             clock; give each its own system id, or stop one",
            since.elapsed().as_secs_f64()
        );
    }
    match autopilot {
        Some((system, component)) => info!(
            "mavlink: autopilot {system}/{component}, attitude {hz:.0} Hz, clock: autopilot + \
             {:.3} s (drift {:+.0} ppm over {:.1} s, {} samples, {} reboots; {}), {} unsigned \
             or badly signed ignored",
            c.offset_us as f64 / 1e6,
            c.drift_ppm,
            c.span_us as f64 / 1e6,
            c.samples,
            c.resets,
            match (c.trips, c.link_delay_us) {
                (0, _) => "no TIMESYNC answers".to_string(),
                (n, Some(d)) => format!(
                    "{n} TIMESYNC round trips: {:.1} ms of link delay taken out",
                    d / 1e3
                ),
                (n, None) => format!("{n} TIMESYNC round trips: no link delay to take out"),
            },
            status.unsigned.load(Ordering::Relaxed)
        ),
        None => info!(
            "mavlink: no autopilot heard yet ({} messages)",
            status.messages.load(Ordering::Relaxed)
        ),
    }
    (Instant::now(), n, c.resets)
}

/// What failed (SYSTEM_STATUS's error), told to ground stations as it changes: a STATUSTEXT
/// error naming it, and one saying so when nothing has failed any more.
fn tell_failures(shared: &Shared, c: &Connection, header: MavHeader, told: &mut Option<String>) {
    let now = shared.report.brief();
    if now == *told {
        return;
    }
    let msg = match &now {
        Some(what) => said(
            MavSeverity::MAV_SEVERITY_ERROR,
            &format!("DigiView: {what}"),
        ),
        None => said(MavSeverity::MAV_SEVERITY_INFO, "DigiView: running again"),
    };
    send_one(shared, c, header, &msg);
    *told = now;
}

/// A warning for ground stations (STATUSTEXT, at most 50 characters: one chunk).
pub(super) fn status_text(text: &str) -> MavMessage {
    said(MavSeverity::MAV_SEVERITY_WARNING, text)
}

fn said(severity: MavSeverity, text: &str) -> MavMessage {
    MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity,
        text: text.into(),
        ..Default::default()
    })
}

pub(super) fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// MAV_CMD_SET_MESSAGE_INTERVAL: message `id` every 1/`hz` s.
fn message_interval(system: u8, component: u8, id: u32, hz: f64) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        target_system: system,
        target_component: component,
        param1: id as f32,
        param2: (1e6 / hz) as f32,
        ..Default::default()
    })
}

/// Unanswered TIMESYNC requests remembered (three seconds' worth).
const SYNCS_KEPT: usize = 30;

/// Asks the autopilot for its time, remembering when.
fn request_timesync(shared: &Shared, connection: &Connection, header: MavHeader) {
    let now = clock_us();
    {
        let mut sent = shared.syncs_sent.locked();
        sent.push_back(now);
        while sent.len() > SYNCS_KEPT {
            sent.pop_front();
        }
    }
    let request = MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: 0,
        ts1: now as i64 * 1000,
        ..Default::default()
    });
    send_one(shared, connection, header, &request);
}

/// Answers the autopilot's TIMESYNC request (PX4 asks a companion computer for its time).
pub(super) fn answer_timesync(shared: &Shared, to: &MavHeader, ts1: i64) {
    let Some(c) = shared.connection() else {
        return;
    };
    let header = MavHeader {
        system_id: to.system_id,
        component_id: OWN_COMPONENT,
        sequence: 0,
    };
    let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: clock_us() as i64 * 1000,
        ts1,
        target_system: to.system_id as u8,
        target_component: to.component_id,
    });
    send_one(shared, &c, header, &answer);
}

/// Answers a command addressed to DigiView's own component, which carries none out (the
/// cameras, components 100 and up, do): COMMAND_ACK UNSUPPORTED. Unanswered, MAVSDK probes it
/// as a camera and gimbal manager and asks again every half second for as long as it is
/// connected; told, it stops. A command to every component (0) is left to those it concerns.
pub(super) fn refuse_own_command(out: &Outbox, from: &MavHeader, msg: &MavMessage) {
    let (command, system, component) = match msg {
        MavMessage::COMMAND_LONG(c) => (c.command, c.target_system, c.target_component),
        MavMessage::COMMAND_INT(c) => (c.command, c.target_system, c.target_component),
        _ => return,
    };
    if component != OWN_COMPONENT || (system != 0 && system != out.system_id()) {
        return;
    }
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result: MavResult::MAV_RESULT_UNSUPPORTED,
        progress: 0,
        result_param2: 0,
        target_system: from.system_id as u8,
        target_component: from.component_id,
    });
    out.send(OWN_COMPONENT, &ack);
}
