//! The names this server answers to, the defence against DNS rebinding: a page of another
//! site that makes its own name resolve to this machine still sends that name as `Host`, and
//! still has that name in its `Origin`. A request is served only when its `Host` is one of
//! this server's names: an IP address (a rebinding page cannot have one as its own name),
//! `localhost`, this machine's host name (and `NAME.local`), or a name the user configured
//! (`[http] hosts`, and the MAVLink cameras' `public_host`). A request that changes something
//! is taken only from a page whose `Origin` is one of those names on this server's own port.

use std::net::IpAddr;

#[derive(Clone, Debug)]
pub struct Names {
    /// Lower case, no trailing dot.
    names: Vec<String>,
    /// The port the server listens on: a page of another port is another site.
    port: u16,
}

impl Names {
    /// `localhost`, this machine's name, and `configured`, on `port`.
    pub fn new(configured: &[String], port: u16) -> Names {
        let mut names = vec!["localhost".to_string()];
        if let Some(host) = host_name() {
            names.push(format!("{host}.local"));
            names.push(host);
        }
        names.extend(configured.iter().map(|n| normal(n)));
        Names { names, port }
    }

    /// Whether a request's `Host` header (`NAME[:PORT]`, `[V6][:PORT]`) names this server.
    pub fn knows_host(&self, host: &str) -> bool {
        self.knows(split_port(host).0)
    }

    /// Whether an `Origin` (`SCHEME://NAME[:PORT]`) is a page of this server.
    pub fn knows_origin(&self, origin: &str) -> bool {
        let Some((scheme, rest)) = origin.split_once("://") else {
            return false; // "null": a sandboxed page, a file, a redirect chain
        };
        let (name, port) = split_port(rest);
        let port = match (port, scheme.to_ascii_lowercase().as_str()) {
            (Some(p), _) => p.parse::<u16>().ok(),
            (None, "http") => Some(80),
            (None, "https") => Some(443),
            (None, _) => None,
        };
        port == Some(self.port) && self.knows(name)
    }

    fn knows(&self, name: &str) -> bool {
        let bare = name.trim_start_matches('[').trim_end_matches(']');
        bare.parse::<IpAddr>().is_ok() || self.names.contains(&normal(name))
    }
}

fn normal(name: &str) -> String {
    name.trim().trim_end_matches('.').to_ascii_lowercase()
}

/// `name:port` into its parts; an IPv6 literal keeps its brackets.
fn split_port(host: &str) -> (&str, Option<&str>) {
    let host = host.trim();
    if host.starts_with('[') {
        return match host.split_once("]:") {
            Some((v6, port)) => (&host[..v6.len() + 1], Some(port)),
            None => (host, None),
        };
    }
    match host.rsplit_once(':') {
        // A bare IPv6 address has several colons and no port.
        Some((name, port)) if !name.contains(':') => (name, Some(port)),
        _ => (host, None),
    }
}

/// This machine's host name, lower case.
fn host_name() -> Option<String> {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most `len` bytes into `buf`, which outlives the call.
    let ok = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0;
    let end = buf.iter().position(|&b| b == 0)?;
    let name = std::str::from_utf8(&buf[..end]).ok()?;
    (ok && !name.is_empty()).then(|| normal(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_localhost_and_configured_names_only() {
        let n = Names::new(&["Drone1.example.".into()], 8080);
        for ok in [
            "127.0.0.1:8080",
            "192.168.1.20",
            "[::1]:8080",
            "::1",
            "localhost:8080",
            "LOCALHOST",
            "drone1.example:8080",
        ] {
            assert!(n.knows_host(ok), "{ok}");
        }
        for no in [
            "rebind.example:8080",
            "evil.localhost.example",
            "",
            "127.0.0.1.example",
        ] {
            assert!(!n.knows_host(no), "{no}");
        }
        if let Some(h) = host_name() {
            assert!(n.knows_host(&format!("{h}.local:8080")));
        }
    }

    #[test]
    fn an_origin_is_this_server_only_on_its_own_port() {
        let n = Names::new(&[], 8080);
        assert!(n.knows_origin("http://127.0.0.1:8080"));
        assert!(n.knows_origin("http://localhost:8080"));
        assert!(n.knows_origin("http://[::1]:8080"));
        assert!(
            !n.knows_origin("http://127.0.0.1:9090"),
            "another port's page"
        );
        assert!(!n.knows_origin("http://rebind.example:8080"));
        assert!(!n.knows_origin("null"));
        assert!(!n.knows_origin("http://localhost"), "port 80 is not 8080");
        assert!(Names::new(&[], 80).knows_origin("http://localhost"));
    }
}
