//! `digiview serve`: the running system. By default the video head (source → GPU → H.264 →
//! RTSP) runs beside the control server, configured by `--config digiview.toml` and the flags
//! here; with no arguments it streams the built-in demo. `--no-video` runs the control
//! server alone on the live state, so the protocol can be exercised on any machine.

use super::StateArgs;
use crate::autopilot::{Components, Link};
use crate::cameras::{self, Cameras, ViewShooter};
use crate::control::Controller;
use crate::control::permissions::{Allow, Permissions};
use crate::control::server::{self, Shutdown};
use crate::head::Head;
use crate::head::capture::Capture;
use crate::head::config::Config;
use crate::head::telemetry::Telemetry;
use crate::lens::LensCal;
use crate::state::Live;
use crate::state::capture::{Capturer, NoVideo};
use crate::stream::{Publisher, Rtsp};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tracing::info;

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
    /// Also push the stream to a relay: rtsp://HOST:PORT/PATH (RTSP RECORD) or
    /// srt://HOST:PORT (repeatable; replaces the config's `publish`).
    #[arg(long = "publish", value_name = "URL")]
    publish: Vec<String>,
    /// The detector for the detection tiles: motion (built in), onnx (a model, NanoDet-m by
    /// default) or off (default: the config's, motion; off when the state gives objects with
    /// --track).
    #[arg(long, value_enum)]
    detector: Option<crate::head::config::Detector>,
    /// The external detector's socket (replaces the config's `[detection] socket`).
    #[arg(long, value_name = "PATH")]
    detections_socket: Option<std::path::PathBuf>,
    /// The ONNX detector's model file (replaces the config's `[detection] model`).
    #[arg(long, value_name = "FILE")]
    model: Option<std::path::PathBuf>,
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
}

impl SetupArgs {
    /// The configuration file (or the defaults) with these flags applied, not yet checked.
    pub fn config(&self) -> Result<(Config, super::locate::Origin)> {
        let (mut cfg, origin) = super::locate::config(self.config.as_deref())?;
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
        cfg.detection.detector = crate::head::config::Detector::Off;
    }
    let permissions = Permissions {
        set: match &args.allow_set {
            Some(a) => a.clone(),
            None => cfg
                .control
                .allow_set
                .parse()
                .map_err(|e| anyhow!("control.allow_set: {e}"))?,
        },
        quit: match &args.allow_quit {
            Some(a) => a.clone(),
            None => cfg
                .control
                .allow_quit
                .parse()
                .map_err(|e| anyhow!("control.allow_quit: {e}"))?,
        },
    };
    let http_address = cfg.http.address().map_err(|e| anyhow!(e))?;
    let http_cameras_cfg = cfg.cameras.clone();
    let captures_dir = (!args.no_video).then(|| cfg.capture.dir.clone());
    let login = cfg.rtsp.user.clone().zip(cfg.rtsp.password.clone());
    let control: SocketAddr = cfg
        .control
        .listen
        .parse()
        .map_err(|e| anyhow!("control.listen {:?}: {e}", cfg.control.listen))?;

