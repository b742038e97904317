//! A media relay in the test, as users run MediaMTX or gst-rtsp-server: an RTSP server whose
//! mount point takes RECORD (a publisher pushes to it), decoding what arrives and counting
//! the frames. It can be stopped (clients cut off, the port closed) and started again on the
//! same port.

use gstreamer as gst;
use gstreamer::glib;
use gstreamer::prelude::*;
use gstreamer_rtsp_server as rtsp;
use gstreamer_rtsp_server::prelude::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A relay a test publishes to: started on a port (0: a free one), counting decoded frames.
pub trait Ingest: Sized {
    fn start(port: u16, frames: Arc<AtomicUsize>) -> Self;
    fn url(&self) -> String;
    fn port(&self) -> u16;
}

pub struct Relay {
    port: u16,
    main_loop: glib::MainLoop,
    thread: Option<JoinHandle<()>>,
}

impl Ingest for Relay {
    /// Listens on `port` at `/relay`.
    fn start(port: u16, frames: Arc<AtomicUsize>) -> Relay {
        gst::init().unwrap();
        let server = rtsp::RTSPServer::new();
        server.set_address("127.0.0.1");
        server.set_service(&port.to_string());
        let factory = rtsp::RTSPMediaFactory::new();
        factory.set_transport_mode(rtsp::RTSPTransportMode::RECORD);
        factory.set_launch(
            "( rtph264depay name=depay0 ! h264parse ! avdec_h264 ! fakesink name=sink \
             signal-handoffs=true sync=false )",
        );
        {
            let frames = frames.clone();
            factory.connect_media_configure(move |_, media| {
                let bin = media.element().downcast::<gst::Bin>().unwrap();
                let sink = bin.by_name_recurse_up("sink").unwrap();
                let frames = frames.clone();
                sink.connect("handoff", false, move |_| {
                    frames.fetch_add(1, Ordering::Relaxed);
                    None
                });
            });
        }
        server
            .mount_points()
            .unwrap()
            .add_factory("/relay", factory);
        let context = glib::MainContext::new();
        let main_loop = glib::MainLoop::new(Some(&context), false);
        let source = context
            .with_thread_default(|| server.attach(Some(&context)))
            .unwrap()
            .expect("the relay's port is free");
        let port = server.bound_port() as u16;
        let thread = {
            let main_loop = main_loop.clone();
            std::thread::spawn(move || {
                let _ = context.with_thread_default(|| main_loop.run());
                // Stopped: cut every client off and close the listening socket.
                server.client_filter(Some(&mut |_, _| rtsp::RTSPFilterResult::Remove));
                if let Some(s) = context.find_source_by_id(&source) {
                    s.destroy();
                }
                let _ = context.with_thread_default(|| while context.iteration(false) {});
            })
        };
        Relay {
            port,
            main_loop,
            thread: Some(thread),
        }
    }

    fn url(&self) -> String {
        format!("rtsp://127.0.0.1:{}/relay", self.port)
    }

    fn port(&self) -> u16 {
        self.port
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.main_loop.quit();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// An SRT ingest as relays run one: a listener taking MPEG-TS, decoded, frames counted.
pub struct SrtRelay {
    port: u16,
    pipeline: gst::Pipeline,
}

impl Ingest for SrtRelay {
    fn start(port: u16, frames: Arc<AtomicUsize>) -> SrtRelay {
        gst::init().unwrap();
        let port = match port {
            0 => std::net::UdpSocket::bind("127.0.0.1:0")
                .unwrap()
                .local_addr()
                .unwrap()
                .port(),
            p => p,
        };
        let pipeline = gst::parse::launch(&format!(
            "srtsrc uri=srt://127.0.0.1:{port}?mode=listener ! tsdemux ! h264parse ! avdec_h264 \
             ! fakesink name=sink signal-handoffs=true sync=false"
        ))
        .unwrap()
        .downcast::<gst::Pipeline>()
        .unwrap();
        pipeline
            .by_name("sink")
            .unwrap()
            .connect("handoff", false, move |_| {
                frames.fetch_add(1, Ordering::Relaxed);
                None
            });
        pipeline.set_state(gst::State::Playing).unwrap();
        SrtRelay { port, pipeline }
    }

    fn url(&self) -> String {
        format!("srt://127.0.0.1:{}", self.port)
    }

    fn port(&self) -> u16 {
        self.port
    }
}

impl Drop for SrtRelay {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// Waits until `frames` reaches `want`; false after `limit`.
pub fn wait_count(frames: &AtomicUsize, want: usize, limit: Duration) -> bool {
    let t = Instant::now();
    while t.elapsed() < limit {
        if frames.load(Ordering::Relaxed) >= want {
            return true;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    false
}
