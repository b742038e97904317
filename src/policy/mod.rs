//! One trust boundary for every control path. The DigiView protocol, the web API, its
//! WebSocket and MAVLink all ask the same [`Policy`] (through one function,
//! `crate::state::Gate::permit`) whether a peer may change the state
//! ([`Act::Change`]), stop the system ([`Act::Stop`]) or delete files ([`Act::Delete`]), and
//! note each refusal in the one rate-limited [`Refusals`] log. Shared data at the bottom:
//! it knows peers and lists, no service.
//!
//! A peer of the control protocol or HTTP is its address. A MAVLink peer is the address its
//! message came from where the transport has one (UDP, TCP; a serial link has none), and
//! whether the message was signed with the link's key. The address lists apply to both; a
//! MAVLink peer with no address is permitted only by `any`. Deleting files over MAVLink
//! needs a signed message as well (docs/security.md).

mod allow;
pub mod refusals;

pub use allow::{Allow, NotAnAddress};
pub use refusals::Refusals;

use std::fmt;
use std::net::IpAddr;

/// Who sent a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Peer {
    /// A client of the control protocol, the web API or its WebSocket.
    Net(IpAddr),
    /// A MAVLink sender.
    Mavlink {
        system: u8,
        component: u8,
        /// The address the message came from, where the transport has one.
        from: Option<IpAddr>,
        /// Whether the message was signed with the link's key (MAVLink 2 signing).
        signed: bool,
    },
}

impl Peer {
    /// The address the request came from, if the transport has one.
    pub fn address(&self) -> Option<IpAddr> {
        match *self {
            Peer::Net(a) => Some(a),
            Peer::Mavlink { from, .. } => from,
        }
    }
}

impl fmt::Display for Peer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Peer::Net(a) => write!(f, "{a}"),
            Peer::Mavlink {
                system,
                component,
                from,
                signed,
            } => {
                write!(f, "mavlink {system}/{component}")?;
                if let Some(a) = from {
                    write!(f, " at {a}")?;
                }
                f.write_str(if signed { " (signed)" } else { " (unsigned)" })
            }
        }
    }
}

/// What a request would do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// Change the live state: aim, zoom, layout, capture, settings.
    Change,
    /// Stop the system (QUIT).
    Stop,
    /// Delete files (MAVLink's STORAGE_FORMAT).
    Delete,
}

/// Why a request was not permitted: the reason the peer is told and the log shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Forbidden(pub &'static str);

/// Who may do what. Default: anyone may change the state; only loopback clients may stop
/// the system or delete files, and MAVLink deletes only with a signed message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Permissions {
    pub set: Allow,
    pub quit: Allow,
    pub delete: Allow,
}

impl Default for Permissions {
    fn default() -> Self {
        Permissions {
            set: Allow::Anyone,
            quit: Allow::loopback(),
            delete: Allow::loopback(),
        }
    }
}

impl Permissions {
    /// Whether `peer` may do `act` (asked through [`Policy::allow`], which notes a refusal).
    fn check(&self, peer: Peer, act: Act) -> Result<(), Forbidden> {
        let (list, refused) = match act {
            Act::Change => (&self.set, "SET is not permitted from here"),
            Act::Stop => (&self.quit, "QUIT is not permitted from here"),
            Act::Delete => (&self.delete, "deleting files is not permitted from here"),
        };
        let listed = match peer.address() {
            Some(a) => list.permits(a),
            None => *list == Allow::Anyone,
        };
        if !listed {
            return Err(Forbidden(refused));
        }
        if act == Act::Delete && matches!(peer, Peer::Mavlink { signed: false, .. }) {
            return Err(Forbidden(
                "deleting files over MAVLink needs a signed link ([mavlink] signing_key)",
            ));
        }
        Ok(())
    }
}

/// The policy every control path asks, and the refusals they all note.
#[derive(Default)]
pub struct Policy {
    pub permissions: Permissions,
    pub refusals: Refusals,
}

impl Policy {
    pub fn new(permissions: Permissions) -> Policy {
        Policy {
            permissions,
            refusals: Refusals::default(),
        }
    }

    /// Whether `peer` may do `act`; a refusal is noted with `what` was asked. Every control
    /// path asks it through one function, `crate::state::Gate::permit`.
    pub fn allow(&self, peer: Peer, act: Act, what: &str) -> Result<(), Forbidden> {
        self.permissions
            .check(peer, act)
            .inspect_err(|e| self.refusals.note(peer, what, e.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mavlink(from: Option<&str>, signed: bool) -> Peer {
        Peer::Mavlink {
            system: 255,
            component: 190,
            from: from.map(|a| a.parse().unwrap()),
            signed,
        }
    }

    #[test]
    fn every_path_is_judged_by_the_same_lists() {
        let p = Permissions {
            set: "10.0.0.0/8".parse().unwrap(),
            ..Permissions::default()
        };
        let local = Peer::Net("127.0.0.1".parse().unwrap());
        let lan = Peer::Net("10.1.2.3".parse().unwrap());
        assert!(p.check(lan, Act::Change).is_ok());
        assert!(p.check(local, Act::Change).is_err());
        assert!(
            p.check(mavlink(Some("10.9.9.9"), false), Act::Change)
                .is_ok()
        );
        assert!(
            p.check(mavlink(Some("127.0.0.1"), true), Act::Change)
                .is_err()
        );
        // A serial link has no address: only `any` lets it change the state.
        assert!(p.check(mavlink(None, true), Act::Change).is_err());
        assert!(
            Permissions::default()
                .check(mavlink(None, false), Act::Change)
                .is_ok()
        );
        assert!(p.check(local, Act::Stop).is_ok());
        assert!(p.check(lan, Act::Stop).is_err());
    }

    #[test]
    fn none_refuses_every_peer_and_mavlink_deletes_only_signed() {
        let none = Permissions {
            set: "none".parse().unwrap(),
            quit: "none".parse().unwrap(),
            delete: "none".parse().unwrap(),
        };
        let open = Permissions {
            delete: Allow::Anyone,
            ..Permissions::default()
        };
        for peer in [
            Peer::Net("127.0.0.1".parse().unwrap()),
            mavlink(Some("127.0.0.1"), true),
            mavlink(None, true),
        ] {
            for act in [Act::Change, Act::Stop, Act::Delete] {
                assert!(none.check(peer, act).is_err(), "{peer} {act:?}");
            }
        }
        let d = Permissions::default();
        assert!(
            d.check(mavlink(Some("127.0.0.1"), false), Act::Delete)
                .is_err()
        );
        assert!(open.check(mavlink(None, false), Act::Delete).is_err());
        assert!(
            d.check(mavlink(Some("127.0.0.1"), true), Act::Delete)
                .is_ok()
        );
        assert!(open.check(mavlink(None, true), Act::Delete).is_ok());
        assert!(
            d.check(Peer::Net("127.0.0.1".parse().unwrap()), Act::Delete)
                .is_ok()
        );
        assert!(
            d.check(Peer::Net("192.168.1.4".parse().unwrap()), Act::Delete)
                .is_err()
        );
    }

    #[test]
    fn a_refusal_is_noted_for_its_peer() {
        let policy = Policy::new(Permissions {
            set: "none".parse().unwrap(),
            ..Permissions::default()
        });
        let peer = mavlink(Some("127.0.0.1"), false);
        let e = policy
            .allow(peer, Act::Change, "SET_CAMERA_ZOOM")
            .unwrap_err();
        assert_eq!(policy.refusals.last(peer).as_deref(), Some(e.0));
        assert_eq!(policy.refusals.count(), 1);
    }
}
