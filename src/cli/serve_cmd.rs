//! `digiview serve`'s command line: the flags, laid over the configuration file
//! (`--config digiview.toml`), and the initial state; `crate::app` then builds and runs the
//! services. With no arguments it streams the built-in demo. `--no-video` runs the control
//! server alone on the live state, so the protocol can be exercised on any machine.

use super::StateArgs;
use crate::app::{self, Config};
use crate::detect::Detector;
use crate::lens::LensCal;
use crate::policy::{Allow, Permissions};
use anyhow::{Result, anyhow};
use clap::Args;
use std::net::SocketAddr;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ServeArgs {
    #[command(flatten)]
    pub setup: SetupArgs,
    /// Run only the control server on the live state: no camera, renderer or encoder.
    #[arg(long)]
    no_video: bool,
    /// Who may SET: `any`, `none`, `loopback`, or addresses and CIDR ranges, comma-separated.
    #[arg(long)]
    allow_set: Option<Allow>,
    /// Who may QUIT (same forms as --allow-set).
    #[arg(long)]
    allow_quit: Option<Allow>,
    /// Who may delete files: MAVLink's STORAGE_FORMAT (same forms as --allow-set; over
    /// MAVLink a signed message as well).
    #[arg(long)]
    allow_delete: Option<Allow>,
    /// Also push the stream to a relay: rtsp://HOST:PORT/PATH (RTSP RECORD),
    /// srt://HOST:PORT or udp://HOST:PORT (MPEG-TS with KLV) (repeatable; replaces the
    /// config's `publish`).
    #[arg(long = "publish", value_name = "URL")]
    publish: Vec<String>,
    /// Push camera N's own stream to a relay: N=URL, the URL as --publish's (repeatable;
    /// replaces the config's `publish_views`).
    #[arg(long = "publish-view", value_name = "N=URL")]
    publish_views: Vec<String>,
    /// The detector for the detection tiles: motion (built in), onnx (a model, NanoDet-m by
    /// default) or off (default: the config's, motion; off when the state gives objects with
    /// --track).
    #[arg(long, value_enum)]
    detector: Option<Detector>,
    /// The external detector's socket (replaces the config's `[detection] socket`).
    #[arg(long, value_name = "PATH")]
    detections_socket: Option<std::path::PathBuf>,
    /// The ONNX detector's model file (replaces the config's `[detection] model`).
    #[arg(long, value_name = "FILE")]
    model: Option<std::path::PathBuf>,
    /// What the views are to the autopilot's gimbal protocol: manager (each view's camera
    /// manages its view as a gimbal; ground stations point it) or device (each view a gimbal
    /// device, 154 then 171.., that the autopilot manages: its mount set to a MAVLink
    /// gimbal). Replaces the config's `[cameras] gimbal`; docs/mavlink.md says when to
    /// choose which.
    #[arg(long, value_enum, value_name = "ROLE")]
    mavlink_gimbal: Option<crate::cameras::GimbalRole>,
    /// The payload SDK's link, where apps written with Gremsy's PayloadSdk drive one view as
    /// their payload: udpin:0.0.0.0:14566 (the SDK's port), another endpoint, or off
    /// (replaces the config's `[payload] endpoint`; docs/mavlink.md).
    #[arg(long, value_name = "ENDPOINT")]
    payload: Option<String>,
    /// The view the payload SDK drives, 0 to 3 (replaces the config's `[payload] view`).
    #[arg(long, value_name = "N")]
    payload_view: Option<usize>,
    /// A thermal sensor beside the fisheye: demo, v4l2:DEVICE (Y16), gst:DESCRIPTION
    /// (GRAY16_LE), file:PATH, image:PATH, sequence:PATTERN, or off (replaces the config's
    /// `[thermal] source`; docs/thermal.md).
    #[arg(long, value_name = "SOURCE")]
    thermal: Option<String>,
    /// The demo vehicle hovers at the state's attitude and position instead of flying.
    #[arg(long)]
    demo_hover: bool,
    /// The demo draws each frame's capture time as a barcode (glass-to-glass latency).
    #[arg(long)]
    demo_stamp: bool,
    /// The demo camera's frame size, WxH.
    #[arg(long, value_parser = crate::units::parse_size)]
    demo_size: Option<(u32, u32)>,
    #[command(flatten)]
    state: StateArgs,
}

/// The configuration file with the flags applied.
/// Where `serve` and `doctor` find their configuration, and the flags that override it.
#[derive(Args, Debug)]
pub struct SetupArgs {
    /// A TOML configuration file (docs/serve.md lists every key and default); flags override
    /// it. Without it: $DIGIVIEW_CONFIG, else the first digiview.toml in the working
    /// directory, ~/.config/digiview, /etc/digiview, else the defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The source: demo, v4l2:DEVICE, gst:DESCRIPTION, file:PATH, image:PATH, sequence:PATTERN.
    #[arg(long)]
    source: Option<String>,
    /// Where the control protocol listens, TCP and UDP (port 0 picks a free port).
    #[arg(long)]
    control: Option<SocketAddr>,
    /// The RTSP port (0 picks a free port).
    #[arg(long)]
    rtsp_port: Option<u16>,
    /// Where the HTTP server listens, ADDR:PORT (port 0 picks a free port), or off.
    #[arg(long, value_name = "ADDR:PORT")]
    http: Option<String>,
    /// The autopilot link: udpin:ADDR:PORT, udpout:HOST:PORT, tcpin:ADDR:PORT,
    /// tcpout:HOST:PORT, serial:DEVICE:BAUD, or off (docs/mavlink.md).
    #[arg(long, value_name = "ENDPOINT")]
    mavlink: Option<String>,
    /// Where stills and recordings go.
    #[arg(long)]
    capture_dir: Option<PathBuf>,
    /// The GPU backend: auto (the best adapter that draws a known frame right, Vulkan before
    /// GL), vulkan or gl (replaces the config's `gpu_backend`).
    #[arg(long, value_enum)]
    backend: Option<crate::modes::GpuBackend>,
}

