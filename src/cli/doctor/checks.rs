//! The doctor's checks of this machine: lens.cal, the GPU, GStreamer's elements, the camera
//! source (opened, one frame read) and the disk captures go to.

use super::Outcome;
use crate::app::Config;
use crate::cli::locate;
use crate::exposure::v4l2::{Device, Mapping};
use crate::source::demo::DemoCamera;
use crate::source::{FrameSlot, SourceSpec};
use gstreamer as gst;
use gstreamer::prelude::*;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// lens.cal is found and parses, every lens passes `lens check`, and the configuration's lens
/// is in it.
pub fn lens_cal(flag: Option<&Path>, cfg: &Config) -> Outcome {
    let (cal, origin) = match locate::lens_cal(flag) {
        Ok(found) => found,
        Err(e) => return Outcome::fail("lens.cal", format!("{e:#}")),
    };
    let failed: Vec<String> = cal
        .entries
        .iter()
        .flat_map(|e| {
            crate::lens::check::check(e)
                .into_iter()
                .filter(|f| !f.ok)
                .map(|f| format!("{}: {}", e.name, f.what))
        })
        .collect();
    if !failed.is_empty() {
        return Outcome::fail(
            "lens.cal",
            format!(
                "{origin}: {} (see `digiview lens check`)",
                failed.join("; ")
            ),
        );
    }
    if let Some(lens) = &cfg.lens
        && let Err(e) = cal.find(lens)
    {
        return Outcome::fail("lens.cal", format!("{origin}: the config's lens: {e}"));
    }
    let names: Vec<&str> = cal.entries.iter().map(|e| e.name.as_str()).collect();
    Outcome::pass(
        "lens.cal",
        format!("{origin}: {}, every check passes", names.join(", ")),
    )
}

/// An adapter of the configured backend opens and draws a known frame right (a software
/// one works, slowly): which one `serve` would render on, and why.
pub fn gpu(cfg: &Config) -> Outcome {
    match crate::render::choose::open(cfg.gpu_backend) {
        Ok(c) => {
            let slow = match c.gpu.is_software() {
                true => " (software: fine to try, too slow for 4K at full rate)",
                false => "",
            };
            let line = format!(
                "{}{slow}, backend {}: {}",
                c.choice.adapter, c.choice.backend, c.choice.why
            );
            Outcome::pass("gpu", line)
        }
        Err(e) => Outcome::fail("gpu", e.to_string()),
    }
}

/// The elements `serve` builds its pipelines from, for this configuration, each with the
/// Debian package that has it.
fn needed(cfg: &Config) -> Vec<(&'static str, &'static str)> {
    let mut out = vec![
        ("appsrc", "gstreamer1.0-plugins-base"),
        ("appsink", "gstreamer1.0-plugins-base"),
        ("videoconvert", "gstreamer1.0-plugins-base"),
        (cfg.encoder.codec.parser(), "gstreamer1.0-plugins-bad"),
        (cfg.encoder.codec.payloader(), "gstreamer1.0-plugins-good"),
        ("mp4mux", "gstreamer1.0-plugins-good"),
        ("filesink", "libgstreamer1.0-0"),
    ];
    let (hardware, software) = crate::stream::probe::encoders(cfg.encoder.codec);
    if cfg.encoder.kind != "auto" || !hardware.iter().any(|n| present(n)) {
        out.push(match software {
            "x265enc" => ("x265enc", "gstreamer1.0-plugins-bad"),
            _ => ("x264enc", "gstreamer1.0-plugins-ugly"),
        });
    }
    match cfg.source.parse::<SourceSpec>() {
        Ok(SourceSpec::V4l2(_)) => out.push(("v4l2src", "gstreamer1.0-plugins-good")),
        Ok(SourceSpec::File(_) | SourceSpec::Image(_) | SourceSpec::Sequence(_)) => {
            out.extend([
                ("filesrc", "libgstreamer1.0-0"),
                ("decodebin", "gstreamer1.0-plugins-base"),
                ("imagefreeze", "gstreamer1.0-plugins-good"),
                ("multifilesrc", "gstreamer1.0-plugins-good"),
                ("avdec_h264", "gstreamer1.0-libav"),
            ]);
        }
        _ => {}
    }
    for url in &cfg.publish {
        if url.starts_with("srt:") {
            out.extend([
                ("mpegtsmux", "gstreamer1.0-plugins-bad"),
                ("srtsink", "gstreamer1.0-plugins-bad"),
            ]);
        } else {
            out.push(("rtspclientsink", "gstreamer1.0-rtsp"));
        }
    }
    out
}

