//! The host ground stations are told to fetch a camera's streams and files from.

use super::CamerasConfig;

/// The host ground stations are told to fetch streams from: `public_host`, else the RTSP
/// server's own address, else (it listens on every address) this machine's first network
/// address that is up and not loopback, else loopback.
pub fn public_host(cfg: &CamerasConfig, rtsp_address: &str) -> String {
    if let Some(h) = &cfg.public_host {
        return h.clone();
    }
    match rtsp_address {
        "0.0.0.0" | "::" | "" => first_address().unwrap_or_else(|| "127.0.0.1".into()),
        a => a.to_string(),
    }
}

/// This machine's first IPv4 address on an interface that is up, not loopback.
fn first_address() -> Option<String> {
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: getifaddrs fills `list` with a linked list that freeifaddrs releases; each
    // node's ifa_addr is null or points to a sockaddr of the family it names.
    unsafe {
        if libc::getifaddrs(&mut list) != 0 {
            return None;
        }
        let mut found = None;
        let mut node = list;
        while !node.is_null() && found.is_none() {
            let ifa = &*node;
            let up = ifa.ifa_flags & libc::IFF_UP as u32 != 0;
            let loopback = ifa.ifa_flags & libc::IFF_LOOPBACK as u32 != 0;
            if up
                && !loopback
                && !ifa.ifa_addr.is_null()
                && (*ifa.ifa_addr).sa_family as i32 == libc::AF_INET
            {
                let sin = &*(ifa.ifa_addr as *const libc::sockaddr_in);
                let ip = std::net::Ipv4Addr::from(u32::from_be(sin.sin_addr.s_addr));
                found = Some(ip.to_string());
            }
            node = ifa.ifa_next;
        }
        libc::freeifaddrs(list);
        found
    }
}
