//! The RTSP server (gst-rtsp-server) at `rtsp://HOST:PORT/PATH`: each client gets a media of
//! its own, an appsrc fed with the encoder's access units, so any number of clients watch one
//! encode. A client's stream starts at a key frame: one is asked of the encoder when it joins
//! (the caller is told) and the units before it are not sent to that client, so every
//! player's first frame decodes whole. A client that vanishes is the server's business and
//! costs the frame path nothing. Optional basic authentication. Beside the composed frame,
//! each view has a mount of its own (`PATH/cam0` .. `cam3`, the MAVLink cameras' streams),
//! fed only while someone watches it.

use super::{Codec, Restamp, StreamError};
use crate::supervise::Locked;
use gstreamer as gst;
use gstreamer::glib;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_rtsp_server as rtsp;
use gstreamer_rtsp_server::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RtspConfig {
    /// Address to listen on.
    pub address: String,
    /// TCP port (0 picks a free one, printed at start-up).
    pub port: u16,
    /// Mount path of the stream.
    pub path: String,
    /// Basic authentication: both set, or neither (open).
    pub user: Option<String>,
    pub password: Option<String>,
    /// The streams' coding: the encoder's (`[encoder] codec`), not a key of `[rtsp]`.
    #[serde(skip)]
    pub codec: Codec,
}

impl Default for RtspConfig {
    fn default() -> Self {
        RtspConfig {
            address: "0.0.0.0".into(),
            port: 8554,
            path: "/digiview".into(),
            user: None,
            password: None,
            codec: Codec::H264,
        }
    }
}

/// Why an `[rtsp]` configuration is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RtspConfigError {
    #[error("rtsp path {0:?} must start with / and name a mount point, without spaces")]
    Path(String),
    #[error("rtsp user {0:?} must be non-empty and without ':'")]
    User(String),
    #[error("rtsp user and password go together: set both or neither")]
    HalfCredentials,
}

impl RtspConfig {
    pub fn check(&self) -> Result<(), RtspConfigError> {
        if !self.path.starts_with('/')
            || self.path.len() < 2
            || self.path.contains(char::is_whitespace)
        {
            return Err(RtspConfigError::Path(self.path.clone()));
        }
        match (&self.user, &self.password) {
            (Some(u), Some(_)) if u.is_empty() || u.contains(':') => {
                Err(RtspConfigError::User(u.clone()))
            }
            (Some(_), None) | (None, Some(_)) => Err(RtspConfigError::HalfCredentials),
            _ => Ok(()),
        }
    }
}

/// One client's media: its appsrc, its clock, and whether it still waits for a key frame.
struct Media {
    src: gst_app::AppSrc,
    clock: Restamp,
    started: bool,
}

type Medias = Arc<Mutex<Vec<Media>>>;

/// The views with a mount of their own.
pub const VIEW_MOUNTS: usize = crate::state::MAX_CAMERAS;

/// A view's mount: its clients' media, and whether a joining one owes a key frame.
#[derive(Default)]
struct ViewMount {
    medias: Medias,
    key_wanted: Arc<AtomicBool>,
}

pub struct Rtsp {
    main_loop: glib::MainLoop,
    thread: Option<JoinHandle<()>>,
    medias: Medias,
    views: [ViewMount; VIEW_MOUNTS],
    clients: Arc<AtomicUsize>,
    port: u16,
    path: String,
    codec: Codec,
}

