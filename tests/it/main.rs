//! The integration tests, one binary: each module is one area of DigiView tried from outside
//! (the `digiview` binary, its servers over real sockets, the GPU on lavapipe), two at a time;
//! `common` the helpers and peers every area shares. One binary links once and shares its
//! fixtures (the GPU device, the lens calibration) across the areas. `cargo test --release
//! --test it AREA::` runs one area. The tests that need the machine to themselves are in
//! `tests/alone`.

#[path = "../common/mod.rs"]
mod common;

mod autopilot_drives;
mod cli;
mod cli_errors;
mod clock_step;
mod control_server;
mod crop_modes;
mod detect_motion;
mod dewarp_vs_truth;
mod disk_full;
mod doctor;
mod encoder_probe;
mod entry_paths;
mod frame_loop;
mod fuzz_corpus;
mod gimbal_device;
mod gpu_fallback;
mod gpu_frames;
mod gpu_render;
mod h265;
mod klv;
mod lens_calibrate;
mod lens_calibrate_video;
mod locate;
mod lock_flags;
mod mavlink_camera_video;
mod mavlink_cameras;
mod mavlink_commands;
mod mavsdk;
mod no_panics;
mod one_path;
mod package;
mod payload_sdk;
mod players;
mod protocol_camera;
mod protocol_system;
mod publish;
mod pymavlink;
mod render_video;
mod rolling_shutter;
mod rtsp_wire;
mod rules_table;
mod services;
mod sphere;
mod stills_geotag;
mod thermal;
mod thermal_layer;
mod thermal_serve;
mod trust_mavlink;
mod trust_web;
mod view_filters;
mod vmti;
mod web;
mod web_api;
mod web_thermal;
