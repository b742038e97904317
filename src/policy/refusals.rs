//! Why requests were refused, on every control path alike: each refusal is logged at info
//! level (at most a few lines a second, then one summary line "N more refused in the last
//! second, the last: ...", so a flood cannot fill the journal), and the last one per client
//! address is kept for the REFUSAL extension, which `digiview ctl` reads to say why its
//! request was refused.

use super::Peer;
use crate::supervise::Locked;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// At most this many refusal lines a second.
const LINES_PER_SECOND: u32 = 5;
/// Addresses remembered; past this the oldest reasons are forgotten.
const PEERS: usize = 256;

#[derive(Default)]
pub struct Refusals {
    inner: Mutex<Inner>,
}

#[derive(Default)]
struct Inner {
    last: HashMap<Peer, (u64, String)>,
    /// Refusals so far, which orders `last` by age.
    count: u64,
    window: Option<Instant>,
    logged: u32,
    left_out: u64,
    /// The last refusal not logged line by line, for the summary.
    last_left_out: String,
}

impl Inner {
    fn summarise(&mut self) {
        if self.left_out > 0 {
            tracing::info!(
                "{} more refused in the last second, the last: {}",
                self.left_out,
                self.last_left_out
            );
        }
        self.left_out = 0;
    }
}

impl Refusals {
    /// Notes that `peer`'s request `what` was refused because of `why`.
    pub fn note(&self, peer: Peer, what: &str, why: &str) {
        let mut g = self.inner.locked();
        let inner = &mut *g;
        inner.count += 1;
        if inner.last.len() >= PEERS && !inner.last.contains_key(&peer) {
            let oldest = inner
                .last
                .iter()
                .min_by_key(|(_, (n, _))| *n)
                .map(|(p, _)| *p);
            if let Some(p) = oldest {
                inner.last.remove(&p);
            }
        }
        inner.last.insert(peer, (inner.count, why.to_string()));

        let now = Instant::now();
        if inner
            .window
            .is_none_or(|w| now.duration_since(w) >= Duration::from_secs(1))
        {
            inner.summarise();
            inner.window = Some(now);
            inner.logged = 0;
        }
        if inner.logged < LINES_PER_SECOND {
            inner.logged += 1;
            tracing::info!(%peer, "refused {what}: {why}");
        } else {
            inner.left_out += 1;
            inner.last_left_out = format!("{what} from {peer}: {why}");
        }
    }

    /// Logs the summary of the refusals left out, if any, even when no new refusal comes
    /// (the frame loop's health thread, or any periodic task, may call it).
    pub fn flush(&self) {
        let mut g = self.inner.locked();
        if g.window
            .is_some_and(|w| w.elapsed() >= Duration::from_secs(1))
        {
            g.summarise();
            g.window = None;
        }
    }

    /// Refusals noted since the start.
    pub fn count(&self) -> u64 {
        self.inner.locked().count
    }

    /// The reason for `peer`'s last refused request, if it had one.
    pub fn last(&self, peer: Peer) -> Option<String> {
        let g = self.inner.locked();
        g.last.get(&peer).map(|(_, why)| why.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::{IpAddr, Ipv4Addr};

    #[test]
    fn each_address_keeps_its_own_last_reason_and_the_memory_is_bounded() {
        let r = Refusals::default();
        let a = Peer::Net(IpAddr::V4(Ipv4Addr::new(10, 0, 0, 1)));
        let b = Peer::Net(IpAddr::V4(Ipv4Addr::new(10, 0, 0, 2)));
        assert_eq!(r.last(a), None);
        r.note(a, "SET LENS", "lens_id 9 is not in lens.cal");
        r.note(b, "GET CAM_FOV", "cam_id 7 is outside 0..=3");
        r.note(a, "SET CAPTURE", "not a directory");
        assert_eq!(r.last(a).as_deref(), Some("not a directory"));
        assert_eq!(r.last(b).as_deref(), Some("cam_id 7 is outside 0..=3"));
        for i in 0..1000u32 {
            r.note(
                Peer::Net(IpAddr::V4(Ipv4Addr::from(i))),
                "SET LENS",
                "flood",
            );
        }
        let g = r.inner.lock().unwrap();
        assert_eq!(g.last.len(), PEERS);
        assert!(!g.last.contains_key(&a), "the oldest are forgotten first");
        assert!(g.left_out > 0, "a flood is not logged line by line");
    }
}
