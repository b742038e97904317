//! Publishing: the encoder's access units pushed to a media relay, so that viewers beyond a
//! handful pull from the relay rather than over the drone's radio link. `rtsp://` publishes
//! with RTSP RECORD (`rtspclientsink`, as MediaMTX and gst-rtsp-server accept), `srt://` as
//! MPEG-TS in SRT caller mode (`srtsink`), `udp://` as MPEG-TS in UDP datagrams to a host or
//! a multicast group (`udpsink`). The MPEG-TS outputs carry each frame's KLV metadata (MISB
//! ST 0601, asynchronous: ST 1402's private data stream) stamped with its frame's time. A
//! view's own stream is published the same way (`CAMERA=URL`, [`view_target`]).
//! Each relay has a thread of its own that connects,
//! and reconnects with back-off whenever the relay goes away or is not there yet; the frame
//! path only hands units over (it never waits on a relay), and the built-in RTSP server is
//! not touched by any of it.

use super::{AccessUnit, Codec, Restamp, StreamError};
use crate::gst::{GstError, element, element_error, launch};
use crate::supervise::{self, Backoff, FailureLog, Fault, Locked};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tracing::{info, warn};

/// Waits between connections: 1 s doubling to 30 s, from 1 s again after a connection that
/// held for [`HELD`].
const BACKOFF: Backoff = Backoff::new(Duration::from_secs(1), Duration::from_secs(30));
const HELD: Duration = Duration::from_secs(10);
/// How long units must flow without an error before the relay counts as taking them.
const TAKEN: Duration = Duration::from_secs(1);
/// Units waiting for the relay; beyond them, units are dropped up to the next key frame (a
/// relay slower than the stream costs the relay's viewers frames, not the drone memory).
const MAX_QUEUED: u64 = 30;

/// Where to publish, checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PublishTarget {
    pub url: String,
    kind: Kind,
    /// The stream's coding, the encoder's.
    pub codec: Codec,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Rtsp,
    Srt,
    Udp,
}

/// Why a publish URL is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PublishError {
    #[error("publish URL {0:?}: not a URL")]
    NotAUrl(String),
    #[error("publish URL {0:?}: the scheme must be rtsp, rtsps, rtspt, srt or udp")]
    Scheme(String),
    #[error("publish URL {0:?} names no host")]
    NoHost(String),
    #[error("publish URL {0:?}: an SRT or UDP URL needs a port")]
    NoPort(String),
    #[error("publish URL {0:?}: an RTSP URL needs a path to publish to (rtsp://HOST:PORT/PATH)")]
    NoPath(String),
    #[error("view relay {0:?}: give CAMERA=URL, the camera 0..=3 (2=udp://239.1.2.3:5602)")]
    NotAView(String),
}

/// A view's own stream's relay, from `CAMERA=URL`: the camera and the target.
pub fn view_target(text: &str) -> Result<(usize, PublishTarget), PublishError> {
    let not_a_view = || PublishError::NotAView(text.to_string());
    let (cam, url) = text.split_once('=').ok_or_else(not_a_view)?;
    let cam: usize = cam.trim().parse().map_err(|_| not_a_view())?;
    if cam >= super::rtsp::VIEW_MOUNTS {
        return Err(not_a_view());
    }
    Ok((cam, url.parse()?))
}

impl std::str::FromStr for PublishTarget {
    type Err = PublishError;
    fn from_str(url: &str) -> Result<PublishTarget, PublishError> {
        let parsed = glib::Uri::parse(url, glib::UriFlags::NONE)
            .map_err(|_| PublishError::NotAUrl(url.to_string()))?;
        let kind = match parsed.scheme().as_str() {
            "rtsp" | "rtsps" | "rtspt" => Kind::Rtsp,
            "srt" => Kind::Srt,
            "udp" => Kind::Udp,
            _ => return Err(PublishError::Scheme(url.to_string())),
        };
        if parsed.host().is_none_or(|h| h.is_empty()) {
            return Err(PublishError::NoHost(url.to_string()));
        }
        if matches!(kind, Kind::Srt | Kind::Udp) && parsed.port() < 0 {
            return Err(PublishError::NoPort(url.to_string()));
        }
        if kind == Kind::Rtsp && parsed.path().trim_matches('/').is_empty() {
            return Err(PublishError::NoPath(url.to_string()));
        }
        Ok(PublishTarget {
            url: url.to_string(),
            kind,
            codec: Codec::H264,
        })
    }
}

