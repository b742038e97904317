//! The tuning page: plain HTML, CSS and JavaScript modules from `src/http/page/`, built into
//! the binary (nothing to install beside it, nothing fetched from the internet).

use super::{Web, text};
use axum::Router;
use axum::extract::Path;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

/// (name, content type, content)
const FILES: &[(&str, &str, &str)] = &[
    (
        "index.html",
        "text/html; charset=utf-8",
        include_str!("page/index.html"),
    ),
    (
        "style.css",
        "text/css; charset=utf-8",
        include_str!("page/style.css"),
    ),
    (
        "app.js",
        "text/javascript; charset=utf-8",
        include_str!("page/app.js"),
    ),
    (
        "api.js",
        "text/javascript; charset=utf-8",
        include_str!("page/api.js"),
    ),
    (
        "preview.js",
        "text/javascript; charset=utf-8",
        include_str!("page/preview.js"),
    ),
    (
        "mp4.js",
        "text/javascript; charset=utf-8",
        include_str!("page/mp4.js"),
    ),
    (
        "views.js",
        "text/javascript; charset=utf-8",
        include_str!("page/views.js"),
    ),
    (
        "controls.js",
        "text/javascript; charset=utf-8",
        include_str!("page/controls.js"),
    ),
];

pub(super) fn routes() -> Router<Web> {
    Router::new()
        .route("/", get(|| async { file("index.html") }))
        .route(
            "/page/{name}",
            get(|Path(name): Path<String>| async move { file(&name) }),
        )
}

fn file(name: &str) -> Response {
    match FILES.iter().find(|(n, ..)| *n == name) {
        Some((_, kind, body)) => (
            StatusCode::OK,
            [
                (header::CONTENT_TYPE, *kind),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            *body,
        )
            .into_response(),
        None => text(StatusCode::NOT_FOUND, format!("no page file {name:?}")),
    }
}