    let capture = Arc::new(Capture::new(cfg.capture.clone()));
    let hook: Box<dyn Capturer> = if args.no_video {
        Box::new(NoVideo)
    } else {
        Box::new(capture.clone())
    };
    let live = Arc::new(Live::new(state, cal, hook)?);
    let telemetry = Arc::new(Telemetry::new(cfg.mavlink.attitude_sample));
    let cameras = cfg.cameras.enabled.then(|| {
        let shooter: Option<Arc<dyn ViewShooter>> = match args.no_video {
            true => None,
            false => Some(capture.clone()),
        };
        Arc::new(Cameras::new(live.clone(), cfg.cameras.clone(), shooter))
    });
    let components = cameras.clone().map(|c| c as Arc<dyn Components>);
    let link = Link::start(&cfg.mavlink, live.clone(), telemetry.clone(), components)?;
    let controller = Arc::new(Controller {
        autopilot: link.as_ref().map(|l| l.status.clone()),
        ..Controller::new(live.clone(), permissions)
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("control")
        .enable_all()
        .build()
        .context("starting the control server's runtime")?;
    let shutdown = Shutdown::default();
    let (tcp, udp) = runtime
        .block_on(server::bind(control))
        .with_context(|| format!("cannot listen on {control} (tcp and udp)"))?;
    // Lines on stdout that scripts (and the tests) read to find the ports: printed once every
    // service serves, so a service that fails to start never announces itself.
    let mut announce = vec![format!("control listening on {}", tcp.local_addr()?)];
    let head = if args.no_video {
        None
    } else {
        let key_wanted = Arc::new(AtomicBool::new(false));
        let wanted = key_wanted.clone();
        let rtsp = Rtsp::start(&cfg.rtsp, move || wanted.store(true, Ordering::Relaxed))?;
        let host = match cfg.rtsp.address.as_str() {
            "0.0.0.0" | "::" => "127.0.0.1",
            a => a,
        };
        announce.push(format!(
            "rtsp serving rtsp://{host}:{}{}",
            rtsp.port(),
            rtsp.path()
        ));
        if let Some(c) = &cameras {
            let public = cameras::public_host(&cfg.cameras, &cfg.rtsp.address);
            let base = format!("rtsp://{public}:{}{}", rtsp.port(), rtsp.path());
            c.set_streams(base, cfg.encoder.bitrate_kbps);
        }
        let publishers = cfg
            .publish_targets()?
            .into_iter()
            .map(|target| {
                let wanted = key_wanted.clone();
                info!("publishing to {}", target.url);
                Publisher::start(target, move || wanted.store(true, Ordering::Relaxed))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let head = Head::new(
            cfg,
            live.clone(),
            capture,
            Arc::new(rtsp),
            publishers,
            telemetry,
            key_wanted,
        );
        head.load_detector()?;
        let running = head.clone();
        let stop_all = shutdown.clone();
        let thread = std::thread::Builder::new()
            .name("frames".into())
            .spawn(move || {
                // The head ending on its own (an error, or even a panic outside its
                // supervised stages) ends the process too.
                let _stop_all = OnExit(move || stop_all.trigger());
                running.run()
            })?;
        let thread = wait_until_streaming(&head, thread)?;
        Some((head, thread))
    };
    let http = match http_address {
        Some(addr) => {
            let listener = runtime
                .block_on(tokio::net::TcpListener::bind(addr))
                .with_context(|| format!("cannot listen on {addr} (http)"))?;
            let port = listener.local_addr()?.port();
            let public = cameras::public_host(&http_cameras_cfg, &addr.ip().to_string());
            if let Some(c) = &cameras {
                c.set_http(format!("http://{public}:{port}"));
            }
            announce.push(format!("http serving http://{public}:{port}/"));
            Some(listener)
        }
        None => None,
    };
    // A reader that went away after the lines it wanted (`serve | head -1`) must not end
    // the service: what cannot be written is dropped.
    let mut stdout = std::io::stdout().lock();
    for line in announce {
        let _ = writeln!(stdout, "{line}");
    }
    let _ = stdout.flush();
    drop(stdout);
    runtime.block_on(async {
        tokio::spawn(server::stop_on_signals(shutdown.clone()));
        if let Some(listener) = http {
            let stop = shutdown.clone();
            let web = crate::http::Web {
                controller: controller.clone(),
                cameras: cameras.clone(),
                head: head.as_ref().map(|(h, _)| h.clone()),
                captures: captures_dir.clone(),
                login,
            };
            tokio::spawn(async move {
                let stopped = async move { stop.wait().await };
                if let Err(e) = crate::http::serve(listener, web, stopped).await {
                    tracing::error!("http: {e}");
                }
            });
        }
        server::run(tcp, udp, controller, shutdown).await
    })?;
    if let Some((head, thread)) = head {
        head.stop.store(true, Ordering::Relaxed);
        thread
            .join()
            .map_err(|_| anyhow!("the frame loop panicked"))??;
    }
    Ok(())
}

/// Waits for the encoder's first picture. A head that ends first (its encoder or GPU would
/// not start) returns its error; one that puts out nothing for a minute is an error too.
fn wait_until_streaming(head: &Arc<Head>, thread: HeadThread) -> Result<HeadThread> {
    let limit = Instant::now() + Duration::from_secs(60);
    while !head.streaming() {
        if thread.is_finished() {
            thread
                .join()
                .map_err(|_| anyhow!("the frame loop panicked"))??;
            bail!("the video head stopped before its first frame");
        }
        if Instant::now() > limit {
            head.stop.store(true, Ordering::Relaxed);
            bail!("the video head put out no frame in 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(thread)
}

type HeadThread = std::thread::JoinHandle<Result<(), crate::head::HeadError>>;

/// Runs its closure when dropped, unwinding included.
struct OnExit<F: FnMut()>(F);

impl<F: FnMut()> Drop for OnExit<F> {
    fn drop(&mut self) {
        (self.0)()
    }
}