impl PublishTarget {
    /// The GStreamer element the target needs.
    fn sink(&self) -> &'static str {
        match self.kind {
            Kind::Rtsp => "rtspclientsink",
            Kind::Srt => "srtsink",
            Kind::Udp => "udpsink",
        }
    }

    /// Whether the target is MPEG-TS, which carries the KLV metadata.
    fn muxed(&self) -> bool {
        self.kind != Kind::Rtsp
    }

    fn description(&self) -> String {
        let src = format!(
            "appsrc name=src is-live=true format=time max-buffers={MAX_QUEUED} caps={} ! {}",
            self.codec.caps(),
            self.codec.parser()
        );
        let klv = super::klv::muxer_input(true);
        let mux = "mpegtsmux name=mux alignment=7";
        match self.kind {
            Kind::Rtsp => format!("{src} ! rtspclientsink name=sink latency=0 protocols=tcp"),
            Kind::Srt => format!("{src} ! {mux} ! srtsink name=sink mode=caller {klv}"),
            Kind::Udp => format!("{src} ! {mux} ! udpsink name=sink sync=false {klv}"),
        }
    }
}

/// The pipeline to the relay while one is up.
struct Link {
    src: gst_app::AppSrc,
    /// The KLV metadata's, in the MPEG-TS outputs.
    klv: Option<gst_app::AppSrc>,
    clock: Restamp,
    /// Units are dropped until a key frame (at the start, and after a unit was dropped).
    need_key: bool,
}

/// Publishes to one relay until dropped.
pub struct Publisher {
    target: PublishTarget,
    link: Arc<Mutex<Option<Link>>>,
    connected: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Publisher {
    /// Starts publishing to `target` (connecting in the background, on a thread supervised
    /// as every service's is, its failures told to `report`); `want_key` is called whenever a
    /// connection is made (ask the encoder for a key frame: the relay's stream starts at
    /// one). Fails at once only when the target's element is not installed.
    pub fn start(
        target: PublishTarget,
        report: Arc<dyn FailureLog>,
        want_key: impl Fn() + Send + Sync + 'static,
    ) -> Result<Publisher, StreamError> {
        super::init()?;
        if gst::ElementFactory::find(target.sink()).is_none() {
            return Err(StreamError::Publish {
                url: target.url.clone(),
                source: GstError::NoElement(format!(
                    "{} (not installed; scripts/setup.sh installs it)",
                    target.sink()
                )),
            });
        }
        let link: Arc<Mutex<Option<Link>>> = Arc::default();
        let connected = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (target, link, connected, stop) = (
                target.clone(),
                link.clone(),
                connected.clone(),
                stop.clone(),
            );
            let (until, fault) = (stop.clone(), Fault::for_service("publish"));
            supervise::spawn(report, "publish", until, move || {
                keep_publishing(&target, &link, &connected, &stop, &want_key, &fault)
            })
            .map_err(|e| StreamError::Thread("publish", e))?
        };
        Ok(Publisher {
            target,
            link,
            connected,
            stop,
            thread: Some(thread),
        })
    }

    pub fn url(&self) -> &str {
        &self.target.url
    }

    /// Whether the relay is taking the stream now.
    pub fn connected(&self) -> bool {
        self.connected.load(Ordering::Relaxed)
    }

