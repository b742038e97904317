//! The JSON API: every parameter type of the control protocol read (`GET /api/params`,
//! `GET /api/params/NAME?cam_id=1`) and set (`PUT /api/params/NAME` with the fields to
//! change) through the same controller as the binary protocol, the head's figures
//! (`/api/status`), the lenses, and the captures listed and downloaded. docs/web.md shows
//! each with an example.

use super::{Web, text};
use crate::control::Refusal;
use crate::protocol::edit::{self, Given};
use crate::protocol::{Param, ParamType};
use axum::Json;
use axum::Router;
use axum::extract::rejection::JsonRejection;
use axum::extract::{ConnectInfo, Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Map, Value, json};
use std::collections::HashMap;
use std::net::SocketAddr;

pub(super) fn routes() -> Router<Web> {
    Router::new()
        .route("/api/params", get(all_params))
        .route("/api/params/{name}", get(get_param).put(put_param))
        .route("/api/status", get(status))
        .route("/api/lenses", get(lenses))
        .route("/api/captures", get(captures))
        .route(
            "/api/readout/estimate",
            get(readout_estimate).post(estimate_readout),
        )
}

/// Where the readout estimate stands (`state`: idle, collecting, fitting, done, failed) and,
/// once done, its `fit`.
async fn readout_estimate(State(web): State<Web>) -> Response {
    match &web.video {
        Some(v) => Json(v.readout_estimate()).into_response(),
        None => ApiError(StatusCode::NOT_FOUND, "no video (--no-video)".into()).into_response(),
    }
}

/// Starts measuring the camera's readout over `?seconds=` (default 10) of frames while the
/// vehicle turns: a change (it loads the head), asked of the one policy as a SET is.
async fn estimate_readout(
    State(web): State<Web>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    Query(query): Query<HashMap<String, String>>,
) -> Response {
    use crate::policy::{Act, Peer};
    let gate = &web.controller.gate;
    if let Err(e) = gate.permit(Peer::Net(peer.ip()), Act::Change, "readout estimate") {
        return ApiError(StatusCode::FORBIDDEN, e.0.into()).into_response();
    }
    let Some(video) = &web.video else {
        return ApiError(StatusCode::NOT_FOUND, "no video (--no-video)".into()).into_response();
    };
    let seconds = match query.get("seconds").map(|s| s.parse::<f64>()) {
        None => 10.0,
        Some(Ok(s)) => s,
        Some(Err(_)) => {
            let message = "seconds: give a number of seconds".to_string();
            return ApiError(StatusCode::BAD_REQUEST, message).into_response();
        }
    };
    match video.estimate_readout(seconds) {
        Ok(status) => (StatusCode::ACCEPTED, Json(status)).into_response(),
        Err(super::NotStarted::Bad(e)) => ApiError(StatusCode::BAD_REQUEST, e).into_response(),
        Err(super::NotStarted::Busy(e)) => ApiError(StatusCode::CONFLICT, e).into_response(),
    }
}

fn kind_of(name: &str) -> Result<ParamType, ApiError> {
    ParamType::parse(name).ok_or_else(|| {
        let names: Vec<_> = ParamType::ALL.iter().map(|p| p.name()).collect();
        let message = format!(
            "`{name}` is not a parameter type; one of: {}",
            names.join(", ")
        );
        ApiError(StatusCode::NOT_FOUND, message)
    })
}

/// A parameter from named fields over `p`.
fn build<'a>(
    mut p: Param,
    fields: impl IntoIterator<Item = (&'a str, Given<'a>)>,
) -> Result<Param, ApiError> {
    for (key, value) in fields {
        edit::set(&mut p, key, value).map_err(|e| ApiError(StatusCode::BAD_REQUEST, e.0))?;
    }
    Ok(p)
}

