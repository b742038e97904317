//! A simulated autopilot: the demo's flight sent as a flight controller sends it (HEARTBEAT
//! each second, ATTITUDE at the rate asked, GLOBAL_POSITION_INT at 10 Hz and HOME_POSITION
//! each second, stamped with its own boot clock, TIMESYNC answered on that clock), so that
//! everything downstream of the link, the parser and the clock mapping included, runs
//! without a drone, and a ground station pointed at it sees a vehicle flying the demo's
//! circle. `digiview sim-autopilot` runs it. As the demo's flight it sends from a socket of
//! its own, so the link tells it from a real autopilot (both system 1, component 1), and it
//! stops for good once the link has heard one (`super::driver`).

use super::LinkStatus;
use super::port::Port;
use crate::geometry::rotation::wrap_pi;
use crate::source::demo::Flight;
use mavlink::dialects::common::{
    ATTITUDE_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, MavAutopilot,
    MavMessage, MavModeFlag, MavState, MavType, TIMESYNC_DATA,
};
use mavlink::error::MessageReadError;
use mavlink::{MavHeader, Message};
use std::io::ErrorKind;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// The simulated vehicle's system id.
pub const SYSTEM: u8 = 1;

pub struct SimAutopilot {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SimAutopilot {
    /// Sends `flight`, its time counted from `start`, to `to` (a MAVLink endpoint), ATTITUDE at
    /// `rate_hz`. A link that cannot be opened (or fails) is retried every second.
    pub fn start(to: &str, flight: Flight, start: Instant, rate_hz: f64) -> SimAutopilot {
        Self::spawn(to, flight, (start, rate_hz), None)
    }

    /// The demo's flight, sent to the link of `status` listening on UDP `port` of this
    /// machine, until a real autopilot is heard there.
    pub fn demo(
        port: u16,
        flight: Flight,
        (start, rate_hz): (Instant, f64),
        status: Arc<LinkStatus>,
    ) -> SimAutopilot {
        let to = format!("udpout:127.0.0.1:{port}");
        Self::spawn(&to, flight, (start, rate_hz), Some(status))
    }

    fn spawn(
        to: &str,
        flight: Flight,
        (start, rate_hz): (Instant, f64),
        demo: Option<Arc<LinkStatus>>,
    ) -> SimAutopilot {
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (to, stop) = (to.to_string(), stop.clone());
            std::thread::Builder::new()
                .name("sim-autopilot".into())
                .spawn(move || run(&to, &flight, (start, rate_hz), &stop, demo.as_deref()))
                .ok()
        };
        SimAutopilot { stop, thread }
    }
}

