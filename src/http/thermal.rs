//! The thermal sensor over the JSON API: `GET /api/thermal?camera=N` gives the hottest and
//! coldest point of what view N shows of the newest thermal frame, in the view's own pixels
//! (its stream's and stills' size), and `&x=X&y=Y` adds the temperature at that pixel
//! (docs/web.md).

use super::Web;
use super::api::ApiError;
use axum::Json;
use axum::extract::{Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use std::collections::HashMap;

/// Why a thermal reading was refused: no sensor (404), no frame yet (503), or a bad request
/// (400), each with its words.
pub enum Refused {
    NoSensor(String),
    NoFrame(String),
    Bad(String),
}

pub(super) async fn in_view(
    State(web): State<Web>,
    Query(query): Query<HashMap<String, String>>,
) -> Response {
    let Some(video) = &web.video else {
        return ApiError(StatusCode::NOT_FOUND, "no video (--no-video)".into()).into_response();
    };
    let number = |key: &str| query.get(key).map(|v| v.trim().parse::<f64>());
    let camera = match query.get("camera").map(|v| v.trim().parse::<usize>()) {
        None => 0,
        Some(Ok(c)) => c,
        Some(Err(_)) => return bad("camera: give a view's number, 0 to 3"),
    };
    let spot = match (number("x"), number("y")) {
        (None, None) => None,
        (Some(Ok(x)), Some(Ok(y))) if x.is_finite() && y.is_finite() => Some((x, y)),
        _ => {
            return bad("x, y: give both, as pixels of the view's picture (0.5, 0.5 is the first)");
        }
    };
    match video.thermal(camera, spot) {
        Ok(v) => Json(v).into_response(),
        Err(Refused::NoSensor(e)) => ApiError(StatusCode::NOT_FOUND, e).into_response(),
        Err(Refused::NoFrame(e)) => ApiError(StatusCode::SERVICE_UNAVAILABLE, e).into_response(),
        Err(Refused::Bad(e)) => bad(&e),
    }
}

fn bad(message: &str) -> Response {
    ApiError(StatusCode::BAD_REQUEST, message.into()).into_response()
}
