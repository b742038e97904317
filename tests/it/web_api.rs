//! The JSON API as a script uses it, with no browser: plain HTTP/1.1 requests written by hand
//! and a WebSocket client that is not the page's (tokio-tungstenite). Reads agree with the
//! binary protocol, SETs take effect there, bad values are refused with a reason and change
//! nothing (what the protocol clamps is clamped here too), and the event socket pushes a
//! change made over the binary protocol.

use crate::common;

use common::serve::Serve;
use digiview::control::client::{Client, query};
use digiview::protocol::params::CamFov;
use digiview::protocol::{Param, ParamType};
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// One request, `Connection: close`: the status and the JSON body.
fn request(host: &str, method: &str, path: &str, body: Option<&Value>) -> (u16, Value) {
    let body = body.map(Value::to_string).unwrap_or_default();
    let (status, body) = common::raw_request(host, method, path, &[("Host", host)], &body).unwrap();
    (status, serde_json::from_str(&body).unwrap_or(Value::Null))
}

fn fov_of(client: &mut Client, cam: u8) -> f64 {
    match client.get_one(query(ParamType::CamFov, cam)).unwrap() {
        Param::CamFov(f) => f.fov,
        p => panic!("{p:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_script_reads_and_sets_over_rest_and_the_event_socket() {
    let serve = Serve::start(&[]);
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let mut client =
        Client::connect(&serve.addr.to_string(), false, Duration::from_secs(5)).unwrap();

    // REST: a read agrees with the binary protocol's; a SET is seen there.
    let (code, fov) = request(host, "GET", "/api/params/CAM_FOV?cam_id=1", None);
    assert_eq!(code, 200, "{fov}");
    assert!((fov["fov"].as_f64().unwrap() - fov_of(&mut client, 1)).abs() < 1e-3);
    let (code, after) = request(
        host,
        "PUT",
        "/api/params/CAM_FOV",
        Some(&json!({"cam_id": 1, "fov": "40deg"})),
    );
    assert_eq!(code, 200, "{after}");
    assert!((after["fov"].as_f64().unwrap() - 40.0 * DEG).abs() < 1e-3);
    assert!((fov_of(&mut client, 1) - 40.0 * DEG).abs() < 1e-3);

    // Bad input: a reason, and nothing changed.
    let (_, lens) = request(host, "GET", "/api/params/LENS", None);
    let (_, general) = request(host, "GET", "/api/params/GENERAL_SETTINGS", None);
    let (_, fov0) = request(host, "GET", "/api/params/CAM_FOV?cam_id=0", None);
    for (param, body, want) in [
        ("CAM_FOV", json!({"cam_id": 1, "fov": "wide"}), 400),
        ("CAM_FOV", json!({"cam_id": 9, "fov": "30deg"}), 422),
        ("CAM_FOV", json!([1, 2]), 400),
        ("LENS", json!({"lens_id": 9}), 422),
        // Nothing to set, or no camera: not camera 0's fov set to zero (then clamped).
        ("CAM_FOV", json!({}), 400),
        ("CAM_FOV", json!({"fov": "30deg"}), 400),
        // Beyond what a mount can be: refused, naming it; the state unchanged (below).
        ("GENERAL_SETTINGS", json!({"mount_pitch": 1e300}), 422),
    ] {
        let path = format!("/api/params/{param}");
        let (code, why) = request(host, "PUT", &path, Some(&body));
        println!("PUT {param} {body}: {code} {why}");
        assert_eq!(code, want, "{body}: {why}");
        assert!(
            !why["error"].as_str().unwrap_or_default().is_empty(),
            "{body}: no reason"
        );
    }
    let (_, why) = request(
        host,
        "PUT",
        "/api/params/GENERAL_SETTINGS",
        Some(&json!({"mount_pitch": 1e300})),
    );
    assert!(
        why["error"]
            .as_str()
            .unwrap_or_default()
            .contains("mount pitch 1e300 is outside ±π/2 rad"),
        "{why}"
    );
    assert_eq!(
        request(host, "GET", "/api/params/GENERAL_SETTINGS", None).1,
        general
    );
    assert_eq!(
        request(host, "GET", "/api/params/CAM_FOV?cam_id=0", None).1,
        fov0
    );
    // A body that is not JSON, or says it is not: the API's JSON error all the same; so is
    // every other refusal (a name the server does not answer to).
    let raw = |headers: &[(&str, &str)], body: &str| {
        let (code, body) =
            common::raw_request(host, "PUT", "/api/params/CAM_FOV", headers, body).unwrap();
        (
            code,
            serde_json::from_str::<Value>(&body).unwrap_or(Value::Null),
        )
    };
    for (headers, body, says) in [
        (
            &[("Host", host)][..],
            "{\"cam_id\": 1, fov",
            "the body is not JSON",
        ),
        (&[("Host", host)][..], "", "Content-Type: application/json"),
        (
            &[("Host", "evil.example")][..],
            "{}",
            "does not answer to the name",
        ),
    ] {
        let (code, why) = raw(headers, body);
        let error = why["error"].as_str().unwrap_or_default();
        assert!(
            code >= 400 && error.contains(says),
            "{body:?}: {code} {why}"
        );
    }
    // A value the protocol clamps or ignores is set as the protocol has it, and the reply
    // says so; one it takes as given says nothing more.
    let path = "/api/params/VIDEO_OUTPUT";
    let (code, reply) = request(
        host,
        "PUT",
        path,
        Some(&json!({"fps": 99, "layout_mode": 9})),
    );
    assert_eq!(code, 200, "{reply}");
    assert_eq!(
        reply["clamped"]["fps"],
        json!({"asked": 99.0, "set": 30.0}),
        "{reply}"
    );
    assert_eq!(reply["clamped"]["layout_mode"]["asked"], 9.0, "{reply}");
    assert_eq!(reply["fps"], 30);
    let (_, reply) = request(host, "PUT", path, Some(&json!({"fps": 25})));
    assert!(
        reply.get("clamped").is_none() && reply["fps"] == 25,
        "{reply}"
    );
    request(host, "PUT", path, Some(&json!({"fps": 30})));
    assert_eq!(request(host, "GET", "/api/params/LENS", None).1, lens);
    let (code, why) = request(host, "GET", "/api/params/NO_SUCH", None);
    assert_eq!(code, 404);
    assert!(why["error"].is_string(), "{why}");
    assert!(
        (fov_of(&mut client, 1) - 40.0 * DEG).abs() < 1e-3,
        "the refusals changed nothing"
    );

    // The event socket: the state first, SETs answered by id, refusals with their code.
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("ws://{host}/api/events"))
        .await
        .expect("a client without an Origin header (not a browser) is let in");
    // The first message is the whole state.
    let first: Value = loop {
        let m = tokio::time::timeout(Duration::from_secs(3), socket.next())
            .await
            .expect("a message within 3 s")
            .unwrap()
            .unwrap();
        if let Message::Text(t) = m {
            break serde_json::from_str(&t).unwrap();
        }
    };
    assert!(first["params"]["CAM_FOV"][1]["fov"].is_number(), "{first}");
    let set = json!({"id": 7, "set": "CAM_FOV", "fields": {"cam_id": 2, "fov": "55deg"}});
    socket.send(Message::text(set.to_string())).await.unwrap();
    let bad = json!({"id": 8, "set": "LENS", "fields": {"lens_id": 7}});
    socket.send(Message::text(bad.to_string())).await.unwrap();
    socket.send(Message::text("not json")).await.unwrap();
    let mut replies = vec![];
    let limit = Instant::now() + Duration::from_secs(3);
    while replies.len() < 3 && Instant::now() < limit {
        let Some(Ok(Message::Text(t))) = socket.next().await else {
            continue;
        };
        let v: Value = serde_json::from_str(&t).unwrap();
        if v.get("params").is_none() && v.get("status").is_none() {
            replies.push(v);
        }
    }
    println!("event socket replies: {replies:?}");
    assert_eq!(replies.len(), 3, "every message answered");
    assert_eq!(replies[0]["id"], 7);
    assert!((replies[0]["ok"]["fov"].as_f64().unwrap() - 55.0 * DEG).abs() < 1e-3);
    assert_eq!(
        (replies[1]["id"].clone(), replies[1]["code"].clone()),
        (json!(8), json!(422))
    );
    assert_eq!(replies[2]["code"], 400);
    assert!((fov_of(&mut client, 2) - 55.0 * DEG).abs() < 1e-3);

    // A change over the binary protocol is pushed to the socket.
    client
        .set(Param::CamFov(CamFov {
            cam_id: 3,
            fov: 33.0 * DEG,
        }))
        .unwrap();
    let t = Instant::now();
    loop {
        assert!(
            t.elapsed() < Duration::from_millis(500),
            "not pushed within 0.5 s"
        );
        let Ok(Some(Ok(Message::Text(m)))) =
            tokio::time::timeout(Duration::from_millis(500), socket.next()).await
        else {
            continue;
        };
        let v: Value = serde_json::from_str(&m).unwrap();
        let fov = v["params"]["CAM_FOV"][3]["fov"].as_f64();
        if fov.is_some_and(|f| (f - 33.0 * DEG).abs() < 1e-3) {
            break;
        }
    }
    println!("pushed after {:?}", t.elapsed());
}

/// PUT with a `len`-byte body, written in pieces while the answer is read on another thread
/// (a server that answers early and closes resets the rest of the write): the status line.
fn put_large(host: &str, path: &str, len: usize) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut reader = s.try_clone().unwrap();
    let answer = std::thread::spawn(move || {
        let mut got = vec![0u8; 4096];
        let n = reader.read(&mut got).unwrap_or(0);
        String::from_utf8_lossy(&got[..n]).into_owned()
    });
    let head = format!(
        "PUT {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: {len}\r\nConnection: close\r\n\r\n"
    );
    let _ = s.write_all(head.as_bytes());
    let piece = vec![b'a'; 64 * 1024];
    for _ in 0..len / piece.len() {
        if s.write_all(&piece).is_err() {
            break;
        }
    }
    let text = answer.join().unwrap();
    text.lines().next().unwrap_or("").to_string()
}

#[test]
fn a_body_too_large_is_refused_as_too_large_and_changes_nothing() {
    let serve = Serve::start(&[]);
    let http = serve.http.clone().unwrap();
    let host = http.trim_start_matches("http://").trim_end_matches('/');
    let (_, before) = request(host, "GET", "/api/params/CAM_FOV?cam_id=0", None);
    let status = put_large(host, "/api/params/CAM_FOV", 10 << 20);
    assert!(status.contains(" 413 "), "{status:?}");
    let (_, after) = request(host, "GET", "/api/params/CAM_FOV?cam_id=0", None);
    assert_eq!(before, after);
}
