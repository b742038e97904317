//! The doctor's checks of the network: the ports `serve` listens on are free, and the
//! MAVLink endpoint hears an autopilot.

use super::Outcome;
use crate::app::Config;
use crate::autopilot::Endpoint;
use std::net::{SocketAddr, TcpListener, UdpSocket};
use std::time::Duration;

#[derive(Clone, Copy)]
enum Proto {
    Tcp,
    Udp,
}

/// What `serve` listens on with this configuration: (what, address, protocol, the setting
/// that moves it).
fn listens(cfg: &Config) -> Vec<(&'static str, String, Proto, &'static str)> {
    let mut out = vec![
        (
            "control",
            cfg.control.listen.clone(),
            Proto::Tcp,
            "--control",
        ),
        (
            "control",
            cfg.control.listen.clone(),
            Proto::Udp,
            "--control",
        ),
        (
            "rtsp",
            format!("{}:{}", cfg.rtsp.address, cfg.rtsp.port),
            Proto::Tcp,
            "--rtsp-port",
        ),
    ];
    if let Ok(Some(a)) = cfg.http.address() {
        out.push(("http", a.to_string(), Proto::Tcp, "--http"));
    }
    let m = &cfg.mavlink.endpoint;
    if let Some(a) = m.strip_prefix("udpin:") {
        out.push(("mavlink", a.to_string(), Proto::Udp, "--mavlink"));
    } else if let Some(a) = m.strip_prefix("tcpin:") {
        out.push(("mavlink", a.to_string(), Proto::Tcp, "--mavlink"));
    }
    out
}

/// Each port is free to listen on (port 0, any free one, always is).
pub fn ports(cfg: &Config) -> Vec<Outcome> {
    listens(cfg)
        .into_iter()
        .map(|(what, address, proto, flag)| {
            let kind = match proto {
                Proto::Tcp => "tcp",
                Proto::Udp => "udp",
            };
            let addr: SocketAddr = match address.parse() {
                Ok(a) => a,
                Err(_) => {
                    return Outcome::fail("ports", format!("{what} {address}: not ADDR:PORT"));
                }
            };
            let bound = match proto {
                Proto::Tcp => TcpListener::bind(addr).map(drop),
                Proto::Udp => UdpSocket::bind(addr).map(drop),
            };
            match bound {
                Ok(()) if addr.port() == 0 => {
                    Outcome::pass("ports", format!("{what} {kind} {address}: any free port"))
                }
                Ok(()) => Outcome::pass("ports", format!("{what} {kind} {address}: free")),
                Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => Outcome::fail(
                    "ports",
                    format!(
                        "{what} {kind} {address}: taken by another program (a digiview serve \
                         already running? `ss -lntup` names it); stop it or move {what} with \
                         {flag} or the config"
                    ),
                ),
                Err(e) => Outcome::fail("ports", format!("{what} {kind} {address}: {e}")),
            }
        })
        .collect()
}

/// With an endpoint configured, an autopilot's HEARTBEAT arrives within `wait`.
pub fn mavlink(cfg: &Config, wait: Duration) -> Outcome {
    let endpoint = &cfg.mavlink.endpoint;
    match endpoint.parse::<Endpoint>() {
        Ok(Endpoint::Off) => Outcome::pass("mavlink", "off (no autopilot link configured)"),
        Err(e) => Outcome::fail("mavlink", e.to_string()),
        Ok(Endpoint::Address(_)) => match crate::autopilot::probe::heartbeat(endpoint, wait) {
            Ok(h) => Outcome::pass(
                "mavlink",
                format!(
                    "{endpoint}: HEARTBEAT from system {} component {} ({})",
                    h.system, h.component, h.what
                ),
            ),
            Err(why) => Outcome::fail(
                "mavlink",
                format!(
                    "{endpoint}: {why}; is the autopilot connected and sending there (its \
                     MAVLink port, baud rate, or a router's output)? Set mavlink endpoint = \
                     \"off\" where there is none"
                ),
            ),
        },
    }
}
