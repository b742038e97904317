//! `/api/preview`: the stream's H.264 for the page, over a WebSocket, decoded in the browser
//! with WebCodecs. Each binary message is one access unit: a byte of flags (bit 0: key frame),
//! the presentation time in µs (u64, little-endian), then the Annex B bytes (SPS and PPS lead
//! each key frame). The first unit is a key frame; a viewer that falls behind skips to the
//! next one (stream::preview), so it never slows the stream or other viewers. A page whose
//! decoder falls behind sends the text message `key` to have the next one come sooner.

use super::{Web, text};
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};

pub(super) async fn upgrade(ws: WebSocketUpgrade, State(web): State<Web>) -> Response {
    let Some(video) = web.video.clone() else {
        return text(
            StatusCode::NOT_FOUND,
            "no video: serve runs with --no-video",
        );
    };
    let viewer = video.preview().watch();
    ws.on_upgrade(move |socket| send_units(socket, viewer))
        .into_response()
}

async fn send_units(mut socket: WebSocket, mut viewer: crate::stream::preview::Viewer) {
    loop {
        tokio::select! {
            unit = viewer.next() => {
                let Some(unit) = unit else { return };
                let mut bytes = Vec::with_capacity(9 + unit.data.len());
                bytes.push(unit.key as u8);
                bytes.extend_from_slice(&unit.pts_us.to_le_bytes());
                bytes.extend_from_slice(&unit.data);
                if socket.send(Message::Binary(bytes.into())).await.is_err() {
                    return;
                }
            }
            // The page says only "key" on this socket (it fell behind and skips to the next
            // key frame); a close (or a dead peer) ends it.
            message = socket.recv() => match message {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => return,
                Some(Ok(Message::Text(t))) if t.as_str() == "key" => viewer.ask_key(),
                Some(Ok(_)) => {}
            },
        }
    }
}
