//! The control server: the protocol over TCP and UDP on one port (protocol.md, "Transport").
//!
//! Each TCP client gets a reader task and a writer task joined by a bounded queue of reply
//! frames, so a client that stalls mid-frame only stalls its own reader, and one that never
//! reads its replies fills its own queue and, when it stays full, is dropped; nobody else
//! waits. UDP datagrams
//! are answered one by one from a single task. A permitted QUIT, SIGINT or SIGTERM stops
//! everything: the listeners close, every connection sends what it has queued and closes.
//! The server is supervised as every service of `serve` is (`crate::supervise`, service
//! `control`): a client's task that panics is reported and only that client is dropped, the
//! UDP task that panics is reported and started again on the same port, and repeated
//! failures give the service up, which ends `serve` non-zero.

use super::Controller;
use crate::protocol::FRAME_LEN;
use crate::supervise::{self, FailureLog, Failures, Fault};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::OwnedWriteHalf;
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinSet;
use tracing::{debug, info, warn};

/// Reply frames queued per TCP client.
pub const REPLY_QUEUE: usize = 4096;
/// How long a client's reply queue may stay full before the client is dropped as one that
/// does not read its replies.
pub const STALLED: Duration = Duration::from_secs(2);
/// Consecutive bad checksums after which a TCP stream is taken as misaligned and closed.
pub const MAX_BAD_FRAMES: u32 = 16;
/// How long connections get to send their queued replies when the server stops.
const DRAIN: Duration = Duration::from_secs(2);

/// Binds TCP and UDP on the same address. With port 0 the system picks a port free for
/// both (it retries a few times if the UDP side of the TCP port is taken).
pub async fn bind(addr: SocketAddr) -> std::io::Result<(TcpListener, UdpSocket)> {
    let mut last = None;
    for _ in 0..if addr.port() == 0 { 20 } else { 1 } {
        let tcp = TcpListener::bind(addr).await?;
        match UdpSocket::bind(tcp.local_addr()?).await {
            Ok(udp) => return Ok((tcp, udp)),
            Err(e) => last = Some(e),
        }
    }
    Err(last.expect("tried at least once"))
}

/// Stops the server when told to (QUIT, a signal, or the owner).
#[derive(Clone)]
pub struct Shutdown {
    tx: Arc<watch::Sender<bool>>,
}

impl Default for Shutdown {
    fn default() -> Self {
        Shutdown {
            tx: Arc::new(watch::channel(false).0),
        }
    }
}

impl Shutdown {
    pub fn trigger(&self) {
        self.tx.send_replace(true);
    }
    pub fn is_triggered(&self) -> bool {
        *self.tx.borrow()
    }
    /// Resolves once the shutdown has been triggered.
    pub async fn wait(&self) {
        let mut rx = self.tx.subscribe();
        let _ = rx.wait_for(|stop| *stop).await;
    }
}

