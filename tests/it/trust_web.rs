//! The web server as a hostile page or script would try it: a DNS-rebinding request (a name
//! that is not the server's, in Host and Origin alike) is refused and changes nothing; a page
//! of another port is another site; names the user configures are served; the event
//! WebSocket closes on a flood of frames of any type, and on one oversized frame, while
//! another client's SET is answered at once. Plain HTTP/1.1 written by hand and
//! tokio-tungstenite, against `digiview serve`.

use crate::common;

use common::serve::Serve;
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

/// One request to `addr` with the given Host and Origin headers (a CAM_FOV body): the
/// status and the body.
fn request(
    addr: &str,
    method: &str,
    path: &str,
    host: &str,
    origin: Option<&str>,
) -> (u16, String) {
    let body = json!({"cam_id": 1, "fov": 0.9}).to_string();
    let mut headers = vec![("Host", host)];
    headers.extend(origin.map(|o| ("Origin", o)));
    common::raw_request(addr, method, path, &headers, &body).unwrap()
}

fn fov_1(addr: &str) -> f64 {
    let (code, body) = request(addr, "GET", "/api/params/CAM_FOV?cam_id=1", addr, None);
    assert_eq!(code, 200, "{body}");
    serde_json::from_str::<Value>(&body).unwrap()["fov"]
        .as_f64()
        .unwrap()
}

#[test]
fn a_rebinding_page_is_refused_and_the_servers_own_names_are_served() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("digiview.toml");
    std::fs::write(&config, "[http]\nhosts = [\"drone1.example\"]\n").unwrap();
    let serve = Serve::start(&["--config", config.to_str().unwrap()]);
    let http = serve.http.clone().unwrap();
    let addr = http.trim_start_matches("http://").trim_end_matches('/');
    let port = addr.rsplit_once(':').unwrap().1;
    let before = fov_1(addr);

    // The request: a rebinding page's name in Host and Origin alike.
    let rebound = format!("rebind.example:{port}");
    let origin = format!("http://{rebound}");
    let path = "/api/params/CAM_FOV";
    let (code, why) = request(addr, "PUT", path, &rebound, Some(&origin));
    assert_eq!(code, 403, "{why}");
    assert!(why.contains("rebind.example"), "{why}");
    // Nor may it read.
    let (code, _) = request(addr, "GET", "/api/status", &rebound, None);
    assert_eq!(code, 403);
    assert_eq!(fov_1(addr), before, "nothing changed");

    // A page of this server by any of its names may change the state; a page of another
    // port on the same machine is another site.
    for name in ["127.0.0.1", "localhost", "drone1.example"] {
        let host = format!("{name}:{port}");
        let (code, why) = request(addr, "PUT", path, &host, Some(&format!("http://{host}")));
        assert_eq!(code, 200, "{name}: {why}");
    }
    let other = format!("http://127.0.0.1:{}", port.parse::<u16>().unwrap() ^ 1);
    let (code, _) = request(addr, "PUT", path, addr, Some(&other));
    assert_eq!(code, 403, "a page of another port");
    let (code, _) = request(addr, "PUT", path, addr, Some(&origin));
    assert_eq!(code, 403, "a rebinding page's Origin under a good Host");
    // A script (no Origin) by address is served as before.
    let (code, _) = request(addr, "PUT", path, addr, None);
    assert_eq!(code, 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_frames_of_any_type_closes_the_socket_and_others_are_answered() {
    let serve = Serve::start(&[]);
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let url = format!("ws://{host}/api/events");

    for (what, frame) in [
        ("binary", Message::Binary(vec![0u8; 16].into())),
        ("ping", Message::Ping(vec![1u8; 8].into())),
    ] {
        let (mut flood, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        let (mut other, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        // Sending until the server closes the socket (at most 3 s).
        let started = Instant::now();
        let mut sent = 0u64;
        let closed = loop {
            if started.elapsed() > Duration::from_secs(3) {
                break false;
            }
            if flood.send(frame.clone()).await.is_err() {
                break true;
            }
            sent += 1;
            // Reading what came back shows a close as soon as it comes.
            match tokio::time::timeout(Duration::from_micros(1), flood.next()).await {
                Ok(None) | Ok(Some(Err(_))) | Ok(Some(Ok(Message::Close(_)))) => break true,
                _ => {}
            }
        };
        println!("{what}: {sent} frames, closed: {closed}");
        assert!(
            closed,
            "{what}: {sent} frames in 3 s and the socket is still open"
        );

        // The other client's SET is answered within a second.
        let set = json!({"id": 7, "set": "CAM_FOV", "fields": {"cam_id": 2, "fov": "50deg"}});
        other
            .send(Message::Text(set.to_string().into()))
            .await
            .unwrap();
        let asked = Instant::now();
        let answered = loop {
            let next = tokio::time::timeout(Duration::from_secs(1), other.next()).await;
            let Ok(Some(Ok(Message::Text(t)))) = next else {
                break false;
            };
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["id"] == 7 {
                assert!(v.get("ok").is_some(), "{v}");
                break true;
            }
        };
        assert!(
            answered && asked.elapsed() < Duration::from_secs(1),
            "{what}"
        );
    }

    // One frame larger than any message the page sends closes the socket too.
    let (mut big, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
    let huge = format!("{{\"id\": 1, \"pad\": \"{}\"}}", "x".repeat(64 * 1024));
    let _ = big.send(Message::Text(huge.into())).await;
    let deadline = Instant::now() + Duration::from_secs(3);
    let closed = loop {
        match tokio::time::timeout(Duration::from_secs(3), big.next()).await {
            Ok(None) | Ok(Some(Err(_))) | Ok(Some(Ok(Message::Close(_)))) => break true,
            Ok(Some(Ok(_))) if Instant::now() < deadline => continue,
            _ => break false,
        }
    };
    assert!(closed, "an oversized frame");
}