    /// Hands one access unit over; never waits. Returns true when it starts dropping units
    /// because the relay is behind: ask the encoder for a key frame to resume at.
    pub fn push(&self, au: &AccessUnit) -> bool {
        let (src, buffer, klv) = {
            let mut link = self.link.locked();
            let Some(l) = link.as_mut() else {
                return false;
            };
            if l.src.property::<u64>("current-level-buffers") >= MAX_QUEUED {
                return !std::mem::replace(&mut l.need_key, true);
            }
            if l.need_key && !au.key {
                return false;
            }
            l.need_key = false;
            let now = l.src.current_running_time().unwrap_or(gst::ClockTime::ZERO);
            let Some(buffer) = l.clock.restamped(&au.buffer, now) else {
                return false;
            };
            // The frame's KLV, stamped as its picture is.
            let klv = l
                .klv
                .clone()
                .zip(au.klv.as_ref())
                .map(|(src, packet)| (src, super::klv::buffer(packet, buffer.pts())));
            (l.src.clone(), buffer, klv)
        };
        let _ = src.push_buffer(buffer);
        if let Some((src, b)) = klv {
            let _ = src.push_buffer(b);
        }
        false
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Connects, watches the link until it fails or `stop`, waits with back-off, again.
fn keep_publishing(
    target: &PublishTarget,
    link: &Mutex<Option<Link>>,
    connected: &AtomicBool,
    stop: &AtomicBool,
    want_key: &(dyn Fn() + Send + Sync),
    fault: &Fault,
) {
    let mut backoff = BACKOFF;
    // Started again after a panic: the last run's pipeline is let go first.
    *link.locked() = None;
    connected.store(false, Ordering::Relaxed);
    while !stop.load(Ordering::Relaxed) {
        let started = Instant::now();
        let result = publish_once(target, link, connected, stop, want_key, fault);
        *link.locked() = None;
        let was_connected = connected.swap(false, Ordering::Relaxed);
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if was_connected && started.elapsed() >= HELD {
            backoff.held();
        }
        let why = match result {
            Ok(()) => "the relay ended the stream".to_string(),
            Err(e) => e.to_string(),
        };
        let wait = backoff.failed();
        warn!(
            "publish {}: {why}; retrying in {} s",
            target.url,
            wait.as_secs()
        );
        supervise::sleep_unless(stop, wait);
    }
}

/// One connection: runs until the pipeline fails or ends (the error), or `stop` (Ok).
fn publish_once(
    target: &PublishTarget,
    link: &Mutex<Option<Link>>,
    connected: &AtomicBool,
    stop: &AtomicBool,
    want_key: &(dyn Fn() + Send + Sync),
    fault: &Fault,
) -> Result<(), GstError> {
    let pipeline = launch(&target.description())?;
    // However this ends, a panic included, the pipeline stops and no unit is handed to it.
    let _stopped = Stopped(&pipeline, link);
    let sink: gst::Element = element(&pipeline, "sink")?;
    match target.kind {
        Kind::Rtsp => sink.set_property("location", &target.url),
        Kind::Srt => sink.set_property("uri", &target.url),
        Kind::Udp => {
            let uri = glib::Uri::parse(&target.url, glib::UriFlags::NONE)
                .map_err(|e| GstError::Refused(e.to_string()))?;
            sink.set_property("host", uri.host().unwrap_or_default().as_str());
            sink.set_property("port", uri.port());
        }
    }
    let src: gst_app::AppSrc = element(&pipeline, "src")?;
    let klv: Option<gst_app::AppSrc> = match target.muxed() {
        true => Some(element(&pipeline, "klv")?),
        false => None,
    };
    let bus = pipeline.bus().ok_or(GstError::NoBus)?;
    (|| {
        pipeline
            .set_state(gst::State::Playing)
            .map_err(|_| GstError::Refused(format!("cannot start publishing to {}", target.url)))?;
        // Units flow from now: the relay's session is described from the first ones.
        *link.locked() = Some(Link {
            src,
            klv,
            clock: Restamp::default(),
            need_key: true,
        });
        want_key();
        // The relay took the stream once units have flowed a while with no error (the sinks
        // reach PLAYING before they know: a relay that is not there fails right after).
        let mut playing_since = None;
        while !stop.load(Ordering::Relaxed) {
            fault.check("publish");
            if playing_since.is_some_and(|t: Instant| t.elapsed() >= TAKEN)
                && !connected.swap(true, Ordering::Relaxed)
            {
                info!("publish {}: publishing", target.url);
            }
            let Some(msg) = bus.timed_pop(gst::ClockTime::from_mseconds(100)) else {
                continue;
            };
            match msg.view() {
                gst::MessageView::Error(e) => return Err(element_error(e)),
                gst::MessageView::Eos(_) => return Ok(()),
                gst::MessageView::StateChanged(s)
                    if s.src() == Some(pipeline.upcast_ref())
                        && s.current() == gst::State::Playing =>
                {
                    playing_since.get_or_insert_with(Instant::now);
                }
                _ => {}
            }
        }
        Ok(())
    })()
}

/// Stops a publishing pipeline, and the hand-over to it, when dropped.
struct Stopped<'a>(&'a gst::Pipeline, &'a Mutex<Option<Link>>);

impl Drop for Stopped<'_> {
    fn drop(&mut self) {
        *self.1.locked() = None;
        let _ = self.0.set_state(gst::State::Null);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn publish_urls_are_checked() {
        for ok in [
            "rtsp://relay.local:8554/drone1",
            "rtsp://10.0.0.2/live/cam",
            "rtsps://user:pw@relay:8322/a",
            "srt://10.0.0.2:8890?streamid=publish:drone1",
            "udp://239.1.2.3:5600",
            "udp://10.0.0.2:5600",
        ] {
            assert!(ok.parse::<PublishTarget>().is_ok(), "{ok}");
        }
        for (bad, why) in [
            ("relay:8554/x", "scheme"),
            ("http://relay/x", "scheme"),
            ("rtsp:///x", "no host"),
            ("rtsp://relay:8554", "a path"),
            ("rtsp://relay:8554/", "a path"),
            ("srt://relay", "a port"),
            ("udp://relay", "a port"),
            ("not a url", "URL"),
        ] {
            let e = bad.parse::<PublishTarget>().unwrap_err().to_string();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }
}
