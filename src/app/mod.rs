//! The serve assembly, on top of everything: it takes `digiview serve`'s configuration
//! (`config`, one section per service) and the initial state, builds each service on the
//! shared parts of the live state (the settings behind the one gate, what is sensed, what
//! the head reports) and the telemetry (the MAVLink link, the MAVLink cameras, the control
//! server, the HTTP server, the video head with its RTSP server and relays), fills the small
//! trait or hook each owns for what it needs of another (`wiring`), says where each one
//! serves, and runs them until one of them stops the rest. Nothing below imports this module.

pub mod checks;
pub mod config;
pub mod config_rules;
mod wiring;

pub use config::{Config, ConfigError};

use crate::autopilot::{Components, EndpointError, Link, LinkStatus};
use crate::cameras::{self, Cameras};
use crate::control::Controller;
use crate::control::server::{self, Shutdown};
use crate::head::capture::Capture;
use crate::head::thermal::Sensor;
use crate::head::{DetectorError, Head, HeadError, HeadParts};
use crate::lens::LensCal;
use crate::policy::{Permissions, Policy};
use crate::state::capture::{Capturer, NoVideo, ViewShooter};
use crate::state::{Gate, Invalid, LiveSettings, Report, Sensed, State};
use crate::stream::publish::PublishError;
use crate::stream::rtsp::VIEW_MOUNTS;
use crate::stream::{Publisher, Rtsp, StreamError};
use crate::supervise;
use crate::telemetry::Telemetry;
use std::io::Write;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tokio::net::TcpListener;
use tracing::info;

/// How `serve` runs, beyond its configuration file.
pub struct Options {
    /// Only the control server on the live state: no camera, renderer or encoder.
    pub no_video: bool,
    /// Who may change the state, QUIT and delete files, on every control path.
    pub permissions: Permissions,
}

