//! `/api/events`: a WebSocket that pushes the live state as it changes, whoever changed it
//! (the binary protocol, MAVLink, another page), and takes SETs.
//!
//! Server to client, JSON text: `{"params": {...}}` (every parameter, as `GET /api/params`)
//! at once and whenever a value changes (looked at every 100 ms, once for all sockets), and `{"status": {...}}`
//! (as `GET /api/status`) every second. Client to server: `{"id": 7, "set": "CAM_FOV",
//! "fields": {"cam_id": 1, "fov": "60deg"}}`, answered `{"id": 7, "ok": {...}}` or `{"id":
//! 7, "error": "...", "code": 422}` with the same checks and permissions as `PUT`. A client
//! that sends more than [`MAX_PER_SECOND`] frames of any kind in a second, or one frame over
//! [`MAX_MESSAGE`] bytes, is disconnected.

use super::Web;
use super::api::{set_json, snapshot, status_value};
use axum::Extension;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::response::Response;
use serde_json::{Value, json};
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{Notify, watch};

/// How often the state is compared with what was last pushed.
const LOOK_EVERY: Duration = Duration::from_millis(100);
/// Messages a client may send per second before the socket is closed (a flood).
const MAX_PER_SECOND: u32 = 200;
/// The largest message a client may send: a SET is a few hundred bytes.
const MAX_MESSAGE: usize = 16 * 1024;

/// The parameters every event socket pushes, built once per look for all of them (and only
/// while one is open): the `{"params": ...}` message, ready to send.
pub(super) struct Feed {
    params: watch::Sender<Arc<str>>,
    /// A SET was answered: look now rather than at the next tick.
    look_now: Notify,
}

impl Feed {
    /// Looks at the state every [`LOOK_EVERY`] while a socket is open, and publishes a new
    /// message when any value changed. The task ends with the feed: a server restarted after
    /// a failure starts a feed of its own and leaves no task behind.
    pub(super) fn start(web: Web) -> Arc<Feed> {
        let feed = Arc::new(Feed {
            params: watch::channel(Arc::from("")).0,
            look_now: Notify::new(),
        });
        let weak = Arc::downgrade(&feed);
        tokio::spawn(async move {
            let mut last: Option<Value> = None;
            let mut look = tokio::time::interval(LOOK_EVERY);
            look.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            while let Some(looking) = weak.upgrade() {
                tokio::select! {
                    _ = look.tick() => {}
                    _ = looking.look_now.notified() => {}
                }
                if looking.params.receiver_count() == 0 {
                    // Nobody watches: the next socket starts from a fresh look.
                    last = None;
                    continue;
                }
                let web = web.clone();
                let Ok(now) = tokio::task::spawn_blocking(move || snapshot(&web)).await else {
                    continue;
                };
                if last.as_ref() != Some(&now) {
                    let message = json!({ "params": now }).to_string();
                    looking.params.send_replace(Arc::from(message));
                    last = Some(now);
                }
            }
        });
        feed
    }
}

pub(super) async fn upgrade(
    ws: WebSocketUpgrade,
    State(web): State<Web>,
    Extension(feed): Extension<Arc<Feed>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
) -> Response {
    ws.max_message_size(MAX_MESSAGE)
        .max_frame_size(MAX_MESSAGE)
        .on_upgrade(move |socket| events(socket, web, feed, peer.ip()))
}

async fn events(mut socket: WebSocket, web: Web, feed: Arc<Feed>, peer: IpAddr) {
    // Every socket starts with the whole state, from its own look.
    let mut params = feed.params.subscribe();
    let first = {
        let web = web.clone();
        tokio::task::spawn_blocking(move || snapshot(&web)).await
    };
    let Ok(first) = first else { return };
    let first = json!({ "params": first }).to_string();
    if socket.send(Message::Text(first.into())).await.is_err() {
        return;
    }
    params.mark_unchanged();
    let mut status = tokio::time::interval(Duration::from_secs(1));
    let mut received = 0u32;
    loop {
        tokio::select! {
            _ = status.tick() => {
                received = 0;
                let status = json!({ "status": status_value(&web) });
                if socket.send(Message::Text(status.to_string().into())).await.is_err() {
                    return;
                }
            }
            changed = params.changed() => {
                if changed.is_err() {
                    return;
                }
                let message = params.borrow_and_update().clone();
                if socket.send(Message::Text(message.as_ref().into())).await.is_err() {
                    return;
                }
            }
            message = socket.recv() => {
                // Every frame counts against the limit, whatever its type; only text is
                // answered. A frame over the size limit is an error: the socket closes.
                let text = match message {
                    Some(Ok(Message::Text(t))) => Some(t),
                    Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                    Some(Ok(_)) => None,
                };
                received += 1;
                if received > MAX_PER_SECOND {
                    tracing::info!("http: closing {peer}'s event socket: over {MAX_PER_SECOND} messages a second");
                    return;
                }
                let Some(text) = text else { continue };
                let reply = answer(&web, peer, &text);
                if socket.send(Message::Text(reply.to_string().into())).await.is_err() {
                    return;
                }
                // The change shows at once, on every page, not at the next look.
                feed.look_now.notify_one();
            }
        }
    }
}

/// The reply to one client message.
fn answer(web: &Web, peer: IpAddr, text: &str) -> Value {
    let message: Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return json!({ "error": format!("not JSON: {e}"), "code": 400 }),
    };
    let id = message.get("id").cloned().unwrap_or(Value::Null);
    let Some(name) = message.get("set").and_then(Value::as_str) else {
        let error = "a message is {\"id\": N, \"set\": \"PARAM\", \"fields\": {...}}";
        return json!({ "id": id, "error": error, "code": 400 });
    };
    let fields = message.get("fields").cloned().unwrap_or_else(|| json!({}));
    match set_json(web, peer, name, &fields) {
        Ok(v) => json!({ "id": id, "ok": v }),
        Err(e) => json!({ "id": id, "error": e.1, "code": e.0.as_u16() }),
    }
}
