//! `digiview serve` as a child process on an ephemeral port, and raw protocol clients.

use super::frames::Client;
use digiview::protocol::{FRAME_LEN, Message};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

pub struct Serve {
    child: Child,
    pub addr: SocketAddr,
    /// The stream's URL (video mode only).
    pub rtsp: Option<String>,
    /// The page's URL, `http://127.0.0.1:PORT/` (unless the test turned HTTP off).
    pub http: Option<String>,
}

impl Serve {
    /// `digiview serve --no-video` on 127.0.0.1, port chosen by the system, plus `extra` flags.
    pub fn start(extra: &[&str]) -> Serve {
        Serve::spawn(&["--no-video"], extra)
    }

    /// `digiview serve` with video (RTSP on a free port), plus `extra` flags.
    pub fn start_video(extra: &[&str]) -> Serve {
        Serve::spawn(&["--rtsp-port", "0"], extra)
    }

    /// As [`Serve::start`], logging at info level into a pipe whose reader is gone (as under
    /// `digiview serve 2>&1 | head -1`).
    pub fn start_unread(extra: &[&str]) -> Serve {
        let mut serve = Serve::launch(&["--no-video"], extra, Some("info"), &[]);
        drop(serve.child.stderr.take());
        serve
    }

    fn spawn(mode: &[&str], extra: &[&str]) -> Serve {
        Serve::launch(mode, extra, None, &[])
    }

    /// As [`Serve::start_video`] with `DIGIVIEW_FAULT=fault` and errors logged into a pipe
    /// ([`Serve::log`]).
    pub fn start_video_faulty(fault: &str, extra: &[&str]) -> Serve {
        Serve::launch(
            &["--rtsp-port", "0"],
            extra,
            Some("error"),
            &[("DIGIVIEW_FAULT", fault)],
        )
    }

    /// As [`Serve::start_video`] with `env` set for this server alone, errors logged into a
    /// pipe ([`Serve::log`]).
    pub fn start_video_env(env: &[(&str, &str)], extra: &[&str]) -> Serve {
        Serve::launch(&["--rtsp-port", "0"], extra, Some("error"), env)
    }

    /// As [`Serve::start`], logging at `level` into a pipe ([`Serve::log`]), with
    /// `DIGIVIEW_FAULT=fault` when given.
    pub fn start_logging(level: &str, fault: Option<&str>, extra: &[&str]) -> Serve {
        let fault: Vec<_> = fault.map(|f| ("DIGIVIEW_FAULT", f)).into_iter().collect();
        Serve::launch(&["--no-video"], extra, Some(level), &fault)
    }

    /// As [`Serve::start_video`], logging at `level` into a pipe ([`Serve::log`]).
    pub fn start_video_logging(level: &str, extra: &[&str]) -> Serve {
        Serve::launch(&["--rtsp-port", "0"], extra, Some(level), &[])
    }

    /// What the server logged (with a piped log), once it has ended.
    pub fn log(&mut self) -> String {
        let mut log = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = e.read_to_string(&mut log);
        }
        log
    }

    /// `log`: a RUST_LOG level for a piped stderr, else the test's choice (see below);
    /// `fault`: DIGIVIEW_FAULT for this server alone.
    fn launch(mode: &[&str], extra: &[&str], log: Option<&str>, env: &[(&str, &str)]) -> Serve {
        let cal = super::lens_cal_path();
        // No autopilot link unless the test asks for one (the default port is one per host).
        let link: &[&str] = if extra.contains(&"--mavlink") {
            &[]
        } else {
            &["--mavlink", "off"]
        };
        // The HTTP server on a free port, unless the test says where.
        let http: &[&str] = if extra.contains(&"--http") {
            &[]
        } else {
            &["--http", "127.0.0.1:0"]
        };
        // The demo's exposure held where it shows the world's own colours (auto exposure
        // off), so pictures compare with offline renders, unless the test sets it.
        let sensor: &[&str] = if extra.contains(&"--cam-sensor") || mode.contains(&"--no-video") {
            &[]
        } else {
            &["--cam-sensor", "ae=0"]
        };
        // No detector unless the test asks for one: its tiles would follow the demo's movers,
        // and the pictures compare with offline renders of the state given.
        let detector: &[&str] = if extra.contains(&"--detector") || mode.contains(&"--no-video") {
            &[]
        } else {
            &["--detector", "off"]
        };
        let mut command = Command::new(env!("CARGO_BIN_EXE_digiview"));
        command.envs(env.iter().copied());
        let mut child = command
            .args(["serve", "--control", "127.0.0.1:0"])
            .args(mode)
            .args(link)
            .args(detector)
            .args(http)
            .args(sensor)
            .args(extra)
            .env("DIGIVIEW_LENS_CAL", cal)
            // DIGIVIEW_TEST_LOG=info shows the server's log while debugging a test.
            .env(
                "RUST_LOG",
                log.map(String::from).unwrap_or_else(|| {
                    std::env::var("DIGIVIEW_TEST_LOG").unwrap_or_else(|_| "warn".into())
                }),
            )
            .stdout(Stdio::piped())
            .stderr(if log.is_some() {
                Stdio::piped()
            } else if std::env::var_os("DIGIVIEW_TEST_LOG").is_some() {
                Stdio::inherit()
            } else {
                Stdio::null()
            })
            .spawn()
            .expect("digiview serve starts");
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        let addr = line
            .trim()
            .strip_prefix("control listening on ")
            .unwrap_or_else(|| panic!("serve printed {line:?}"))
            .parse()
            .unwrap();
        // The next announced line, which starts with `prefix`: what follows it.
        let mut announced = |prefix: &str| {
            line.clear();
            out.read_line(&mut line).unwrap();
            line.trim()
                .strip_prefix(prefix)
                .unwrap_or_else(|| panic!("serve printed {line:?}"))
                .to_string()
        };
        let rtsp = (!mode.contains(&"--no-video")).then(|| announced("rtsp serving "));
        let off = extra.windows(2).any(|w| w == ["--http", "off"]);
        let http = (!off).then(|| announced("http serving "));
        Serve {
            child,
            addr,
            rtsp,
            http,
        }
    }

    /// kill -9.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Sends SIGTERM.
    pub fn terminate(&self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
    }

    pub fn tcp(&self) -> Raw {
        Raw::connect(self.addr)
    }

    /// The exit status if the process ends within `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> Option<ExitStatus> {
        let t = Instant::now();
        while t.elapsed() < limit {
            if let Some(s) = self.child.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A TCP client that speaks raw frames.
pub struct Raw {
    pub stream: TcpStream,
}

impl Raw {
    pub fn connect(addr: SocketAddr) -> Raw {
        let stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        Raw { stream }
    }
}

impl Client for Raw {
    fn send_bytes(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).unwrap();
    }

    fn recv(&mut self) -> Message {
        let mut f = [0u8; FRAME_LEN];
        self.stream.read_exact(&mut f).unwrap();
        Message::decode(&f).expect("the server's replies are valid frames")
    }
}