/// Why `serve` could not start, or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Http(#[from] crate::http::ListenError),
    #[error("control.listen {0:?}: {1}; use ADDR:PORT, e.g. \"0.0.0.0:5000\"")]
    ControlListen(String, std::net::AddrParseError),
    #[error(transparent)]
    State(#[from] Invalid),
    #[error(transparent)]
    Mavlink(#[from] EndpointError),
    #[error("starting the control server's runtime")]
    Runtime(#[source] std::io::Error),
    #[error("cannot listen on {0} ({1})")]
    Listen(SocketAddr, &'static str, #[source] std::io::Error),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Stream(#[from] StreamError),
    #[error(transparent)]
    Publish(#[from] PublishError),
    #[error(transparent)]
    Detector(#[from] DetectorError),
    #[error(transparent)]
    Head(#[from] HeadError),
    #[error("the frame loop panicked")]
    Panicked,
    #[error("the {0} service kept failing ({1}): given up")]
    GivenUp(&'static str, String),
    #[error("the video head stopped before its first frame")]
    NoFirstFrame,
    #[error("the video head put out no frame in 60 s")]
    Silent,
}

/// What every service of `serve` shares: the live state's three parts (the settings behind
/// the one gate, what is sensed, what the head reports), the policy, the telemetry and the
/// video head's capture.
struct Core {
    gate: Arc<Gate>,
    report: Arc<Report>,
    policy: Arc<Policy>,
    telemetry: Arc<Telemetry>,
    capture: Arc<Capture>,
}

impl Core {
    fn new(cal: &LensCal, cfg: &Config, state: State, options: Options) -> Result<Core, Invalid> {
        let settings = Arc::new(LiveSettings::new(state.settings, cal)?);
        let sensed = Arc::new(Sensed::new(state.vehicle, state.tracked));
        let policy = Arc::new(Policy::new(options.permissions));
        let report = Arc::<Report>::default();
        let capture = crate::head::capture::CaptureConfig {
            codec: cfg.encoder.codec,
            ..cfg.capture.clone()
        };
        Ok(Core {
            gate: Arc::new(Gate::new(settings, sensed, policy.clone())),
            capture: Arc::new(Capture::new(capture, report.clone())),
            report,
            policy,
            telemetry: Arc::new(Telemetry::new(cfg.mavlink.attitude_sample)),
        })
    }
}

/// The services on the autopilot link and the control protocol's request handling. The link
/// runs while it is held.
struct Services {
    cameras: Option<Arc<Cameras>>,
    link: Option<Link>,
    /// The payload SDK's link, while it runs.
    payload: Option<Link>,
    controller: Arc<Controller>,
}

fn services(core: &Core, cfg: &Config, no_video: bool) -> Result<Services, ServeError> {
    let cameras = cfg.cameras.enabled.then(|| {
        let shooter: Option<Arc<dyn ViewShooter>> = match no_video {
            true => None,
            false => Some(core.capture.clone()),
        };
        Arc::new(Cameras::new(
            core.gate.clone(),
            cfg.cameras.clone(),
            shooter,
        ))
    });
    let components = cameras.clone().map(|c| c as Arc<dyn Components>);
    let sensing = (core.gate.sensed().clone(), core.report.clone());
    let link = Link::start(
        &cfg.mavlink,
        sensing,
        core.telemetry.clone(),
        core.policy.clone(),
        components,
    )?;
    let payload = match &cameras {
        Some(c) => payload_link(core, cfg, c, link.as_ref())?,
        None => None,
    };
    let capture: Arc<dyn Capturer> = match no_video {
        true => Arc::new(NoVideo),
        false => core.capture.clone(),
    };
    let controller = Arc::new(Controller {
        autopilot: link
            .as_ref()
            .map(|l| wiring::autopilot_status(l.status.clone())),
        has_thermal: !no_video && !cfg.thermal.source.eq_ignore_ascii_case("off"),
        ..Controller::new(core.gate.clone(), core.report.clone(), capture)
    });
    Ok(Services {
        cameras,
        link,
        payload,
        controller,
    })
}

/// The payload SDK's link (`[payload]`), None when it is off. Signed as the autopilot link
/// is, its components under the autopilot's system id.
fn payload_link(
    core: &Core,
    cfg: &Config,
    cameras: &Arc<Cameras>,
    autopilot: Option<&Link>,
) -> Result<Option<Link>, ServeError> {
    let link_cfg = crate::autopilot::MavlinkConfig {
        endpoint: cfg.payload.endpoint.clone(),
        ..cfg.mavlink.clone()
    };
    let payload = crate::payload::Payload::new(cameras.clone(), core.gate.clone(), &cfg.payload);
    let kind = crate::autopilot::Kind {
        profile: crate::autopilot::Profile::Payload,
        ids: autopilot.map(|l| l.status.clone()),
    };
    Ok(Link::start_kind(
        &link_cfg,
        kind,
        (core.gate.sensed().clone(), core.report.clone()),
        core.telemetry.clone(),
        core.policy.clone(),
        Some(Arc::new(payload)),
    )?)
}

/// Runs `digiview serve` with `cfg` (checked) from `state` until it is stopped (QUIT, a
/// signal) or one of its services fails.
pub fn serve(cal: &LensCal, cfg: Config, state: State, options: Options) -> Result<(), ServeError> {
    let no_video = options.no_video;
    let http_address = cfg.http.address()?;
    let control: SocketAddr = cfg
        .control
        .listen
        .parse()
        .map_err(|e| ServeError::ControlListen(cfg.control.listen.clone(), e))?;
    let core = Core::new(cal, &cfg, state, options)?;
    // The link stops when this is dropped, as `serve` returns.
    let Services {
        cameras,
        link,
        payload: _payload,
        controller,
    } = services(&core, &cfg, no_video)?;
    let link_status = link.as_ref().map(|l| l.status.clone());
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("control")
        .enable_all()
        .build()
        .map_err(ServeError::Runtime)?;
    let shutdown = Shutdown::default();
    let (tcp, udp) = runtime
        .block_on(server::bind(control))
        .map_err(|e| ServeError::Listen(control, "tcp and udp", e))?;
    // Lines on stdout that scripts (and the tests) read to find the ports: printed once every
    // service serves, so a service that fails to start never announces itself.
    let mut announce = vec![format!("control listening on {}", tcp.local_addr()?)];
    let head = match no_video {
        true => None,
        false => {
            let services = (&cameras, link_status);
            Some(run_head(&cfg, &core, services, &shutdown, &mut announce)?)
        }
    };
    let http = match http_address {
        Some(addr) => Some(bind_http(&runtime, addr, &cfg, &cameras, &mut announce)?),
        None => None,
    };
    say(announce);
    let web = web(
        &cfg,
        &controller,
        &cameras,
        head.as_ref().map(|h| &h.0),
        no_video,
    );
    runtime.block_on(async {
        tokio::spawn(server::stop_on_signals(shutdown.clone()));
        if let Some(listener) = http {
            tokio::spawn(serve_http(
                listener,
                web,
                core.report.clone(),
                shutdown.clone(),
            ));
        }
        tokio::spawn(watch(
            core.report.clone(),
            core.policy.clone(),
            shutdown.clone(),
        ));
        server::run(tcp, udp, controller, shutdown).await
    })?;
    if let Some((head, thread)) = head {
        head.stop.store(true, Ordering::Relaxed);
        thread.join().map_err(|_| ServeError::Panicked)??;
    }
    match core.report.services.given_up() {
        Some((service, why)) => Err(ServeError::GivenUp(service, why)),
        None => Ok(()),
    }
}

/// The video head started on a thread of its own, once it streams; its line said.
fn run_head(
    cfg: &Config,
    core: &Core,
    services: (&Option<Arc<Cameras>>, Option<Arc<LinkStatus>>),
    shutdown: &Shutdown,
    announce: &mut Vec<String>,
) -> Result<(Arc<Head>, HeadThread), ServeError> {
    let (head, line) = start_head(cfg, core, services)?;
    announce.push(line);
    let (running, stop_all) = (head.clone(), shutdown.clone());
    let thread = std::thread::Builder::new()
        .name("frames".into())
        .spawn(move || {
            // The head ending on its own (an error, or even a panic outside its supervised
            // stages) ends the process too.
            let _stop_all = OnExit(move || stop_all.trigger());
            running.run()
        })?;
    let thread = wait_until_streaming(&head, thread)?;
    Ok((head, thread))
}

/// The HTTP server's listener; its line said, and the cameras told where captures are.
fn bind_http(
    runtime: &tokio::runtime::Runtime,
    addr: SocketAddr,
    cfg: &Config,
    cameras: &Option<Arc<Cameras>>,
    announce: &mut Vec<String>,
) -> Result<TcpListener, ServeError> {
    let listener = runtime
        .block_on(TcpListener::bind(addr))
        .map_err(|e| ServeError::Listen(addr, "http", e))?;
    let port = listener.local_addr()?.port();
    let public = cameras::public_host(&cfg.cameras, &addr.ip().to_string());
    let base = format!("http://{public}:{port}");
    if let Some(c) = cameras {
        c.set_captures_url(format!("{base}{}", crate::http::CAPTURES_PATH));
    }
    announce.push(format!("http serving {base}/"));
    Ok(listener)
}

/// Says where each service serves, on stdout. A reader that went away after the lines it
/// wanted (`serve | head -1`) must not end the service: what cannot be written is dropped.
fn say(announce: Vec<String>) {
    let mut stdout = std::io::stdout().lock();
    for line in announce {
        let _ = writeln!(stdout, "{line}");
    }
    let _ = stdout.flush();
}

/// What the HTTP server serves from.
fn web(
    cfg: &Config,
    controller: &Arc<Controller>,
    cameras: &Option<Arc<Cameras>>,
    head: Option<&Arc<Head>>,
    no_video: bool,
) -> crate::http::Web {
    crate::http::Web {
        controller: controller.clone(),
        camera_definition: cameras.clone().map(wiring::camera_definition),
        video: head.map(|h| wiring::video(h.clone())),
        captures: (!no_video).then(|| cfg.capture.dir.clone()),
        login: cfg.rtsp.user.clone().zip(cfg.rtsp.password.clone()),
        // The cameras' public host is in the URLs ground stations fetch the definition by.
        hosts: cfg
            .http
            .hosts
            .iter()
            .chain(&cfg.cameras.public_host)
            .cloned()
            .collect(),
    }
}

/// The HTTP server, supervised as every service is ([`supervise::keep_serving`]): one that
/// fails (an error, the server ending by itself, or a panic in the server) is reported and
/// served again on the same address after the pause; given up, it stops `serve` through
/// [`watch`].
async fn serve_http(
    listener: TcpListener,
    web: crate::http::Web,
    report: Arc<Report>,
    stop: Shutdown,
) {
    let Ok(address) = listener.local_addr() else {
        return;
    };
    let serve = |l| {
        let (web, stop) = (web.clone(), stop.clone());
        async move {
            let stopped = stop.clone();
            match crate::http::serve(l, web, async move { stopped.wait().await }).await {
                Ok(()) if stop.is_triggered() => Ok(()),
                Ok(()) => Err(std::io::Error::other("the server ended")),
                Err(e) => Err(e),
            }
        }
    };
    let stopped = || stop.is_triggered();
    let bind = TcpListener::bind::<SocketAddr>;
    supervise::keep_serving(
        &*report,
        "http",
        "",
        (listener, address),
        bind,
        serve,
        stopped,
    )
    .await;
}

/// Stops everything once a supervised service is given up (`crate::supervise`), and logs
/// the summary of refusals left out of the log once their second is over.
async fn watch(report: Arc<Report>, policy: Arc<Policy>, shutdown: Shutdown) {
    let mut look = tokio::time::interval(Duration::from_millis(250));
    loop {
        look.tick().await;
        policy.refusals.flush();
        if report.services.given_up().is_some() {
            shutdown.trigger();
            return;
        }
    }
}

/// The video head, not yet running: its RTSP server serves, its relays are started and its
/// detector is loaded. With the line that says where the stream is.
fn start_head(
    cfg: &Config,
    core: &Core,
    (cameras, link): (&Option<Arc<Cameras>>, Option<Arc<LinkStatus>>),
) -> Result<(Arc<Head>, String), ServeError> {
    let key_wanted = Arc::new(AtomicBool::new(false));
    let wanted = key_wanted.clone();
    let codec = cfg.encoder.codec;
    let rtsp_cfg = crate::stream::RtspConfig {
        codec,
        ..cfg.rtsp.clone()
    };
    let rtsp = Rtsp::start(&rtsp_cfg, move || wanted.store(true, Ordering::Relaxed))?;
    let host = match cfg.rtsp.address.as_str() {
        "0.0.0.0" | "::" => "127.0.0.1",
        a => a,
    };
    let line = format!("rtsp serving rtsp://{host}:{}{}", rtsp.port(), rtsp.path());
    if let Some(c) = cameras {
        let public = cameras::public_host(&cfg.cameras, &cfg.rtsp.address);
        let base = format!("rtsp://{public}:{}{}", rtsp.port(), rtsp.path());
        c.set_streams(base, cfg.encoder.bitrate_kbps, codec);
    }
    let publish = |mut target: crate::stream::PublishTarget, wanted: Arc<AtomicBool>| {
        target.codec = codec;
        info!("publishing to {}", target.url);
        let report: Arc<dyn crate::supervise::FailureLog> = core.report.clone();
        Publisher::start(target, report, move || {
            wanted.store(true, Ordering::Relaxed)
        })
    };
    let publishers = cfg
        .publish_targets()?
        .into_iter()
        .map(|target| publish(target, key_wanted.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let view_key_wanted: [Arc<AtomicBool>; VIEW_MOUNTS] = Default::default();
    let mut view_publishers: [Vec<Publisher>; VIEW_MOUNTS] = Default::default();
    for (cam, target) in cfg.view_publish_targets()? {
        view_publishers[cam].push(publish(target, view_key_wanted[cam].clone())?);
    }
    let parts = HeadParts {
        gate: core.gate.clone(),
        report: core.report.clone(),
        capture: core.capture.clone(),
        clients: Arc::new(rtsp),
        publishers,
        view_publishers,
        view_key_wanted,
        telemetry: core.telemetry.clone(),
        key_wanted,
        demo_autopilot: link.and_then(|l| wiring::demo_autopilot(&cfg.mavlink, l)),
        thermal: Sensor::configured(&cfg.thermal, core.gate.settings().lenses())
            .map_err(ConfigError::Range)?
            .map(Arc::new),
    };
    let head = Head::new(cfg.head()?, parts);
    head.load_detector()?;
    if let (Some(c), Some(reader)) = (cameras, wiring::thermal_reader(&head)) {
        c.set_thermal(reader);
    }
    Ok((head, line))
}

/// Waits for the encoder's first picture. A head that ends first (its encoder or GPU would
/// not start) returns its error; one that puts out nothing for a minute is an error too.
fn wait_until_streaming(head: &Arc<Head>, thread: HeadThread) -> Result<HeadThread, ServeError> {
    let limit = Instant::now() + Duration::from_secs(60);
    while !head.streaming() {
        if thread.is_finished() {
            thread.join().map_err(|_| ServeError::Panicked)??;
            return Err(ServeError::NoFirstFrame);
        }
        if Instant::now() > limit {
            head.stop.store(true, Ordering::Relaxed);
            return Err(ServeError::Silent);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(thread)
}

type HeadThread = std::thread::JoinHandle<Result<(), HeadError>>;

/// Runs its closure when dropped, unwinding included.
struct OnExit<F: FnMut()>(F);

impl<F: FnMut()> Drop for OnExit<F> {
    fn drop(&mut self) {
        (self.0)()
    }
}