/// Every parameter's value as a GET answers it: per-camera types as a list of four (CAM_TARGET
/// null for a camera without a target), the tracked objects as a list, each with where the
/// views show it (`views`).
pub(crate) fn snapshot(web: &Web) -> Value {
    let c = &web.controller;
    let mut out = Map::new();
    let one = |p: Param| c.get(&p).ok().and_then(|v| v.into_iter().next());
    for &kind in ParamType::ALL {
        let value = match kind {
            // Asked of a pixel, per request; the link's counters are in the status.
            ParamType::RefusalReason | ParamType::CamOffset | ParamType::Autopilot => continue,
            ParamType::DetectedRoi => objects(web),
            k if k.per_camera() => Value::Array(
                (0..crate::state::MAX_CAMERAS)
                    .map(|cam| {
                        let mut q = k.zeroed();
                        let _ = q.set_field("cam_id", cam as f64);
                        json!(one(q))
                    })
                    .collect(),
            ),
            k => json!(one(k.zeroed())),
        };
        out.insert(kind.name().to_string(), value);
    }
    Value::Object(out)
}

/// DETECTED_ROI 255's replies, each known object's with its `id`, its `label` (what it is:
/// "moving", a model's class; the binary reply has no room for it), `views`: the views
/// showing it, with its centre, radius and velocity in output pixels (what the page draws
/// over the picture), and `pts_us`: the presentation time, in the composed stream, of the
/// frame they are placed on (the page moves each ring on from it to the frame it shows).
/// All from one snapshot of the state.
fn objects(web: &Web) -> Value {
    let c = &web.controller;
    let state = c.state();
    let replies = crate::control::detection::detected_roi(&state, 255).unwrap_or_default();
    let frame = c.report.rendered();
    let lenses = c.gate.settings().lenses();
    let seen = crate::control::detection::seen(lenses, &state, frame.as_ref());
    let pts_us = frame.map(|f| f.pts_us);
    let mut list: Vec<Value> = replies.iter().map(|p| json!(p)).collect();
    for ((object, views), tracked) in list.iter_mut().zip(seen).zip(&state.tracked) {
        object["views"] = json!(views);
        object["id"] = json!(tracked.id);
        object["label"] = json!(tracked.label);
        object["pts_us"] = json!(pts_us);
    }
    Value::Array(list)
}

async fn all_params(State(web): State<Web>) -> Response {
    Json(snapshot(&web)).into_response()
}

/// One GET; the query string gives the request's fields (`cam_id`, `index`, `x`, `y`).
async fn get_param(
    State(web): State<Web>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    Path(name): Path<String>,
    Query(fields): Query<HashMap<String, String>>,
) -> Response {
    let answer = || -> Result<Value, ApiError> {
        let kind = kind_of(&name)?;
        let given = fields.iter().map(|(k, v)| (k.as_str(), Given::Text(v)));
        let query = build(kind.zeroed(), given)?;
        let mut params = web.controller.get_from(&query, peer.ip())?;
        Ok(match (kind, params.len()) {
            (ParamType::DetectedRoi, _) => json!(params),
            (_, 1) => json!(params.remove(0)),
            _ => json!(params),
        })
    };
    match answer() {
        Ok(v) => Json(v).into_response(),
        Err(e) => e.into_response(),
    }
}

/// A request the API refused: its status and why.
pub(crate) struct ApiError(pub StatusCode, pub String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, Json(json!({ "error": self.1 }))).into_response()
    }
}

impl From<Refusal> for ApiError {
    fn from(r: Refusal) -> ApiError {
        let status = match r {
            Refusal::Forbidden(_) => StatusCode::FORBIDDEN,
            Refusal::Data(_) => StatusCode::UNPROCESSABLE_ENTITY,
        };
        ApiError(status, r.to_string())
    }
}

