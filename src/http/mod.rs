//! The head's one HTTP server (axum, on the tokio runtime the control server runs on), beside
//! the frame path like the control protocol. It serves the tuning page (`page`, built into
//! the binary) and the JSON API behind it (`api`: every parameter type read and set through
//! the same [`Controller`] as the binary protocol, so permissions and checks are the same),
//! the live state pushed over a WebSocket (`events`), the encoder's H.264 for the page's
//! preview (`preview`), the MAVLink cameras' definition file (which ground stations fetch by
//! the URL in CAMERA_INFORMATION) and the captures (`/captures/NAME`).
//!
//! A request whose `Host` is not one of this server's names is refused, the defence against
//! DNS rebinding (`names`). With the RTSP user and password set, everything but the
//! definition file asks for them (basic authentication). A request that changes something,
//! and every WebSocket, is refused when it comes from another site's page (its Origin is not
//! one of this server's names on its port).

mod api;
pub mod checks;
mod events;
mod names;
mod page;
mod preview;
pub mod thermal;

use crate::control::Controller;
use crate::stream::Preview;
use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use base64::Engine;
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use tokio::net::TcpListener;

/// Where the captures are served.
pub const CAPTURES_PATH: &str = "/captures/";
/// Where the MAVLink cameras' definition file is served.
pub const DEFINITION_PATH: &str = "/camera.xml";

/// `[http]` in the config.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct HttpConfig {
    /// `ADDR:PORT` (port 0 picks a free one), or `off`.
    pub listen: String,
    /// Names the server answers to besides its addresses, `localhost` and this machine's
    /// host name: the DNS names users type to reach it (a request naming any other host is
    /// refused, the defence against DNS rebinding).
    pub hosts: Vec<String>,
}

impl Default for HttpConfig {
    fn default() -> Self {
        HttpConfig {
            listen: "0.0.0.0:8080".into(),
            hosts: vec![],
        }
    }
}

/// An `[http] listen` that is neither an address nor `off`.
#[derive(Debug, thiserror::Error)]
#[error("http listen {0:?}: use ADDR:PORT or off")]
pub struct ListenError(String);

impl HttpConfig {
    /// Where to listen; None when off.
    pub fn address(&self) -> Result<Option<SocketAddr>, ListenError> {
        if self.listen.eq_ignore_ascii_case("off") {
            return Ok(None);
        }
        self.listen
            .parse()
            .map(Some)
            .map_err(|_| ListenError(self.listen.clone()))
    }
}

/// The video pipeline as the HTTP server sees it: its figures and the encoder's H.264.
pub trait Video: Send + Sync {
    /// The figures over the last second, as `/api/status` gives them under `video`.
    fn status(&self) -> serde_json::Value;
    /// The page's viewers of the stream.
    fn preview(&self) -> Arc<Preview>;
    /// Starts measuring the camera's readout over `seconds` of frames (docs/serve.md,
    /// "Measuring the readout").
    fn estimate_readout(&self, seconds: f64) -> Result<serde_json::Value, NotStarted>;
    /// Where the readout estimate stands, and its answer.
    fn readout_estimate(&self) -> serde_json::Value;
    /// What view `camera` shows of the thermal sensor (`/api/thermal`): its hottest and
    /// coldest point and, at view pixel `spot`, the temperature.
    fn thermal(
        &self,
        camera: usize,
        spot: Option<(f64, f64)>,
    ) -> Result<serde_json::Value, thermal::Refused>;
}

/// Why a readout estimate did not start.
pub enum NotStarted {
    /// A value out of range: what is wrong with it.
    Bad(String),
    /// One is running already.
    Busy(String),
}

/// What the handlers reach.
#[derive(Clone)]
pub struct Web {
    pub controller: Arc<Controller>,
    /// The MAVLink cameras' definition file (None with the cameras off).
    pub camera_definition: Option<Arc<dyn Fn() -> String + Send + Sync>>,
    /// The video pipeline (None with `--no-video`).
    pub video: Option<Arc<dyn Video>>,
    /// The capture directory (None without video).
    pub captures: Option<PathBuf>,
    /// `user:password` for basic authentication (the RTSP server's), or open.
    pub login: Option<(String, String)>,
    /// Names the server answers to besides its addresses, `localhost` and the host name.
    pub hosts: Vec<String>,
}