/// Serves until `shutdown` triggers, then lets connections drain and returns.
pub async fn run(
    tcp: TcpListener,
    udp: UdpSocket,
    controller: Arc<Controller>,
    shutdown: Shutdown,
) -> std::io::Result<()> {
    info!("control server on {} (tcp and udp)", tcp.local_addr()?);
    let udp_task = tokio::spawn(supervise_udp(udp, controller.clone(), shutdown.clone()));
    let mut connections = JoinSet::new();
    let mut failures = Failures::default();
    loop {
        tokio::select! {
            accepted = tcp.accept() => match accepted {
                Ok((stream, peer)) => {
                    debug!(%peer, "control client connected");
                    let _ = stream.set_nodelay(true);
                    connections.spawn(serve_tcp(stream, peer, controller.clone(), shutdown.clone()));
                }
                // Out of descriptors and the like: keep serving the clients we have.
                Err(e) => {
                    warn!("accepting a control client failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            },
            _ = shutdown.wait() => break,
            Some(joined) = connections.join_next(), if !connections.is_empty() => {
                // A client's task that panicked: that client is gone, the server goes on.
                if let Err(e) = joined
                    && e.is_panic()
                {
                    let why = supervise::panic_message(e.into_panic().as_ref());
                    let report = &*controller.report;
                    if failures.given_up(report, SERVICE, &format!("a client's task: {why}")) {
                        break;
                    }
                    report.restarted(SERVICE);
                }
            }
        }
    }
    drop(tcp);
    let _ = tokio::time::timeout(DRAIN, async {
        while connections.join_next().await.is_some() {}
    })
    .await;
    connections.abort_all();
    udp_task.abort();
    info!("control server stopped");
    Ok(())
}

async fn serve_tcp(
    stream: TcpStream,
    peer: SocketAddr,
    controller: Arc<Controller>,
    shutdown: Shutdown,
) {
    let (rd, wr) = stream.into_split();
    let (tx, rx) = mpsc::channel::<[u8; FRAME_LEN]>(REPLY_QUEUE);
    let mut writer = tokio::spawn(write_replies(wr, rx));
    let mut rd = BufReader::with_capacity(64 * 1024, rd);
    let mut frame = [0u8; FRAME_LEN];
    let mut bad_in_a_row = 0;
    let fault = Fault::for_service(SERVICE);
    loop {
        tokio::select! {
            read = rd.read_exact(&mut frame) => if read.is_err() { break },
            _ = shutdown.wait() => break,
        }
        fault.check(SERVICE);
        let outcome = controller.handle(&frame, peer.ip());
        bad_in_a_row = if outcome.bad_checksum {
            bad_in_a_row + 1
        } else {
            0
        };
        for reply in &outcome.replies {
            if !queue(&tx, reply.encode()).await {
                warn!(%peer, "dropping control client: it does not read its replies");
                writer.abort();
                return;
            }
        }
        if outcome.quit {
            info!(%peer, "QUIT received: stopping");
            shutdown.trigger();
            break;
        }
        if bad_in_a_row >= MAX_BAD_FRAMES {
            warn!(%peer, "closing control connection: {MAX_BAD_FRAMES} bad frames in a row");
            break;
        }
    }
    drop(tx);
    if tokio::time::timeout(DRAIN, &mut writer).await.is_err() {
        writer.abort();
    }
    debug!(%peer, "control client gone");
}

/// Queues a reply. A full queue holds this client's reader back (a fast pipelining client
/// just waits for its replies to drain); if it stays full for [`STALLED`], the client is not
/// reading and `false` says to drop it.
async fn queue(tx: &mpsc::Sender<[u8; FRAME_LEN]>, frame: [u8; FRAME_LEN]) -> bool {
    match tx.try_send(frame) {
        Ok(()) => true,
        Err(mpsc::error::TrySendError::Full(frame)) => {
            matches!(
                tokio::time::timeout(STALLED, tx.send(frame)).await,
                Ok(Ok(()))
            )
        }
        Err(mpsc::error::TrySendError::Closed(_)) => false,
    }
}

/// Sends queued replies, batching whatever is ready into one write.
async fn write_replies(mut wr: OwnedWriteHalf, mut rx: mpsc::Receiver<[u8; FRAME_LEN]>) {
    let mut batch = Vec::with_capacity(64 * FRAME_LEN);
    while let Some(first) = rx.recv().await {
        batch.clear();
        batch.extend_from_slice(&first);
        while batch.len() < 64 * FRAME_LEN {
            match rx.try_recv() {
                Ok(f) => batch.extend_from_slice(&f),
                Err(_) => break,
            }
        }
        if wr.write_all(&batch).await.is_err() {
            return;
        }
    }
    let _ = wr.shutdown().await;
}

/// The service's name in `/api/status`, SYSTEM_STATUS and `DIGIVIEW_FAULT`.
const SERVICE: &str = "control";

/// Serves UDP on `udp`, and on the same address again after a panic
/// ([`supervise::keep_serving`]), until stopped or given up.
async fn supervise_udp(udp: UdpSocket, controller: Arc<Controller>, shutdown: Shutdown) {
    let Ok(address) = udp.local_addr() else {
        return;
    };
    let serve = |socket| {
        let (controller, shutdown) = (controller.clone(), shutdown.clone());
        async move {
            serve_udp(socket, controller, shutdown).await;
            Ok::<(), std::convert::Infallible>(())
        }
    };
    let stopped = || shutdown.is_triggered();
    let report = &*controller.report;
    let (first, bind) = ((udp, address), UdpSocket::bind::<SocketAddr>);
    supervise::keep_serving(report, SERVICE, "udp: ", first, bind, serve, stopped).await;
}

async fn serve_udp(udp: UdpSocket, controller: Arc<Controller>, shutdown: Shutdown) {
    // Larger than a frame, so an oversized datagram is seen as such, not truncated to 80.
    let mut buf = vec![0u8; 64 * 1024];
    let fault = Fault::for_service(SERVICE);
    loop {
        let (n, peer) = tokio::select! {
            r = udp.recv_from(&mut buf) => match r {
                Ok(x) => x,
                // ICMP errors from earlier replies surface here on some systems; ignore them.
                Err(e) => { debug!("udp receive: {e}"); continue }
            },
            _ = shutdown.wait() => return,
        };
        fault.check(SERVICE);
        // A datagram of the wrong length decodes to DATA_ERROR with param_type 0.
        let outcome = controller.handle(&buf[..n], peer.ip());
        for reply in &outcome.replies {
            if let Err(e) = udp.send_to(&reply.encode(), peer).await {
                debug!(%peer, "udp send: {e}");
                break;
            }
        }
        if outcome.quit {
            info!(%peer, "QUIT received over UDP: stopping");
            shutdown.trigger();
            return;
        }
    }
}

/// Triggers `shutdown` on SIGINT or SIGTERM.
pub async fn stop_on_signals(shutdown: Shutdown) {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        let mut term = match signal(SignalKind::terminate()) {
            Ok(s) => s,
            Err(e) => {
                warn!("cannot watch SIGTERM: {e}");
                let _ = ctrl_c.await;
                shutdown.trigger();
                return;
            }
        };
        let signal = tokio::select! {
            _ = ctrl_c => "SIGINT",
            _ = term.recv() => "SIGTERM",
            _ = shutdown.wait() => return,
        };
        // Stop first: nothing the log does may keep the server running.
        shutdown.trigger();
        info!("{signal}: stopping");
    }
    #[cfg(not(unix))]
    {
        tokio::select! {
            _ = ctrl_c => {}
            _ = shutdown.wait() => return,
        }
        shutdown.trigger();
        info!("SIGINT: stopping");
    }
}
