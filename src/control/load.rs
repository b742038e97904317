//! A load generator for the control server (`digiview ctl load`): many TCP clients, each
//! pipelining alternating SETs and GETs, checked reply by reply, while one more client sits
//! stalled in the middle of a frame. Reports throughput and reply-time percentiles.

use crate::protocol::params::{CamFov, CamLockFlags};
use crate::protocol::{Body, FRAME_LEN, Message, Param, Verdict};
use std::io::{BufWriter, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

/// Frames written per flush: a client that pipelines, not one that writes frame by frame.
const BATCH: usize = 32;

#[derive(Clone, Debug, serde::Serialize)]
pub struct LoadReport {
    pub clients: usize,
    pub requests_per_client: usize,
    /// Replies received.
    pub replies: u64,
    /// Replies that were not the answer their request should get (type, camera or order).
    pub wrong: u64,
    pub seconds: f64,
    pub requests_per_second: f64,
    /// Time from a request's batch being written to its reply being read.
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub stalled_client: bool,
}

fn request(i: usize, cam: u8) -> Body {
    if i.is_multiple_of(2) {
        Body::Set(Param::CamFov(CamFov {
            cam_id: cam,
            fov: 0.5 + (i % 100) as f64 * 0.01,
        }))
    } else {
        Body::Get(Param::CamLockFlags(CamLockFlags {
            cam_id: cam,
            flags: 0,
        }))
    }
}

fn is_answer(i: usize, cam: u8, reply: &[u8]) -> bool {
    match Message::decode(reply).map(|m| m.body) {
        Ok(Body::Verdict(Verdict::Acknowledgement, 12)) => i.is_multiple_of(2),
        Ok(Body::Current(Param::CamLockFlags(p))) => i % 2 == 1 && p.cam_id == cam,
        _ => false,
    }
}

/// One client: a writer thread pipelines `n` requests while this thread reads and checks
/// the replies. Returns each request's reply time and the number of wrong replies.
fn client(addr: SocketAddr, id: usize, n: usize) -> std::io::Result<(Vec<Duration>, u64)> {
    let stream = TcpStream::connect(addr)?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(Duration::from_secs(30)))?;
    let cam = (id % 4) as u8;
    let out = stream.try_clone()?;
    let writer = std::thread::spawn(move || -> std::io::Result<Vec<Instant>> {
        let mut w = BufWriter::with_capacity(BATCH * FRAME_LEN, out);
        let mut sent = Vec::with_capacity(n);
        for start in (0..n).step_by(BATCH) {
            let end = (start + BATCH).min(n);
            for i in start..end {
                w.write_all(&Message::new(request(i, cam)).encode())?;
            }
            w.flush()?;
            sent.extend(std::iter::repeat_n(Instant::now(), end - start));
        }
        Ok(sent)
    });
    let mut rd = std::io::BufReader::with_capacity(64 * 1024, stream);
    let mut frame = [0u8; FRAME_LEN];
    let mut received = Vec::with_capacity(n);
    let mut wrong = 0;
    for i in 0..n {
        rd.read_exact(&mut frame)?;
        received.push(Instant::now());
        wrong += !is_answer(i, cam, &frame) as u64;
    }
    let sent = writer.join().expect("writer thread")?;
    // A reply can be read before its batch's send time was noted: count that as zero.
    let times = sent
        .iter()
        .zip(&received)
        .map(|(s, r)| r.saturating_duration_since(*s))
        .collect();
    Ok((times, wrong))
}

/// Runs `clients` clients of `requests` requests each against the server at `addr`, with one
/// more client stalled mid-frame throughout when `stall` is set.
pub fn run(
    addr: SocketAddr,
    clients: usize,
    requests: usize,
    stall: bool,
) -> std::io::Result<LoadReport> {
    let stalled = if stall {
        let mut s = TcpStream::connect(addr)?;
        let frame = Message::new(request(1, 0)).encode();
        s.write_all(&frame[..FRAME_LEN / 2])?;
        Some(s)
    } else {
        None
    };
    let start = Instant::now();
    let handles: Vec<_> = (0..clients)
        .map(|id| {
            std::thread::Builder::new()
                .name(format!("load-client-{id}"))
                .spawn(move || client(addr, id, requests))
        })
        .collect::<Result<_, _>>()?;
    let mut times = Vec::with_capacity(clients * requests);
    let mut wrong = 0;
    for h in handles {
        let (t, w) = h.join().expect("client thread")?;
        times.extend(t);
        wrong += w;
    }
    let seconds = start.elapsed().as_secs_f64();
    drop(stalled);
    times.sort_unstable();
    let pick = |q: f64| {
        times
            .get(((times.len() as f64 * q) as usize).min(times.len().saturating_sub(1)))
            .map_or(0.0, |d| d.as_secs_f64() * 1e3)
    };
    Ok(LoadReport {
        clients,
        requests_per_client: requests,
        replies: times.len() as u64,
        wrong,
        seconds,
        requests_per_second: times.len() as f64 / seconds,
        p50_ms: pick(0.5),
        p99_ms: pick(0.99),
        max_ms: pick(1.0),
        stalled_client: stall,
    })
}
