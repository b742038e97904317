//! `digiview serve`: the running system. With `--no-video` only the control server runs, on
//! the live state, so the protocol can be exercised on any machine.

use super::StateArgs;
use crate::control::Controller;
use crate::control::live::{Live, NoVideo};
use crate::control::permissions::{Allow, Permissions};
use crate::control::server::{self, Shutdown};
use crate::lens::LensCal;
use anyhow::{Context, Result, bail};
use clap::Args;
use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Run only the control server on the live state: no camera, renderer or encoder.
    #[arg(long)]
    no_video: bool,
    /// Where the control protocol listens, TCP and UDP (port 0 picks a free port).
    #[arg(long, default_value = "0.0.0.0:5010")]
    control: SocketAddr,
    /// Who may SET: `any`, `none`, `loopback`, or addresses and CIDR ranges, comma-separated.
    #[arg(long, default_value = "any")]
    allow_set: Allow,
    /// Who may QUIT (same forms as --allow-set).
    #[arg(long, default_value = "loopback")]
    allow_quit: Allow,
    #[command(flatten)]
    state: StateArgs,
}

pub fn serve(lens_cal: &Path, args: ServeArgs) -> Result<()> {
    if !args.no_video {
        bail!(
            "the video pipeline (camera → GPU → H.264 → RTSP) is not part of this build yet; \
             `digiview serve --no-video` runs the control server alone"
        );
    }
    let cal = LensCal::load(lens_cal)?;
    let state = args.state.state(&cal)?;
    let live = Live::new(state, &cal, Box::new(NoVideo)).map_err(anyhow::Error::msg)?;
    let controller = Arc::new(Controller::new(
        Arc::new(live),
        Permissions {
            set: args.allow_set,
            quit: args.allow_quit,
        },
    ));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("control")
        .enable_all()
        .build()
        .context("starting the control server's runtime")?;
    runtime.block_on(async {
        let (tcp, udp) = server::bind(args.control)
            .await
            .with_context(|| format!("cannot listen on {} (tcp and udp)", args.control))?;
        // One line on stdout that scripts (and the tests) read to find the port.
        println!("control listening on {}", tcp.local_addr()?);
        std::io::stdout().flush()?;
        let shutdown = Shutdown::default();
        tokio::spawn(server::stop_on_signals(shutdown.clone()));
        server::run(tcp, udp, controller, shutdown).await?;
        anyhow::Ok(())
    })
}
