//! The page's thermal settings in headless Chromium: with a thermal sensor (`serve --thermal
//! demo`) the "Thermal" panel and each camera's "thermal" display show, and what is picked
//! there is what the DigiView protocol then reads (the one live state); without a sensor
//! neither shows.

use crate::common;
use crate::web::page_with_state;
use common::serve::Serve;
use serde_json::{Value, json};
use std::time::Duration;

/// THERMAL's or CAM_THERMAL's values as `digiview ctl` reads them.
fn read(serve: &Serve, args: &[&str]) -> Value {
    let out = common::ctl(
        &serve.addr.to_string(),
        &[&["--json", "get"][..], args].concat(),
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v["values"].clone()
}

/// Picks `value` in the select `id`, as a user does.
fn pick(id: &str, value: u32) -> String {
    format!(
        "const el = document.getElementById('{id}'); el.value = '{value}';
         el.dispatchEvent(new Event('change')); return true;"
    )
}

/// Whether the page shows the thermal panel and camera 0's thermal display, once it has the
/// head's status.
const SHOWN: &str = "const s = document.getElementById('status').textContent;
    if (s.startsWith('connecting')) return null;
    return [!document.getElementById('thermal-panel').hidden,
            !document.getElementById('camera-CAM_THERMAL-show').hidden]";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_thermal_panel_shows_with_a_sensor_and_what_is_picked_there_is_set() {
    let serve = Serve::start_video(&["--thermal", "demo"]);
    let b = page_with_state(&serve.http.clone().unwrap()).await;
    let shown = b
        .until("the page has the status", Duration::from_secs(10), SHOWN)
        .await;
    assert_eq!(shown, json!([true, true]));
    b.js(&pick("thermal-palette", 2), vec![]).await;
    b.until(
        "the page holds ironbow",
        Duration::from_secs(5),
        "return window.digiview.api.params.THERMAL.palette === 2 || null",
    )
    .await;
    assert_eq!(read(&serve, &["thermal"])["palette"], 2);
    b.js(&pick("camera-CAM_THERMAL-show", 3), vec![]).await;
    b.until(
        "the page holds camera 0 showing the thermal picture",
        Duration::from_secs(5),
        "return window.digiview.api.params.CAM_THERMAL[0].show === 3 || null",
    )
    .await;
    assert_eq!(read(&serve, &["cam_thermal", "cam=0"])["show"], 3);
    b.close().await;

    // Without a sensor neither shows.
    let bare = Serve::start(&[]);
    let b = page_with_state(&bare.http.clone().unwrap()).await;
    let shown = b
        .until("the page has the status", Duration::from_secs(10), SHOWN)
        .await;
    assert_eq!(shown, json!([false, false]));
    b.close().await;
}
