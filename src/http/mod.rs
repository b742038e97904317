//! The head's one HTTP server (axum, on the tokio runtime the control server runs on), beside
//! the frame path like the control protocol: today it serves the MAVLink cameras' definition
//! file, which ground stations fetch by the URL in CAMERA_INFORMATION; the web page and its
//! API are to join it on the same port.

use crate::cameras::{Cameras, DEFINITION_PATH};
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use tokio::net::TcpListener;

/// `[http]` in the config.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct HttpConfig {
    /// `ADDR:PORT` (port 0 picks a free one), or `off`.
    pub listen: String,
}

impl Default for HttpConfig {
    fn default() -> Self {
        HttpConfig {
            listen: "0.0.0.0:8080".into(),
        }
    }
}

impl HttpConfig {
    /// Where to listen; None when off.
    pub fn address(&self) -> Result<Option<std::net::SocketAddr>, String> {
        if self.listen.eq_ignore_ascii_case("off") {
            return Ok(None);
        }
        self.listen
            .parse()
            .map(Some)
            .map_err(|_| format!("http listen {:?}: use ADDR:PORT or off", self.listen))
    }
}

/// What the handlers reach.
#[derive(Clone)]
struct Shared {
    cameras: Option<Arc<Cameras>>,
}

/// Serves on `listener` until `stop` resolves.
pub async fn serve(
    listener: TcpListener,
    cameras: Option<Arc<Cameras>>,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let app = Router::new()
        .route(DEFINITION_PATH, get(definition))
        .with_state(Shared { cameras });
    axum::serve(listener, app)
        .with_graceful_shutdown(stop)
        .await
}

/// The camera definition file (application/xml), or 404 with the cameras off.
async fn definition(State(shared): State<Shared>) -> impl IntoResponse {
    match &shared.cameras {
        Some(c) => (
            StatusCode::OK,
            [(header::CONTENT_TYPE, "application/xml")],
            c.definition().0,
        ),
        None => (
            StatusCode::NOT_FOUND,
            [(header::CONTENT_TYPE, "text/plain")],
            "the MAVLink cameras are off ([cameras] enabled = false)\n".to_string(),
        ),
    }
}