/// One SET from a JSON object of fields (numbers, or angles as `"30deg"`). Types whose
/// fields are all settings start from the current values, so fields left out keep them (as
/// `digiview ctl set` does); the answer is the type's value after the SET.
pub(crate) fn set_json(
    web: &Web,
    peer: std::net::IpAddr,
    name: &str,
    body: &Value,
) -> Result<Value, ApiError> {
    let kind = kind_of(name)?;
    let bad = |m: String| ApiError(StatusCode::BAD_REQUEST, m);
    let fields = body
        .as_object()
        .ok_or_else(|| bad("the body is a JSON object of fields".into()))?;
    let mut given = Vec::new();
    for (key, value) in fields {
        let value = match value {
            Value::Number(n) => Given::Number(n.as_f64().unwrap_or(f64::NAN)),
            Value::String(s) => Given::Text(s),
            Value::Bool(b) => Given::Number(*b as u8 as f64),
            other => return Err(bad(format!("{key}: {other} is not a number or an angle"))),
        };
        given.push((key.as_str(), value));
    }
    let is_delta = fields
        .get("is_delta")
        .is_some_and(|v| v.as_f64().is_some_and(|d| d != 0.0) || v == &Value::Bool(true));
    // A SET that starts from zeros sets every field it reads: one given nothing (`{}`), or a
    // camera's without the camera, would set zeros nobody asked for.
    let reads_first = edit::reads_first(kind, is_delta);
    let named: Vec<&str> = kind.fields().iter().map(|f| f.name).collect();
    if kind.per_camera() && !fields.contains_key("cam_id") {
        return Err(bad(format!(
            "{kind} needs cam_id; its fields: {}",
            named.join(", ")
        )));
    }
    if !reads_first && fields.keys().all(|k| k == "cam_id") {
        return Err(bad(format!(
            "{kind}: give the fields to set: {}",
            named.join(", ")
        )));
    }
    let mut base = kind.zeroed();
    if reads_first {
        // The camera first, then that camera's current values.
        if let Some(cam) = fields.get("cam_id").and_then(Value::as_f64) {
            edit::set(&mut base, "cam_id", Given::Number(cam)).map_err(|e| bad(e.0))?;
        }
        if let Some(now) = web.controller.get_from(&base, peer)?.into_iter().next() {
            base = now;
        }
    }
    let param = build(base, given)?;
    web.controller.set_from(&param, peer)?;
    let mut query = kind.zeroed();
    if let Some(cam) = param.cam_id() {
        let _ = query.set_field("cam_id", cam as f64);
    }
    let now = web.controller.get(&query).ok().and_then(|mut v| v.pop());
    let Some(now) = now.filter(|_| !matches!(kind, ParamType::CamOffset | ParamType::CamTarget))
    else {
        return Ok(json!({ "result": "set" }));
    };
    let mut reply = json!(now);
    // What the protocol's rules changed (clamped, wrapped, ignored), said rather than hidden.
    let (asked, set) = (json!(param), reply.clone());
    let clamped: Map<String, Value> = fields
        .keys()
        .filter(|k| !is_delta && !matches!(k.as_str(), "cam_id" | "is_delta"))
        .filter_map(|k| {
            let (a, s) = (asked.get(k)?.as_f64()?, set.get(k)?.as_f64()?);
            let differs = (a - s).abs() > 1e-6 * a.abs().max(1.0);
            differs.then(|| (k.clone(), json!({ "asked": a, "set": s })))
        })
        .collect();
    if !clamped.is_empty()
        && let Some(object) = reply.as_object_mut()
    {
        object.insert("clamped".into(), Value::Object(clamped));
    }
    Ok(reply)
}

async fn put_param(
    State(web): State<Web>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    Path(name): Path<String>,
    body: Result<Json<Value>, JsonRejection>,
) -> Response {
    let body = match body {
        Ok(Json(body)) => body,
        Err(JsonRejection::MissingJsonContentType(_)) => {
            let message = "the body is a JSON object of fields (Content-Type: application/json)";
            return ApiError(StatusCode::BAD_REQUEST, message.into()).into_response();
        }
        Err(e) if e.status() == StatusCode::PAYLOAD_TOO_LARGE => {
            let message = "the body is too large: a parameter's fields are a small JSON object";
            return ApiError(StatusCode::PAYLOAD_TOO_LARGE, message.into()).into_response();
        }
        Err(e) => {
            let message = format!("the body is not JSON: {}", e.body_text());
            return ApiError(StatusCode::BAD_REQUEST, message).into_response();
        }
    };
    match set_json(&web, peer.ip(), &name, &body) {
        Ok(v) => Json(v).into_response(),
        Err(e) => e.into_response(),
    }
}