impl Rtsp {
    /// Starts serving; `on_join` runs when a client starts to play (ask for a key frame).
    pub fn start(
        cfg: &RtspConfig,
        on_join: impl Fn() + Send + Sync + 'static,
    ) -> Result<Rtsp, StreamError> {
        cfg.check()?;
        super::init()?;
        let on_join = Arc::new(on_join);
        let server = rtsp::RTSPServer::new();
        server.set_address(&cfg.address);
        server.set_service(&cfg.port.to_string());
        if let (Some(user), Some(password)) = (&cfg.user, &cfg.password) {
            let auth = rtsp::RTSPAuth::new();
            let token = rtsp::RTSPToken::builder()
                .field(rtsp::RTSP_TOKEN_MEDIA_FACTORY_ROLE, "viewer")
                .build();
            auth.add_basic(rtsp::RTSPAuth::make_basic(user, password).as_str(), &token);
            server.set_auth(Some(&auth));
        }
        let medias: Medias = Arc::default();
        let mounts = server.mount_points().ok_or(StreamError::NoMountPoints)?;
        let join = on_join.clone();
        mounts.add_factory(&cfg.path, factory(cfg, &medias, move || join()));
        let views: [ViewMount; VIEW_MOUNTS] = Default::default();
        for (i, view) in views.iter().enumerate() {
            let wanted = view.key_wanted.clone();
            let f = factory(cfg, &view.medias, move || {
                wanted.store(true, Ordering::Relaxed)
            });
            mounts.add_factory(&format!("{}/cam{i}", cfg.path), f);
        }
        let clients = Arc::new(AtomicUsize::new(0));
        {
            let clients = clients.clone();
            server.connect_client_connected(move |_, client| {
                clients.fetch_add(1, Ordering::Relaxed);
                let left = clients.clone();
                client.connect_closed(move |_| {
                    left.fetch_sub(1, Ordering::Relaxed);
                });
                let on_join = on_join.clone();
                client.connect_play_request(move |_, _| on_join());
            });
        }
        let context = glib::MainContext::new();
        let main_loop = glib::MainLoop::new(Some(&context), false);
        let attached = context
            .with_thread_default(|| server.attach(Some(&context)))
            .map_err(StreamError::Context)?;
        attached.map_err(|_| StreamError::Listen(format!("{}:{}", cfg.address, cfg.port)))?;
        let port = server.bound_port() as u16;
        let thread = {
            let main_loop = main_loop.clone();
            std::thread::Builder::new()
                .name("rtsp".into())
                .spawn(move || {
                    let _server = server;
                    let _ = context.with_thread_default(|| main_loop.run());
                })
                .map_err(|e| StreamError::Thread("rtsp", e))?
        };
        Ok(Rtsp {
            main_loop,
            thread: Some(thread),
            medias,
            views,
            clients,
            port,
            path: cfg.path.clone(),
            codec: cfg.codec,
        })
    }

    /// The port it listens on (the real one when 0 was asked for).
    pub fn port(&self) -> u16 {
        self.port
    }

    pub fn path(&self) -> &str {
        &self.path
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.clients.load(Ordering::Relaxed)
    }

    /// Hands one access unit to the watching clients (nothing happens when none watch); a
    /// client that has not had a key frame yet gets none before one.
    pub fn push(&self, au: &gst::Buffer) {
        push(&self.medias, self.codec, au);
    }

    /// Whether anyone watches view `i`'s own stream.
    pub fn view_watched(&self, i: usize) -> bool {
        self.views
            .get(i)
            .is_some_and(|v| !lock(&v.medias).is_empty())
    }

    /// Whether a client joined view `i`'s stream since last asked (it owes a key frame).
    pub fn view_key_wanted(&self, i: usize) -> bool {
        self.views
            .get(i)
            .is_some_and(|v| v.key_wanted.swap(false, Ordering::Relaxed))
    }

    /// As [`Rtsp::push`], for view `i`'s own stream.
    pub fn push_view(&self, i: usize, au: &gst::Buffer) {
        if let Some(v) = self.views.get(i) {
            push(&v.medias, self.codec, au);
        }
    }
}

/// A mount's factory: a media per client, fed by `medias`; `on_join` runs as one starts.
fn factory(
    cfg: &RtspConfig,
    medias: &Medias,
    on_join: impl Fn() + Send + Sync + 'static,
) -> rtsp::RTSPMediaFactory {
    let factory = rtsp::RTSPMediaFactory::new();
    // The access units already carry SPS and PPS before every key frame (the encoder's
    // h264parse puts them there once per unit). Inserting them again here would put them
    // before each slice of a key frame that has several (x264's sliced threads make two),
    // and FFmpeg, VLC and most players then take each slice for a frame of its own.
    factory.set_launch(&format!(
        "( appsrc name=digiview_h264 is-live=true format=time min-latency=0 caps={} \
         ! {} name=pay0 pt=96 )",
        cfg.codec.caps(),
        cfg.codec.payloader()
    ));
    // A media per client: each starts at its own key frame (a shared one would send a
    // joining client the delta frames before it, which players report as errors).
    factory.set_shared(false);
    factory.set_latency(0);
    let medias = medias.clone();
    factory.connect_media_configure(move |_, m| {
        let Some(src) = m
            .element()
            .downcast::<gst::Bin>()
            .ok()
            .and_then(|bin| bin.by_name_recurse_up("digiview_h264"))
            .and_then(|e| e.downcast::<gst_app::AppSrc>().ok())
        else {
            return;
        };
        unsynchronised_sinks(m);
        lock(&medias).push(Media {
            src: src.clone(),
            clock: Restamp::default(),
            started: false,
        });
        let gone = medias.clone();
        m.connect_unprepared(move |_| lock(&gone).retain(|m| m.src != src));
        on_join();
    });
    if cfg.user.is_some() && cfg.password.is_some() {
        factory.add_role_from_structure(
            &gst::Structure::builder("viewer")
                .field(rtsp::RTSP_PERM_MEDIA_FACTORY_ACCESS, true)
                .field(rtsp::RTSP_PERM_MEDIA_FACTORY_CONSTRUCT, true)
                .build(),
        );
    }
    factory
}