fn present(name: &str) -> bool {
    gst::ElementFactory::find(name).is_some()
}

/// Every element this configuration needs is installed; the hardware H.264 encoders found
/// are named.
pub fn gstreamer(cfg: &Config) -> Outcome {
    if let Err(e) = crate::gst::init() {
        return Outcome::fail("gstreamer", format!("{e} (install libgstreamer1.0-0)"));
    }
    let missing: Vec<String> = needed(cfg)
        .into_iter()
        .filter(|(name, _)| !present(name))
        .map(|(name, package)| format!("{name} (install {package})"))
        .collect();
    let (codec, (hardware, software)) = (
        cfg.encoder.codec,
        crate::stream::probe::encoders(cfg.encoder.codec),
    );
    let usable = crate::stream::probe::usable;
    let without_device: Vec<&str> = hardware
        .iter()
        .copied()
        .filter(|n| present(n) && !usable(n))
        .collect();
    let hardware: Vec<&str> = hardware.iter().copied().filter(|n| usable(n)).collect();
    let mut encoders = match hardware.as_slice() {
        [] => format!(
            "no hardware {} encoder ({} encodes on the CPU)",
            codec.name(),
            software.trim_end_matches("enc")
        ),
        found => format!("hardware {} encoders: {}", codec.name(), found.join(", ")),
    };
    if !without_device.is_empty() {
        let names = without_device.join(", ");
        encoders += &format!("; {names} installed without its device, not tried");
    }
    if missing.is_empty() {
        Outcome::pass(
            "gstreamer",
            format!("{} elements present; {encoders}", needed(cfg).len()),
        )
    } else {
        Outcome::fail("gstreamer", format!("missing {}", missing.join(", ")))
    }
}

/// The source opens and gives a frame within 5 s; a V4L2 camera's formats and exposure
/// controls are listed.
pub fn source(cfg: &Config, lens_cal: Option<&Path>) -> Outcome {
    let spec: SourceSpec = match cfg.source.parse() {
        Ok(s) => s,
        Err(e) => return Outcome::fail("source", e.to_string()),
    };
    if spec == SourceSpec::Demo {
        return demo_frame(cfg, lens_cal);
    }
    let slot = Arc::new(FrameSlot::default());
    let source = match crate::source::open(&spec, cfg.source_fps, false, slot.clone()) {
        Ok(s) => s,
        Err(e) => return Outcome::fail("source", format!("{spec}: {e}")),
    };
    let stop = Arc::new(AtomicBool::new(false));
    let running = {
        let stop = stop.clone();
        std::thread::spawn(move || source.run(&stop))
    };
    let started = Instant::now();
    let frame = slot.take_until(started + Duration::from_secs(5));
    stop.store(true, Ordering::Relaxed);
    let ended = running.join();
    let Some((frame, _)) = frame else {
        let why = match ended {
            Ok(Err(e)) => e.to_string(),
            _ => "no frame within 5 s".into(),
        };
        return Outcome::fail("source", format!("{spec}: {why}"));
    };
    let l = frame.layout;
    let mut line = format!(
        "{spec}: a {}x{} {} frame in {} ms",
        l.width,
        l.height,
        l.format,
        started.elapsed().as_millis()
    );
    if let SourceSpec::V4l2(path) = &spec {
        line += &format!("; formats {}", v4l2_formats(path));
        line += &match Device::open(path) {
            Ok(d) => {
                let m = Mapping::new(&d.controls());
                format!(
                    "; exposure control {}, gain {}, auto exposure {}",
                    yes(m.exposure.is_some()),
                    yes(m.gain.is_some()),
                    if m.has_auto() {
                        "the camera's"
                    } else {
                        "DigiView's"
                    }
                )
            }
            Err(e) => format!("; {e}"),
        };
    }
    Outcome::pass("source", line)
}