/// Serves on `listener` until `stop` resolves.
pub async fn serve(
    listener: TcpListener,
    web: Web,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let names = Arc::new(names::Names::new(&web.hosts, listener.local_addr()?.port()));
    let expected = web.login.as_ref().map(|(user, password)| {
        let token = base64::engine::general_purpose::STANDARD.encode(format!("{user}:{password}"));
        Arc::<str>::from(format!("Basic {token}"))
    });
    let guarded = Router::new()
        .merge(page::routes())
        .merge(api::routes())
        .route("/api/events", get(events::upgrade))
        .route("/api/preview", get(preview::upgrade))
        .route("/api/thermal", get(thermal::in_view))
        .route(&format!("{CAPTURES_PATH}{{name}}"), get(api::capture_file))
        .layer(axum::Extension(events::Feed::start(web.clone())))
        .layer(axum::middleware::from_fn_with_state(
            names.clone(),
            same_site,
        ))
        .layer(axum::middleware::from_fn_with_state(expected, logged_in));
    let app = Router::new()
        .route(DEFINITION_PATH, get(definition))
        .merge(guarded)
        .layer(axum::middleware::from_fn_with_state(names, known_host))
        .with_state(web);
    let fault = crate::supervise::Fault::for_service("http");
    let server = axum::serve(
        listener,
        app.into_make_service_with_connect_info::<SocketAddr>(),
    )
    .with_graceful_shutdown(stop);
    if !fault.pending() {
        return server.await;
    }
    // For the test of the supervisor: the server fails half a second in (DIGIVIEW_FAULT=http).
    tokio::select! {
        done = server.into_future() => done,
        _ = tokio::time::sleep_until(fault.when().into()) => {
            fault.check("http");
            Ok(())
        }
    }
}

/// An error response: `{"error": message}`, as every error of the server is (the JSON API's
/// and the rest alike), so a script reads each the same way.
fn text(status: StatusCode, message: impl Into<String>) -> Response {
    let message: String = message.into();
    (status, axum::Json(serde_json::json!({ "error": message }))).into_response()
}

/// Basic authentication, when a login is set.
async fn logged_in(
    State(expected): State<Option<Arc<str>>>,
    request: Request,
    next: Next,
) -> Response {
    let Some(expected) = expected else {
        return next.run(request).await;
    };
    // The scheme's name is case-insensitive (RFC 9110): "basic" is "Basic".
    let same = |given: &str| {
        let (scheme, token) = given.split_once(' ').unwrap_or((given, ""));
        let (want_scheme, want_token) = expected.split_once(' ').unwrap_or((&expected, ""));
        scheme.eq_ignore_ascii_case(want_scheme) && token.trim_start() == want_token
    };
    let given = request.headers().get(header::AUTHORIZATION);
    if given.and_then(|g| g.to_str().ok()).is_some_and(same) {
        return next.run(request).await;
    }
    let mut refused = text(
        StatusCode::UNAUTHORIZED,
        "log in with the RTSP user and password",
    );
    refused.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        header::HeaderValue::from_static("Basic realm=\"DigiView\", charset=\"UTF-8\""),
    );
    refused
}

/// Whether a request comes from this server's own page, or from no page (a script, `curl`):
/// an `Origin` that is not one of this server's names on its port is another site's page.
fn from_this_site(names: &names::Names, headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN) else {
        return true;
    };
    origin.to_str().is_ok_and(|o| names.knows_origin(o))
}

/// Refuses a request whose `Host` is not one of this server's names (DNS rebinding).
async fn known_host(
    State(names): State<Arc<names::Names>>,
    request: Request,
    next: Next,
) -> Response {
    let host = request.headers().get(header::HOST).map(|h| h.to_str());
    match host {
        // No Host at all (HTTP/1.0, a script): no browser page sends that.
        None => next.run(request).await,
        Some(Ok(h)) if names.knows_host(h) => next.run(request).await,
        Some(h) => text(
            StatusCode::FORBIDDEN,
            format!(
                "this server does not answer to the name {:?}: add it to [http] hosts to \
                 reach it by that name",
                h.unwrap_or("?")
            ),
        ),
    }
}

/// Refuses what changes something (every method but GET and HEAD, and every WebSocket) from
/// another site's page.
async fn same_site(
    State(names): State<Arc<names::Names>>,
    request: Request,
    next: Next,
) -> Response {
    let reads = matches!(*request.method(), Method::GET | Method::HEAD);
    let upgrade = request.headers().contains_key(header::UPGRADE);
    if (!reads || upgrade) && !from_this_site(&names, request.headers()) {
        return text(
            StatusCode::FORBIDDEN,
            "another site's page may not change this video head",
        );
    }
    next.run(request).await
}

/// The camera definition file (application/xml), or 404 with the cameras off.
async fn definition(State(web): State<Web>) -> Response {
    match &web.camera_definition {
        Some(definition) => (
            StatusCode::OK,
            [(header::CONTENT_TYPE, "application/xml")],
            definition(),
        )
            .into_response(),
        None => text(
            StatusCode::NOT_FOUND,
            "the MAVLink cameras are off ([cameras] enabled = false)",
        ),
    }
}