/// The run's status, the head's figures over the last second, and the autopilot link.
pub(crate) fn status_value(web: &Web) -> Value {
    let s = &web.controller.report;
    json!({
        "status": s.status() as u8,
        "failure": s.failure(),
        "capture": s.capture_failure(),
        "video": web.video.as_ref().map(|v| v.status()),
        "autopilot": web.controller.autopilot.as_ref().map(|a| a.param()),
        "services": s.services.failures(),
        "version": env!("CARGO_PKG_VERSION"),
    })
}

async fn status(State(web): State<Web>) -> Response {
    Json(status_value(&web)).into_response()
}

async fn lenses(State(web): State<Web>) -> Response {
    let names = web.controller.gate.settings().lenses().names();
    let list: Vec<_> = names
        .into_iter()
        .map(|(id, name)| json!({ "lens_id": id, "name": name }))
        .collect();
    Json(list).into_response()
}

/// What a capture file is, by its name: DigiView's own files only (`digiview-*`).
fn capture_kind(name: &str) -> Option<&'static str> {
    if !name.starts_with("digiview-") || name.contains(['/', '\\']) {
        return None;
    }
    match name.rsplit_once('.').map(|(_, ext)| ext) {
        Some("jpg") => Some("image/jpeg"),
        Some("png") => Some("image/png"),
        Some("mp4") => Some("video/mp4"),
        Some("ts") => Some("video/mp2t"),
        _ => None,
    }
}

/// The captures, newest first: name, kind, bytes and when written (Unix seconds).
async fn captures(State(web): State<Web>) -> Response {
    let Some(dir) = web.captures.clone() else {
        return Json(json!([])).into_response();
    };
    let mut list = Vec::new();
    if let Ok(mut entries) = tokio::fs::read_dir(&dir).await {
        while let Ok(Some(e)) = entries.next_entry().await {
            let name = e.file_name().to_string_lossy().to_string();
            let (Some(kind), Ok(meta)) = (capture_kind(&name), e.metadata().await) else {
                continue;
            };
            let modified = meta
                .modified()
                .ok()
                .and_then(|m| m.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_secs());
            list.push(json!({
                "name": name, "type": kind, "bytes": meta.len(), "modified": modified,
                "url": format!("{}{name}", super::CAPTURES_PATH),
            }));
        }
    }
    list.sort_by(|a, b| b["name"].as_str().cmp(&a["name"].as_str()));
    Json(list).into_response()
}

/// A still or recording DigiView wrote (nothing else: no other name, no path), streamed from
/// disk, or 404.
pub(super) async fn capture_file(State(web): State<Web>, Path(name): Path<String>) -> Response {
    let file = match (&web.captures, capture_kind(&name)) {
        (Some(dir), Some(kind)) => tokio::fs::File::open(dir.join(&name))
            .await
            .ok()
            .map(|f| (kind, f)),
        _ => None,
    };
    match file {
        Some((kind, file)) => {
            let length = file.metadata().await.map(|m| m.len()).ok();
            let body = axum::body::Body::from_stream(tokio_util::io::ReaderStream::new(file));
            let mut response =
                (StatusCode::OK, [(header::CONTENT_TYPE, kind)], body).into_response();
            if let Some(n) = length {
                response
                    .headers_mut()
                    .insert(header::CONTENT_LENGTH, n.into());
            }
            response
        }
        None => text(StatusCode::NOT_FOUND, format!("no capture {name:?}")),
    }
}
