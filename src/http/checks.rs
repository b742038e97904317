//! The web API's parameter writes on arbitrary bodies, for the fuzz target (`fuzz/`) and the
//! test that replays its corpus: the first byte picks the parameter type, the rest is the
//! body. Every body is taken or refused with an error in words, never a panic, and the live
//! state stays valid.

use super::Web;
use super::api::set_json;
use crate::control::Controller;
use crate::protocol::ParamType;
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;

/// PUT `/api/params/NAME` with the body `data[1..]`, NAME chosen by `data[0]`.
pub fn put_body(controller: &Arc<Controller>, data: &[u8]) {
    let Some((pick, body)) = data.split_first() else {
        return;
    };
    let kind = ParamType::ALL[usize::from(*pick) % ParamType::ALL.len()];
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(body) else {
        return;
    };
    let web = Web {
        controller: controller.clone(),
        camera_definition: None,
        video: None,
        captures: None,
        login: None,
        hosts: vec![],
    };
    if let Err(e) = set_json(&web, IpAddr::V4(Ipv4Addr::LOCALHOST), kind.name(), &value) {
        assert!(!e.1.is_empty(), "a refusal says why");
    }
    let settings = controller.gate.settings();
    settings
        .snapshot()
        .validate(settings.lenses())
        .expect("the settings stay valid");
}
