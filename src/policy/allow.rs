//! A set of client addresses, as `allow_set`, `allow_quit` and `allow_delete` write them.

use ipnet::IpNet;
use std::net::IpAddr;
use std::str::FromStr;

/// A set of client addresses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Allow {
    Anyone,
    /// These networks only; empty is no one.
    Nets(Vec<IpNet>),
}

impl Allow {
    pub fn loopback() -> Allow {
        Allow::Nets(vec![
            "127.0.0.0/8".parse().expect("literal"),
            "::1/128".parse().expect("literal"),
        ])
    }

    pub fn permits(&self, peer: IpAddr) -> bool {
        // A v4 client on a dual-stack socket shows up as ::ffff:a.b.c.d.
        let peer = peer.to_canonical();
        match self {
            Allow::Anyone => true,
            Allow::Nets(nets) => nets.iter().any(|n| n.contains(&peer)),
        }
    }
}

/// A word in a permission list that is none of the forms it takes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is not an address, a CIDR range, `loopback`, `any` or `none`")]
pub struct NotAnAddress(pub String);

impl FromStr for Allow {
    type Err = NotAnAddress;

    /// `any`, `none`, `loopback`, or a comma-separated list of addresses and CIDR ranges
    /// (`loopback` may be one of them).
    fn from_str(text: &str) -> Result<Allow, NotAnAddress> {
        match text.trim() {
            "any" | "anyone" => return Ok(Allow::Anyone),
            "none" | "" => return Ok(Allow::Nets(vec![])),
            _ => {}
        }
        let mut nets = Vec::new();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if item == "loopback" {
                let Allow::Nets(l) = Allow::loopback() else {
                    unreachable!()
                };
                nets.extend(l);
            } else if let Ok(n) = item.parse::<IpNet>() {
                nets.push(n);
            } else if let Ok(a) = item.parse::<IpAddr>() {
                nets.push(IpNet::from(a));
            } else {
                return Err(NotAnAddress(item.to_string()));
            }
        }
        Ok(Allow::Nets(nets))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_of_ranges_permit_their_members_only() {
        let a: Allow = "loopback, 10.0.0.0/8, 192.168.1.7".parse().unwrap();
        for ok in [
            "127.0.0.1",
            "::1",
            "10.200.3.4",
            "192.168.1.7",
            "::ffff:10.1.1.1",
        ] {
            assert!(a.permits(ok.parse().unwrap()), "{ok}");
        }
        for no in ["192.168.1.8", "8.8.8.8", "fe80::1"] {
            assert!(!a.permits(no.parse().unwrap()), "{no}");
        }
        assert!(
            !"none"
                .parse::<Allow>()
                .unwrap()
                .permits("127.0.0.1".parse().unwrap())
        );
        assert!(
            "any"
                .parse::<Allow>()
                .unwrap()
                .permits("8.8.8.8".parse().unwrap())
        );
        assert!(
            "10.0.0.0/33"
                .parse::<Allow>()
                .unwrap_err()
                .to_string()
                .contains("10.0.0.0/33")
        );
    }
}