impl SetupArgs {
    /// The configuration file (or the defaults) with these flags applied, not yet checked.
    pub fn config(&self) -> Result<(Config, super::locate::Origin)> {
        let (mut cfg, origin) = super::locate::config(self.config.as_deref())?;
        // The file's own listen address is checked even where a flag replaces it: a mistake
        // in the file would otherwise come back the day the flag is dropped.
        if let Err(e) = cfg.control.listen.parse::<SocketAddr>() {
            let bad = app::ServeError::ControlListen(cfg.control.listen.clone(), e);
            return Err(anyhow::Error::new(bad).context(format!("{origin}")));
        }
        if let Some(s) = &self.source {
            cfg.source = s.clone();
        }
        if let Some(c) = self.control {
            cfg.control.listen = c.to_string();
        }
        if let Some(p) = self.rtsp_port {
            cfg.rtsp.port = p;
        }
        if let Some(h) = &self.http {
            cfg.http.listen = h.clone();
        }
        if let Some(m) = &self.mavlink {
            cfg.mavlink.endpoint = m.clone();
        }
        if let Some(b) = self.backend {
            cfg.gpu_backend = b;
        }
        if let Some(d) = &self.capture_dir {
            cfg.capture.dir = d.clone();
        }
        Ok((cfg, origin))
    }
}

fn config(args: &ServeArgs) -> Result<Config> {
    let (mut cfg, _) = args.setup.config()?;
    if !args.publish.is_empty() {
        cfg.publish = args.publish.clone();
    }
    if !args.publish_views.is_empty() {
        cfg.publish_views = args.publish_views.clone();
    }
    if let Some(t) = &args.thermal {
        cfg.thermal.source = t.clone();
    }
    if args.demo_hover {
        cfg.demo.motion = false;
    }
    if args.demo_stamp {
        cfg.demo.stamp = true;
    }
    if let Some(d) = args.detector {
        cfg.detection.detector = d;
    }
    if let Some(m) = &args.model {
        cfg.detection.model = m.clone();
    }
    if let Some(p) = &args.detections_socket {
        cfg.detection.socket = p.clone();
    }
    if let Some(role) = args.mavlink_gimbal {
        cfg.cameras.gimbal = role;
    }
    if let Some(p) = &args.payload {
        cfg.payload.endpoint = p.clone();
    }
    if let Some(v) = args.payload_view {
        cfg.payload.view = v;
    }
    if let Some((w, h)) = args.demo_size {
        (cfg.demo.width, cfg.demo.height) = (w, h);
    }
    cfg.check()?;
    Ok(cfg)
}

/// Caps glibc's malloc arenas at two. By default every thread that allocates may get an arena
/// of its own (up to 8 per core), and the video head's threads (GStreamer's streaming and
/// RTSP client threads come and go) leave memory parked in them: a one-hour soak grew 5.1%
/// with the default and 1.4% over 10 minutes with the cap, against 3.4% without
/// (docs/performance.md). Called before any thread starts.
fn cap_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets an allocator parameter; no other thread exists yet.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 2);
    }
}

pub fn serve(cal: &LensCal, args: ServeArgs) -> Result<()> {
    if !args.no_video && std::env::var_os("MALLOC_ARENA_MAX").is_none() {
        cap_malloc_arenas();
    }
    let mut cfg = config(&args)?;
    if !args.no_video {
        // A source that can never open (a missing file, a pipeline that does not parse) is an
        // error now, not retried for ever; a camera that is not there yet is waited for.
        let spec: crate::source::SourceSpec = cfg.source.parse()?;
        crate::source::check(&spec, cfg.source_fps)?;
    }
    let mut state_args = args.state.clone();
    state_args.state = state_args.state.or(cfg.state.clone());
    state_args.lens = state_args.lens.or(cfg.lens.clone());
    let state = state_args.state(cal)?;
    if !state.tracked.is_empty() && args.detector.is_none() {
        tracing::info!("objects given with --track or the state: the detector is off");
        cfg.detection.detector = Detector::Off;
    }
    let list = |given: &Option<Allow>, key: &str, text: &str| -> Result<Allow> {
        match given {
            Some(a) => Ok(a.clone()),
            None => text.parse().map_err(|e| anyhow!("control.{key}: {e}")),
        }
    };
    let c = &cfg.control;
    let permissions = Permissions {
        set: list(&args.allow_set, "allow_set", &c.allow_set)?,
        quit: list(&args.allow_quit, "allow_quit", &c.allow_quit)?,
        delete: list(&args.allow_delete, "allow_delete", &c.allow_delete)?,
    };
    let options = app::Options {
        no_video: args.no_video,
        permissions,
    };
    Ok(app::serve(cal, cfg, state, options)?)
}
