//! The integration tests that need the machine to themselves, one at a time: those that time
//! what a video head does (its frame rate, how closely the attitude follows the autopilot,
//! the frame's clock against a spinning autopilot, the auto exposure's settling), and those
//! that wait on its detection thread, which runs only on CPU time nothing else wants
//! (SCHED_IDLE, by design: the video comes first), so another test's load beside them would
//! stall it. Each test here holds [`one_at_a_time`] for its length, and cargo runs this
//! binary apart from `tests/it`, so nothing of the suite runs beside them. `cargo test
//! --release --test alone AREA::` runs one area.

#[path = "../common/mod.rs"]
mod common;

mod autopilot;
mod autopilot_video;
mod detect_external;
mod detect_flying;
mod detect_motion;
mod detect_onnx;
mod exposure;
mod gimbal_video;
mod klv_flight;
mod payload_video;
mod rolling_video;
mod serve_video;
mod services;
mod sphere_flying;
mod thermal_look;
mod thermal_stream;
mod tracking;
mod view_rates;
mod web_rings;

/// Held by every test here for its length: they run one at a time.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock().unwrap_or_else(|e| e.into_inner())
}