impl Drop for SimAutopilot {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Opens `to`: as the demo's flight from a socket of its own, said to the link (None when
/// it is to step aside).
fn open(to: &str, demo: Option<&LinkStatus>) -> Option<std::io::Result<Port>> {
    let Some(status) = demo else {
        return Some(Port::open(to));
    };
    let port = Port::udp_to(to.strip_prefix("udpout:").unwrap_or(to));
    let from = port.as_ref().ok().and_then(|p| p.local_addr());
    status.drivers.demo_sends_from(from).then_some(port)
}

/// Whether the demo's flight is to stop: a real autopilot drives.
fn aside(demo: Option<&LinkStatus>) -> bool {
    let aside = demo.is_some_and(|s| s.drivers.demo_aside());
    if aside {
        info!("sim-autopilot: a real autopilot is on the link; the demo's flight stops");
    }
    aside
}

fn run(
    to: &str,
    flight: &Flight,
    (start, rate_hz): (Instant, f64),
    stop: &AtomicBool,
    demo: Option<&LinkStatus>,
) {
    let period = crate::units::seconds(1.0 / rate_hz.clamp(1.0, 1000.0), 0.001..=1.0)
        .unwrap_or(Duration::from_millis(10));
    let header = MavHeader {
        system_id: SYSTEM.into(),
        component_id: 1,
        sequence: 0,
    };
    while !stop.load(Ordering::Relaxed) && !aside(demo) {
        let link = match open(to, demo) {
            None => return,
            Some(Ok(l)) => Arc::new(l),
            Some(Err(e)) => {
                warn!("sim-autopilot {to}: {e}; retrying in 1 s");
                std::thread::sleep(Duration::from_secs(1));
                continue;
            }
        };
        answer_timesync(link.clone(), header, start);
        let (mut next, mut position_at, mut beat_at) = (Instant::now(), start, start);
        while !stop.load(Ordering::Relaxed) {
            if aside(demo) {
                return;
            }
            let now = Instant::now();
            if now < next {
                std::thread::sleep(next - now);
            }
            next += period;
            let t = start.elapsed();
            let mut out = vec![attitude(flight, t)];
            if t >= beat_at.duration_since(start) {
                beat_at += Duration::from_secs(1);
                out.push(heartbeat());
                out.push(home(flight));
            }
            if t >= position_at.duration_since(start) {
                position_at += Duration::from_millis(100);
                out.push(position(flight, t));
            }
            if out.iter().any(|m| link.send(header, m).is_err()) {
                // Nobody listening yet (a refused UDP send) costs nothing; a broken TCP link
                // is reopened.
                if to.starts_with("tcp") {
                    break;
                }
            }
        }
    }
}

/// Answers TIMESYNC requests read from `link` on the boot clock (`start`), on a thread that
/// ends with the link (on UDP, at the first message after the sender is gone).
fn answer_timesync(link: Arc<Port>, header: MavHeader, start: Instant) {
    let _ = std::thread::Builder::new()
        .name("sim-timesync".into())
        .spawn(move || {
            loop {
                let msg = match link.recv_raw() {
                    Ok(raw) => MavMessage::parse(raw.version(), raw.message_id(), raw.payload()),
                    // A refused send shows on a connected socket's next read: nobody yet.
                    Err(MessageReadError::Io(e))
                        if matches!(
                            e.kind(),
                            ErrorKind::TimedOut
                                | ErrorKind::WouldBlock
                                | ErrorKind::ConnectionRefused
                        ) =>
                    {
                        continue;
                    }
                    Err(MessageReadError::Io(_)) => break,
                    Err(_) => continue,
                };
                let Ok(msg) = msg else {
                    continue;
                };
                if let MavMessage::TIMESYNC(t) = msg
                    && t.tc1 == 0
                {
                    let tc1 = start.elapsed().as_nanos() as i64;
                    let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
                        tc1,
                        ts1: t.ts1,
                        ..Default::default()
                    });
                    let _ = link.send(header, &answer);
                }
                if Arc::strong_count(&link) == 1 {
                    break;
                }
            }
        });
}

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
        base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

fn boot_ms(t: Duration) -> u32 {
    t.as_millis() as u32
}

fn attitude(flight: &Flight, t: Duration) -> MavMessage {
    let (a, _) = flight.pose(t.as_secs_f64());
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: boot_ms(t),
        roll: a.roll as f32,
        pitch: a.pitch as f32,
        yaw: a.yaw as f32,
        ..Default::default()
    })
}

fn position(flight: &Flight, t: Duration) -> MavMessage {
    let (a, p) = flight.pose(t.as_secs_f64());
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: boot_ms(t),
        lat: (p.lat * 1e7).round() as i32,
        lon: (p.lon * 1e7).round() as i32,
        alt: (p.alt * 1000.0).round() as i32,
        relative_alt: (p.relative_alt * 1000.0).round() as i32,
        hdg: (wrap_pi(a.yaw).to_degrees().rem_euclid(360.0) * 100.0) as u16,
        ..Default::default()
    })
}

fn home(flight: &Flight) -> MavMessage {
    let p = flight.hover;
    MavMessage::HOME_POSITION(HOME_POSITION_DATA {
        latitude: (p.lat * 1e7).round() as i32,
        longitude: (p.lon * 1e7).round() as i32,
        altitude: ((p.alt - p.relative_alt) * 1000.0).round() as i32,
        q: [1.0, 0.0, 0.0, 0.0],
        ..Default::default()
    })
}
