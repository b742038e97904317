//! `[mavlink]` in the serve configuration: where the autopilot link goes ([`Endpoint`]), which
//! autopilot to follow, the rates asked of it, and the MAVLink 2 signing key.

use crate::telemetry::AttitudeSample;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct MavlinkConfig {
    /// The autopilot link (docs/mavlink.md): `udpin:ADDR:PORT`, `udpout:HOST:PORT`,
    /// `tcpin:ADDR:PORT`, `tcpout:HOST:PORT`, `serial:DEVICE:BAUD`, or `off`.
    pub endpoint: String,
    /// Take the autopilot from this system id only (default: the first autopilot heard).
    pub system_id: Option<u8>,
    /// The ATTITUDE rate asked of the autopilot, Hz.
    pub attitude_hz: f64,
    /// The GLOBAL_POSITION_INT rate asked of the autopilot, Hz.
    pub position_hz: f64,
    /// MAVLink 2 signing: 64 hex digits (the 32-byte key), or a passphrase whose SHA-256 is
    /// the key. With it, unsigned and badly signed messages are ignored (and counted), and
    /// DigiView signs what it sends.
    pub signing_key: Option<String>,
    /// Which attitude a frame is rendered with: `interpolated` (slerp at its capture time)
    /// or `latest` (the newest sample when it is rendered; only to see what interpolation
    /// is worth).
    pub attitude_sample: AttitudeSample,
}

impl Default for MavlinkConfig {
    fn default() -> Self {
        MavlinkConfig {
            endpoint: "udpin:0.0.0.0:14550".into(),
            system_id: None,
            attitude_hz: 100.0,
            position_hz: 10.0,
            signing_key: None,
            attitude_sample: AttitudeSample::Interpolated,
        }
    }
}

/// Where the link goes: `off`, or an address the `mavlink` crate opens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    Off,
    Address(String),
}

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EndpointError {
    #[error(
        "mavlink endpoint {0:?}: use udpin:ADDR:PORT, udpout:HOST:PORT, tcpin:ADDR:PORT, \\
         tcpout:HOST:PORT, serial:DEVICE:BAUD or off"
    )]
    Form(String),
    #[error("mavlink endpoint {0:?}: {1}")]
    Part(String, &'static str),
}

impl std::str::FromStr for Endpoint {
    type Err = EndpointError;
    fn from_str(s: &str) -> Result<Endpoint, EndpointError> {
        if s.eq_ignore_ascii_case("off") {
            return Ok(Endpoint::Off);
        }
        let form = || EndpointError::Form(s.to_string());
        let (kind, rest) = s.split_once(':').ok_or_else(form)?;
        let (head, tail) = rest.rsplit_once(':').ok_or_else(form)?;
        match kind {
            "udpin" | "udpout" | "tcpin" | "tcpout" => {
                if head.is_empty() {
                    return Err(EndpointError::Part(s.into(), "no address"));
                }
                tail.parse::<u16>()
                    .map_err(|_| EndpointError::Part(s.into(), "the port is not 0..=65535"))?;
            }
            "serial" => {
                if head.is_empty() {
                    return Err(EndpointError::Part(s.into(), "no device"));
                }
                match tail.parse::<u32>() {
                    Ok(b) if b > 0 => {}
                    _ => {
                        return Err(EndpointError::Part(
                            s.into(),
                            "the baud rate is not a number",
                        ));
                    }
                }
            }
            _ => return Err(form()),
        }
        mavlink::ConnectionAddress::parse_address(s).map_err(|_| form())?;
        Ok(Endpoint::Address(s.to_string()))
    }
}

impl Endpoint {
    /// The UDP port a peer on this machine sends to to be heard by this endpoint, when it
    /// listens on UDP (udpin); None when it is off, on TCP or a serial line, or goes elsewhere.
    pub fn loopback_udp_port(&self) -> Option<u16> {
        let Endpoint::Address(a) = self else {
            return None;
        };
        let (_, port) = a.strip_prefix("udpin:")?.rsplit_once(':')?;
        port.parse().ok()
    }
}

/// The 32-byte signing key of `signing_key`: 64 hex digits as they are, anything else a
/// passphrase hashed with SHA-256 (as MAVProxy's `signing setup` and Mission Planner do).
pub fn signing_key(text: &str) -> [u8; 32] {
    let hex = |i: usize| u8::from_str_radix(text.get(2 * i..2 * i + 2)?, 16).ok();
    if text.len() == 64
        && let Some(bytes) = (0..32).map(hex).collect::<Option<Vec<u8>>>()
    {
        return bytes.try_into().expect("32 bytes");
    }
    use sha2::Digest;
    sha2::Sha256::digest(text.as_bytes()).into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signing_key_is_64_hex_digits_or_a_passphrase() {
        let hex = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
        assert_eq!(signing_key(hex)[..4], [0x00, 0x11, 0x22, 0x33]);
        // SHA-256("abc"), the standard's own test vector.
        assert_eq!(signing_key("abc")[..4], [0xba, 0x78, 0x16, 0xbf]);
    }

    #[test]
    fn endpoints_are_checked() {
        for ok in [
            "udpin:0.0.0.0:14550",
            "udpout:192.168.1.10:14550",
            "tcpin:0.0.0.0:5760",
            "tcpout:127.0.0.1:5760",
            "serial:/dev/ttyAMA0:921600",
        ] {
            assert_eq!(ok.parse(), Ok(Endpoint::Address(ok.into())), "{ok}");
        }
        assert_eq!("off".parse(), Ok(Endpoint::Off));
        let peer = |e: &str| e.parse::<Endpoint>().unwrap().loopback_udp_port();
        assert_eq!(peer("udpin:0.0.0.0:14550"), Some(14550));
        assert_eq!(
            peer("tcpin:0.0.0.0:5760"),
            None,
            "one peer: the demo would hold it"
        );
        assert_eq!(peer("udpout:10.0.0.2:14550"), None);
        assert_eq!(peer("off"), None);
        for bad in [
            "udp:1.2.3.4:5",
            "udpin:0.0.0.0",
            "udpin:0.0.0.0:99999",
            "tcpout::5760",
            "serial:/dev/ttyS0:fast",
            "serial:/dev/ttyS0",
            "file:log.tlog",
            "",
        ] {
            assert!(bad.parse::<Endpoint>().is_err(), "{bad}");
        }
    }
}
