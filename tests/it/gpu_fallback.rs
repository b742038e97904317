//! An adapter that draws wrong is passed over (issue 58): with the first adapter made to draw
//! black (`DIGIVIEW_FAULT=black-adapter`: every frame it reads back is zeros, as the Raspberry
//! Pi 5's Vulkan driver gave a peer), `serve` starts on the next one (Mesa's llvmpipe through
//! GL here) within 5 s of being started, `/api/status` names it and says why, FFmpeg decodes
//! the offline render of the same still from its stream, and `doctor` says the same.

use crate::common;
use crate::doctor::{doctor, good_config};
use crate::players::{SIZE, complaints, pull, still_and_render};

use common::gcs::http_get;
use common::serve::Serve;
use digiview::image_ops;
use digiview::layout::Rect;
use serde_json::Value;
use std::time::{Duration, Instant};

/// The renderer's adapter as `/api/status` gives it, once the head has one.
fn gpu_in_status(http: &str) -> Option<Value> {
    let (code, body) = http_get(&format!("{http}api/status"));
    assert_eq!(code, 200);
    let status: Value = serde_json::from_slice(&body).unwrap();
    let gpu = &status["video"]["gpu"];
    let rendering = status["video"]["fps_out"].as_f64().unwrap_or(0.0) > 0.0;
    (gpu.is_object() && rendering).then(|| gpu.clone())
}

/// `serve` of `source` with `env`, and how long from its start until `/api/status` says it
/// renders, and on which adapter.
fn started(env: &[(&str, &str)], source: &str) -> (Serve, Duration, Value) {
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    let started = Instant::now();
    let serve = Serve::start_video_env(env, &["--source", source, "--size", &size]);
    let http = serve.http.clone().unwrap();
    loop {
        if let Some(gpu) = gpu_in_status(&http) {
            return (serve, started.elapsed(), gpu);
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no GPU in the status"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn a_first_adapter_that_draws_black_is_passed_over_within_5_s_and_the_stream_is_right() {
    let dir = tempfile::tempdir().unwrap();
    let (source, want) = still_and_render(dir.path());
    // Mesa's shader cache of this test alone: the first start on a board compiles the
    // renderer's shaders into it (on llvmpipe, 15 s or more for either backend, with a
    // fallback or without), and every start after reads them. The bound is a start's after
    // the first; the first is said.
    let cache = dir.path().join("mesa-cache");
    let env = [
        ("DIGIVIEW_FAULT", "black-adapter"),
        ("MESA_SHADER_CACHE_DIR", cache.to_str().unwrap()),
    ];
    let (mut first, took, _) = started(&env, &source);
    eprintln!("the first start, shaders compiled: rendering after {took:?}");
    // Stopped as an operator stops it, so Mesa's cache thread has written what it compiled.
    first.terminate();
    first
        .wait_exit(Duration::from_secs(10))
        .expect("serve stops on SIGTERM");
    let (serve, took, gpu) = started(&env, &source);
    eprintln!("rendering on {gpu} after {took:?}");
    assert_eq!(gpu["backend"], "gl", "{gpu}");
    let why = gpu["why"].as_str().unwrap();
    assert!(
        why.contains("in place of") && why.contains("Vulkan"),
        "{why}"
    );
    assert!(why.contains("drew a known frame wrong"), "{why}");
    assert!(took <= Duration::from_secs(5), "rendering after {took:?}");

    let got = pull(serve.rtsp.clone().unwrap(), "tcp").join().unwrap();
    let bad = complaints(&got.log);
    assert!(bad.is_empty(), "FFmpeg reports {bad:#?}");
    let whole = Rect::new(0, 0, SIZE.0, SIZE.1);
    let psnr = image_ops::psnr(&got.last, &want, whole);
    eprintln!("the stream on GL: {psnr:.1} dB against the offline render");
    assert!(
        psnr >= 30.0,
        "the stream on GL is {psnr:.1} dB from the offline render"
    );
}

#[test]
fn doctor_names_the_adapter_that_renders_and_the_one_passed_over() {
    let dir = tempfile::tempdir().unwrap();
    let config = good_config(dir.path(), "off");
    let fault = [("DIGIVIEW_FAULT", "black-adapter")];
    let (_, lines) = doctor(dir.path(), &config, &[], &fault);
    let gpu = lines
        .iter()
        .find(|l| l.contains("gpu"))
        .expect("a gpu line");
    assert!(gpu.starts_with("ok"), "{gpu}");
    assert!(
        gpu.contains("backend gl") && gpu.contains("in place of"),
        "{gpu}"
    );
    let (_, lines) = doctor(dir.path(), &config, &["--backend", "vulkan"], &fault);
    let gpu = lines
        .iter()
        .find(|l| l.contains("gpu"))
        .expect("a gpu line");
    assert!(
        gpu.starts_with("FAIL") && gpu.contains("no GPU adapter draws right"),
        "{gpu}"
    );
    let (_, lines) = doctor(dir.path(), &config, &["--backend", "vulkan"], &[]);
    let gpu = lines
        .iter()
        .find(|l| l.contains("gpu"))
        .expect("a gpu line");
    assert!(gpu.contains("backend vulkan: asked for"), "{gpu}");
}