/// One datagram to the server, one datagram back.
pub fn udp_exchange(addr: SocketAddr, datagram: &[u8]) -> Vec<u8> {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.send_to(datagram, addr).unwrap();
    let mut buf = [0u8; 2048];
    let (n, _) = s.recv_from(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// A configuration file for `serve` in a directory of its own, its captures written to
/// `captures/` there.
pub struct CaptureConfig {
    pub config: std::path::PathBuf,
    pub captures: std::path::PathBuf,
    pub dir: tempfile::TempDir,
}

impl CaptureConfig {
    /// `before` (top-level keys, then sections), then `[capture]` with its `dir` and `capture`'s
    /// keys.
    pub fn new(before: &str, capture: &str) -> CaptureConfig {
        let dir = tempfile::tempdir().unwrap();
        let captures = dir.path().join("captures");
        let config = dir.path().join("digiview.toml");
        let text = format!("{before}[capture]\ndir = {:?}\n{capture}", captures);
        std::fs::write(&config, text).unwrap();
        CaptureConfig {
            config,
            captures,
            dir,
        }
    }

    pub fn path(&self) -> &str {
        self.config.to_str().unwrap()
    }
}

/// `serve` with video, its cameras' stills (640x480) written to a directory of the test's,
/// the demo drawn at 960x540, its MAVLink link on a free UDP port (returned), `extra` flags
/// beside, logging at `log` into a pipe ([`Serve::log`]) when given.
pub fn with_stills(extra: &[&str], log: Option<&str>) -> (CaptureConfig, Serve, u16) {
    with_stills_env(extra, log, &[], "")
}

/// As [`with_stills`], with `env` set for the process and `capture`'s lines added to the
/// configuration's `[capture]` section.
pub fn with_stills_env(
    extra: &[&str],
    log: Option<&str>,
    env: &[(&str, &str)],
    capture: &str,
) -> (CaptureConfig, Serve, u16) {
    let config = CaptureConfig::new(
        "[cameras]\nwidth = 640\nheight = 480\npublic_host = \"127.0.0.1\"\n",
        &format!("min_free_mb = 1\n{capture}"),
    );
    let port = super::autopilot::free_udp_port();
    let link = format!("udpin:127.0.0.1:{port}");
    let mut flags = vec![
        "--config",
        config.path(),
        "--mavlink",
        &link,
        "--demo-size",
        "960x540",
        "--size",
        "640x480",
    ];
    flags.extend_from_slice(extra);
    let serve = Serve::launch(&["--rtsp-port", "0"], &flags, log, env);
    (config, serve, port)
}

/// Waits (20 s at most) until SYSTEM_STATUS says `serve` runs, with no error: its picture
/// is flowing, not its NO SIGNAL card.
pub fn until_running(serve: &Serve) {
    let mut ctl = digiview::control::client::Client::connect(
        &serve.addr.to_string(),
        false,
        Duration::from_secs(5),
    )
    .unwrap();
    let t = Instant::now();
    loop {
        let status = match ctl
            .get_one(digiview::protocol::ParamType::SystemStatus.zeroed())
            .unwrap()
        {
            digiview::protocol::Param::SystemStatus(s) => (s.status, s.error),
            other => panic!("{other:?}"),
        };
        if status == (digiview::state::RunStatus::Running as u8, 0) {
            return;
        }
        assert!(t.elapsed() < Duration::from_secs(20), "the head never runs");
        std::thread::sleep(Duration::from_millis(50));
    }
}
