//! Who drives the views: the component whose attitude they follow, whether that is the
//! demo's simulated flight (told from a real autopilot by the address it sends from, since
//! both are system 1, component 1), and the other components heard sending attitude, which
//! are ignored and shown as a warning. A real autopilot always wins: once one is heard the
//! demo's flight steps aside for the rest of the run.

use crate::supervise::Locked;
use serde::Serialize;
use std::net::SocketAddr;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Another sender of attitude counts for this long after it was last heard.
pub const OTHER_FOR: Duration = Duration::from_secs(5);
/// Another sender silent this long is announced again when it comes back.
const ANNOUNCE_AGAIN: Duration = Duration::from_secs(30);
/// The most other senders remembered (the newest kept).
const MAX_OTHERS: usize = 8;
/// At most one announcement this often, whatever a flood of ids does.
const ANNOUNCE_EVERY: Duration = Duration::from_secs(1);

/// The component the views follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Driver {
    pub system: u8,
    pub component: u8,
    /// The demo's simulated flight, not an autopilot.
    pub simulated: bool,
}

#[derive(Default)]
pub struct Drivers {
    /// Where the demo's simulated flight sends from (None: no demo on this link).
    demo_from: Mutex<Option<SocketAddr>>,
    /// A real autopilot was heard: the demo's flight stops sending.
    demo_aside: AtomicBool,
    driver: Mutex<Option<Driver>>,
    others: Mutex<Others>,
}

/// Other components heard sending attitude, and when one was last announced.
#[derive(Default)]
struct Others {
    /// System, component, when last heard.
    heard: Vec<(u8, u8, Instant)>,
    announced: Option<Instant>,
}

impl Drivers {
    /// The demo's flight sends from `from` (its own socket); false when it must step aside.
    pub fn demo_sends_from(&self, from: Option<SocketAddr>) -> bool {
        *self.demo_from.locked() = from;
        !self.demo_aside()
    }

    /// Whether a frame from `from` is the demo's simulated flight.
    pub fn is_demo(&self, from: Option<SocketAddr>) -> bool {
        from.is_some() && *self.demo_from.locked() == from
    }

    pub fn demo_aside(&self) -> bool {
        self.demo_aside.load(Ordering::Relaxed)
    }

    /// `driver` drives the views now; a real autopilot sends the demo's flight aside.
    pub fn set(&self, driver: Driver) {
        if !driver.simulated {
            self.demo_aside.store(true, Ordering::Relaxed);
        }
        *self.driver.locked() = Some(driver);
    }

    pub fn driver(&self) -> Option<Driver> {
        *self.driver.locked()
    }

    /// `system`/`component` sent attitude too; true when that is news to announce (first
    /// heard, or back after [`ANNOUNCE_AGAIN`]; at most one a second).
    pub fn other(&self, system: u8, component: u8) -> bool {
        let now = Instant::now();
        let mut others = self.others.locked();
        let Others { heard, announced } = &mut *others;
        let quiet = announced.is_none_or(|t| now - t >= ANNOUNCE_EVERY);
        let news = match heard.iter_mut().find(|o| (o.0, o.1) == (system, component)) {
            Some(o) => {
                let news = quiet && now - o.2 >= ANNOUNCE_AGAIN;
                o.2 = now;
                news
            }
            None => {
                if heard.len() == MAX_OTHERS {
                    heard.sort_by_key(|o| std::cmp::Reverse(o.2));
                    heard.pop();
                }
                heard.push((system, component, now));
                quiet
            }
        };
        if news {
            *announced = Some(now);
        }
        news
    }

    /// The other senders of attitude heard within [`OTHER_FOR`], newest first.
    pub fn others(&self) -> Vec<(u8, u8)> {
        let mut others = self.others.locked().heard.clone();
        others.retain(|o| o.2.elapsed() < OTHER_FOR);
        others.sort_by_key(|o| std::cmp::Reverse(o.2));
        others.into_iter().map(|o| (o.0, o.1)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_is_told_by_its_address_and_steps_aside_for_an_autopilot() {
        let d = Drivers::default();
        let demo: SocketAddr = "127.0.0.1:40000".parse().unwrap();
        let other: SocketAddr = "127.0.0.1:40001".parse().unwrap();
        assert!(!d.is_demo(Some(demo)), "no demo yet");
        assert!(d.demo_sends_from(Some(demo)));
        assert!(d.is_demo(Some(demo)) && !d.is_demo(Some(other)) && !d.is_demo(None));
        let flying = |simulated| Driver {
            system: 1,
            component: 1,
            simulated,
        };
        d.set(flying(true));
        assert!(!d.demo_aside(), "the demo drives");
        d.set(flying(false));
        assert!(d.demo_aside() && !d.demo_sends_from(Some(demo)));
        assert_eq!(d.driver(), Some(flying(false)));
    }

    /// A flood of made-up ids is announced once a second at most, and listed.
    #[test]
    fn another_sender_is_news_once_and_listed_while_it_sends() {
        let d = Drivers::default();
        assert!(d.other(2, 1));
        assert!(!d.other(2, 1), "heard again at once: no news");
        assert!(!d.other(3, 1), "news a second apart at most");
        assert_eq!(d.others(), vec![(3, 1), (2, 1)]);
        for id in 10..=255 {
            assert!(!d.other(id, 1));
        }
        assert_eq!(d.others().len(), MAX_OTHERS);
    }
}