fn yes(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

/// The demo camera draws a frame.
fn demo_frame(cfg: &Config, lens_cal: Option<&Path>) -> Outcome {
    let d = &cfg.demo;
    let made = (|| -> anyhow::Result<String> {
        let (cal, _) = locate::lens_cal(lens_cal)?;
        let state = crate::state::State::default();
        let lens = crate::lens::Lenses::new(&cal).for_frame(
            state.settings.lens,
            (d.width, d.height),
            None,
        )?;
        let layout = crate::frame::PlaneLayout::tight(d.format, d.width, d.height)?;
        let t = Instant::now();
        let camera = DemoCamera::new(&lens, layout, state.settings.mount.euler());
        let sensor = crate::exposure::SensorModel::new(crate::exposure::Setting {
            exposure_us: state.settings.sensor.exposure_us,
            gain: state.settings.sensor.gain,
        });
        let pose = (state.vehicle.attitude.euler(), state.vehicle.position);
        camera.frame(|_| pose.0, &pose.1, 0.0, (sensor, 0), None);
        Ok(format!(
            "demo: a {}x{} {} frame in {} ms",
            d.width,
            d.height,
            d.format,
            t.elapsed().as_millis()
        ))
    })();
    match made {
        Ok(line) => Outcome::pass("source", line),
        Err(e) => Outcome::fail("source", format!("demo: {e:#}")),
    }
}

/// What a V4L2 camera can send: each format with its largest size.
fn v4l2_formats(path: &Path) -> String {
    let listed = (|| -> Option<String> {
        let src = gst::ElementFactory::make("v4l2src")
            .property("device", path.to_string_lossy().as_ref())
            .build()
            .ok()?;
        src.set_state(gst::State::Ready).ok()?;
        let caps = src.static_pad("src")?.query_caps(None);
        let _ = src.set_state(gst::State::Null);
        let mut best: Vec<(String, i32, i32)> = vec![];
        for s in caps.iter() {
            let name = s
                .get::<&str>("format")
                .map_or_else(|_| s.name().to_string(), String::from);
            let (w, h) = (
                s.get::<i32>("width").unwrap_or(0),
                s.get::<i32>("height").unwrap_or(0),
            );
            match best.iter_mut().find(|b| b.0 == name) {
                Some(b) if w * h > b.1 * b.2 => (b.1, b.2) = (w, h),
                Some(_) => {}
                None => best.push((name, w, h)),
            }
        }
        Some(
            best.iter()
                .map(|(n, w, h)| format!("{n} up to {w}x{h}"))
                .collect::<Vec<_>>()
                .join(", "),
        )
    })();
    listed.unwrap_or_else(|| "unknown".into())
}

/// The capture directory (or the nearest folder above it that exists, where it will be
/// made) is writable and has the configured free space.
pub fn disk(cfg: &Config) -> Outcome {
    let dir = &cfg.capture.dir;
    let Some(existing) = dir
        .ancestors()
        .find(|p| p.as_os_str().is_empty() || p.exists())
    else {
        return Outcome::fail("disk", format!("{}: no folder of it exists", dir.display()));
    };
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    if let Err(e) = rustix::fs::access(existing, rustix::fs::Access::WRITE_OK) {
        return Outcome::fail(
            "disk",
            format!(
                "{}: not writable ({e}); set capture dir to a folder this user may write",
                existing.display()
            ),
        );
    }
    let stat = match rustix::fs::statvfs(existing) {
        Ok(s) => s,
        Err(e) => return Outcome::fail("disk", format!("{}: {e}", existing.display())),
    };
    let free_mb = stat.f_bavail * stat.f_frsize / 1_000_000;
    let line = format!(
        "captures in {}: {:.1} GB free (at least {} MB wanted)",
        dir.display(),
        free_mb as f64 / 1000.0,
        cfg.capture.min_free_mb
    );
    if free_mb < cfg.capture.min_free_mb {
        Outcome::fail(
            "disk",
            format!("{line}: free some space or set capture dir elsewhere"),
        )
    } else {
        Outcome::pass("disk", line)
    }
}
