//! The head's one HTTP server (axum, on the tokio runtime the control server runs on), beside
//! the frame path like the control protocol: today it serves the MAVLink cameras' definition
//! file, which ground stations fetch by the URL in CAMERA_INFORMATION, and the cameras' stills
//! (`/captures/NAME`, the URL in CAMERA_IMAGE_CAPTURED); the web page and its API are to join
//! it on the same port.

use crate::cameras::{Cameras, DEFINITION_PATH};
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;
use tokio::net::TcpListener;

/// Where the stills are served.
pub const CAPTURES_PATH: &str = "/captures/";

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
    /// The capture directory (None without video).
    captures: Option<PathBuf>,
}

/// Serves on `listener` until `stop` resolves.
pub async fn serve(
    listener: TcpListener,
    cameras: Option<Arc<Cameras>>,
    captures: Option<PathBuf>,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let app = Router::new()
        .route(DEFINITION_PATH, get(definition))
        .route(&format!("{CAPTURES_PATH}{{name}}"), get(still))
        .with_state(Shared { cameras, captures });
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

/// A still DigiView wrote (`digiview-*.jpg` or `.png` in the capture directory, nothing
/// else: no other name, no path), or 404.
async fn still(
    State(shared): State<Shared>,
    axum::extract::Path(name): axum::extract::Path<String>,
) -> impl IntoResponse {
    let kind = match name.rsplit_once('.').map(|(_, ext)| ext) {
        Some("jpg") => Some("image/jpeg"),
        Some("png") => Some("image/png"),
        _ => None,
    };
    let ours = name.starts_with("digiview-") && !name.contains(['/', '\\']);
    let found = match (&shared.captures, kind) {
        (Some(dir), Some(kind)) if ours => tokio::fs::read(dir.join(&name))
            .await
            .ok()
            .map(|bytes| (kind, bytes)),
        _ => None,
    };
    match found {
        Some((kind, bytes)) => (StatusCode::OK, [(header::CONTENT_TYPE, kind)], bytes),
        None => (
            StatusCode::NOT_FOUND,
            [(header::CONTENT_TYPE, "text/plain")],
            format!("no still {name:?}\n").into_bytes(),
        ),
    }
}
