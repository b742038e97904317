//! A simulated autopilot, written with the `mavlink` crate as a flight controller's MAVLink
//! would be: HEARTBEAT at 1 Hz and ATTITUDE at 200 Hz stamped with its own boot clock (booted
//! 3.7 s before the test's), each message delivered after 0 to 20 ms of random delay, so
//! they arrive jittered and now and then out of order. It answers TIMESYNC on its boot clock
//! as ArduPilot and PX4 do, the answer delayed alike. The vehicle's attitude is a function
//! of time the test gives; it can fall silent, and hostile bytes can be sent beside it.

use glam::DVec3;
use mavlink::dialects::common::*;
use mavlink::{MavConnection, MavHeader};
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The vehicle's (yaw, pitch, roll) in radians at `t`, seconds on the monotonic clock that
/// DigiView stamps frames with ([`clock_s`]).
pub type Flight = fn(f64) -> DVec3;

/// The monotonic clock of frames' capture times, in seconds.
pub fn clock_s() -> f64 {
    digiview::clock::clock_us() as f64 / 1e6
}

/// The system clock's time of [`clock_s`]'s zero, seconds since 1970: the system clock read
/// between two readings of [`clock_s`], taking the closest of a hundred brackets (a test
/// thread preempted between two plain readings, on a loaded host, put them 30 ms apart, and
/// every UNIX time turned back onto [`clock_s`] was that much late).
pub fn clock_zero_unix_s() -> f64 {
    let bracket = || {
        let before = clock_s();
        let wall = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64();
        let after = clock_s();
        (after - before, wall - (before + after) / 2.0)
    };
    (0..100)
        .map(|_| bracket())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap()
        .1
}

pub struct SimAutopilot {
    pub start: Instant,
    /// While set, no ATTITUDE is sent (HEARTBEAT goes on).
    pub silent: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// A small deterministic generator (xorshift) for the delays.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

const BOOTED_BEFORE: Duration = Duration::from_millis(3700);

impl SimAutopilot {
    /// Sends to `to` (`udpout:127.0.0.1:PORT`) from system 1, component 1.
    pub fn start(to: &str, flight: Flight) -> SimAutopilot {
        SimAutopilot::start_signed(to, flight, None)
    }

    /// As [`SimAutopilot::start`], signing every message with `key` when given.
    pub fn start_signed(to: &str, flight: Flight, key: Option<[u8; 32]>) -> SimAutopilot {
        let mut link = mavlink::connect::<MavMessage>(to).expect("the simulated autopilot's link");
        link.setup_signing(key.map(|k| mavlink::SigningConfig::new(k, 0, true, false)));
        let link: Arc<dyn MavConnection<MavMessage> + Send + Sync> = Arc::from(link);
        // The boot clock's start on both clocks, read together: with a thread started
        // between the two readings, a loaded host can put milliseconds between them, and
        // every attitude is then reported that much off its stamp (the likely cause of
        // landmarks 1.5-2.9 px off, now and then, in full runs).
        let (start_s, start) = (clock_s(), Instant::now());
        let answers = answer_timesync(link.clone(), start);
        let silent = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (silent, stop) = (silent.clone(), stop.clone());
            std::thread::spawn(move || {
                let header = MavHeader {
                    system_id: 1,
                    component_id: 1,
                    sequence: 0,
                };
                let mut rng = Rng(0x5eed);
                // (delivery time, sequence) → message; the sequence keeps equal times in order.
                let mut queue: BinaryHeap<Reverse<(Instant, u64)>> = BinaryHeap::new();
                let mut pending = std::collections::HashMap::new();
                let (mut n, mut next_att, mut next_beat) = (0u64, start, start);
                while !stop.load(Ordering::Relaxed) {
                    let now = Instant::now();
                    let mut made: Vec<MavMessage> = answers.try_iter().collect();
                    if now >= next_beat {
                        next_beat += Duration::from_secs(1);
                        made.push(heartbeat());
                    }
                    while next_att <= now {
                        let t = next_att - start;
                        next_att += Duration::from_millis(5);
                        if !silent.load(Ordering::Relaxed) {
                            made.push(attitude(t, flight(start_s + t.as_secs_f64())));
                        }
                    }
                    for m in made {
                        let at = now + Duration::from_secs_f64(rng.unit() * 0.020);
                        queue.push(Reverse((at, n)));
                        pending.insert(n, m);
                        n += 1;
                    }
                    while queue.peek().is_some_and(|Reverse((at, _))| *at <= now) {
                        let Reverse((_, k)) = queue.pop().unwrap();
                        let _ = link.send(&header, &pending.remove(&k).unwrap());
                    }
                    std::thread::sleep(Duration::from_micros(500));
                }
            })
        };
        SimAutopilot {
            start,
            silent,
            stop,
            thread: Some(thread),
        }
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

pub fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
        ..Default::default()
    })
}

/// TIMESYNC answers to requests read from `link`, stamped with the boot clock of an autopilot
/// started at `start`, for the sending thread to deliver. The reading thread ends with the
/// link (or, on UDP, at the first message after the sender is gone).
fn answer_timesync(
    link: Arc<dyn MavConnection<MavMessage> + Send + Sync>,
    start: Instant,
) -> std::sync::mpsc::Receiver<MavMessage> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        loop {
            let msg = match link.recv() {
                Ok((_, msg)) => msg,
                Err(mavlink::error::MessageReadError::Io(_)) => break,
                Err(_) => continue,
            };
            if let MavMessage::TIMESYNC(t) = msg
                && t.tc1 == 0
            {
                let now = (start.elapsed() + BOOTED_BEFORE).as_nanos() as i64;
                let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
                    tc1: now,
                    ts1: t.ts1,
                    ..Default::default()
                });
                if tx.send(answer).is_err() {
                    break;
                }
            }
        }
    });
    rx
}

/// ATTITUDE at `t` after the start: the autopilot's clock reads `t` + [`BOOTED_BEFORE`].
pub fn attitude(t: Duration, ypr: DVec3) -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: (t + BOOTED_BEFORE).as_millis() as u32,
        yaw: ypr.x as f32,
        pitch: ypr.y as f32,
        roll: ypr.z as f32,
        ..Default::default()
    })
}

/// A MAVLink 2 frame of `msg` from `system`, as bytes (to corrupt or send raw).
pub fn frame(system: u8, msg: &MavMessage) -> Vec<u8> {
    let mut out = vec![];
    let header = MavHeader {
        system_id: system.into(),
        component_id: 1,
        sequence: 7,
    };
    mavlink::write_versioned_msg(&mut out, mavlink::MavlinkVersion::V2, header, msg).unwrap();
    out
}

/// A UDP port free now.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}