/// Makes the sinks a media sends through (an appsink per TCP client, a multiudpsink for
/// UDP) send each packet as it comes. gst-rtsp-server synchronises them to the clock, so
/// every unit waited in the sink for its running time plus the pipeline's latency, holding
/// the media's one streaming thread: about 14 ms a unit here (glass to glass 44 ms, 25 ms
/// without; docs/performance.md). The units come paced by the head already. The server sets
/// the property after adding the sink, so it is turned off at the sink's first buffer.
fn unsynchronised_sinks(media: &rtsp::RTSPMedia) {
    let mut top = media.element().upcast::<gst::Object>();
    while let Some(parent) = top.parent() {
        top = parent;
    }
    let Ok(pipeline) = top.downcast::<gst::Bin>() else {
        return;
    };
    pipeline.connect_deep_element_added(|_, _, e| {
        let sink = e
            .factory()
            .is_some_and(|f| matches!(f.name().as_str(), "appsink" | "multiudpsink"));
        let Some(pad) = e.static_pad("sink").filter(|_| sink) else {
            return;
        };
        let e = e.clone();
        pad.add_probe(
            gst::PadProbeType::BUFFER | gst::PadProbeType::BUFFER_LIST,
            move |_, _| {
                e.set_property("sync", false);
                gst::PadProbeReturn::Remove
            },
        );
    });
}

/// One access unit to every client of a mount that has had its key frame (or gets one now),
/// its access unit delimiter sent at its end (`delimit`). A client has had its key frame only
/// once one was handed to it: one that comes while its media is not running yet is not sent,
/// so the delta frames after it must wait for the next (FFmpeg reports them, without the SPS
/// and PPS before them, as decode errors).
fn push(medias: &Medias, codec: Codec, au: &gst::Buffer) {
    if lock(medias).is_empty() {
        return;
    }
    let au = &super::delimit::delimited_buffer(codec, au);
    let key = !au.flags().contains(gst::BufferFlags::DELTA_UNIT);
    let ready: Vec<_> = lock(medias)
        .iter_mut()
        .filter_map(|m| {
            if !(m.started || key) {
                return None;
            }
            let now = m.src.current_running_time()?;
            let unit = m.clock.restamped(au, now)?;
            m.started = true;
            Some((m.src.clone(), unit))
        })
        .collect();
    for (src, buffer) in ready {
        let _ = src.push_buffer(buffer);
    }
}

fn lock(medias: &Medias) -> std::sync::MutexGuard<'_, Vec<Media>> {
    medias.locked()
}

impl Drop for Rtsp {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            // A quit that comes before the loop runs is lost (a server dropped as soon as
            // it started, when start-up fails after it): ask until the loop has ended.
            while !t.is_finished() {
                self.main_loop.quit();
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(key: bool) -> gst::Buffer {
        let mut b = gst::Buffer::from_slice(vec![0u8, 0, 0, 1, 0x65]);
        let m = b.get_mut().unwrap();
        m.set_pts(gst::ClockTime::ZERO);
        if !key {
            m.set_flags(gst::BufferFlags::DELTA_UNIT);
        }
        b
    }

    #[test]
    fn a_client_whose_key_frame_came_before_its_media_ran_gets_no_delta_frames_before_the_next() {
        crate::gst::init().unwrap();
        let pipeline = gst::parse::launch("appsrc name=src is-live=true format=time ! fakesink")
            .unwrap()
            .downcast::<gst::Pipeline>()
            .unwrap();
        let src = pipeline
            .by_name("src")
            .unwrap()
            .downcast::<gst_app::AppSrc>()
            .unwrap();
        let medias: Medias = Arc::default();
        lock(&medias).push(Media {
            src: src.clone(),
            clock: Restamp::default(),
            started: false,
        });
        let started = || lock(&medias)[0].started;

        // Not running yet: the key frame cannot be handed over.
        push(&medias, Codec::H264, &unit(true));
        assert!(
            !started(),
            "a key frame its client never got counts as its start"
        );
        pipeline.set_state(gst::State::Playing).unwrap();
        let t = std::time::Instant::now();
        while src.current_running_time().is_none() {
            assert!(t.elapsed().as_secs() < 5, "the pipeline never runs");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        push(&medias, Codec::H264, &unit(false));
        assert!(!started(), "a delta frame went out before any key frame");
        push(&medias, Codec::H264, &unit(true));
        assert!(started(), "the next key frame starts the client");
        pipeline.set_state(gst::State::Null).unwrap();
    }
}
