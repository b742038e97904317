//! `digiview readout`: asks a running head to measure its camera's rolling-shutter readout
//! (`POST /api/readout/estimate`), shows its progress while the vehicle turns, and prints the
//! readout to put in `[readout] time_ms` (docs/serve.md, "Measuring the readout").

use anyhow::{Context, Result, bail};
use base64::Engine;
use clap::Args;
use http_body_util::{BodyExt, Empty};
use hyper::body::Bytes;
use hyper_util::rt::TokioIo;
use serde_json::Value;
use std::time::Duration;

#[derive(Args, Debug)]
pub struct ReadoutCmdArgs {
    /// The head's web server.
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    http: String,
    /// Seconds of frames to measure over while the vehicle turns, 1 to 60.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// USER:PASSWORD, where the head's page asks for them (its RTSP login).
    #[arg(long)]
    login: Option<String>,
    /// Print the head's whole answer as JSON instead.
    #[arg(long)]
    json: bool,
}

/// One request: the status code and the JSON body.
async fn request(args: &ReadoutCmdArgs, method: &str, query: &str) -> Result<(u16, Value)> {
    let uri: hyper::Uri = args
        .http
        .parse()
        .with_context(|| format!("--http {}", args.http))?;
    let (Some("http"), Some(authority)) = (uri.scheme_str(), uri.authority()) else {
        bail!("--http {}: give http://HOST:PORT", args.http);
    };
    let port = authority.port_u16().unwrap_or(80);
    let stream = tokio::net::TcpStream::connect((authority.host(), port))
        .await
        .with_context(|| format!("connecting to {authority}"))?;
    let (mut sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(stream))
        .await
        .context("HTTP handshake")?;
    tokio::spawn(connection);
    let mut req = hyper::Request::builder()
        .method(method)
        .uri(format!("/api/readout/estimate{query}"))
        .header(hyper::header::HOST, authority.as_str());
    if let Some(login) = &args.login {
        let token = base64::engine::general_purpose::STANDARD.encode(login);
        req = req.header(hyper::header::AUTHORIZATION, format!("Basic {token}"));
    }
    let reply = sender
        .send_request(req.body(Empty::<Bytes>::new())?)
        .await?;
    let status = reply.status().as_u16();
    let body = reply.into_body().collect().await?.to_bytes();
    let value = serde_json::from_slice(&body)
        .with_context(|| format!("HTTP {status}: {}", String::from_utf8_lossy(&body)))?;
    Ok((status, value))
}

pub fn run(args: ReadoutCmdArgs) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    runtime.block_on(measure(&args))
}

async fn measure(args: &ReadoutCmdArgs) -> Result<()> {
    let (status, body) = request(args, "POST", &format!("?seconds={}", args.seconds)).await?;
    if status != 202 {
        let why = body["error"].as_str().unwrap_or("no reason given");
        bail!("the head did not start the estimate (HTTP {status}): {why}");
    }
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {pos}/{len}")
            .expect("valid template"),
    );
    let done = loop {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let (_, s) = request(args, "GET", "").await?;
        match s["state"].as_str() {
            Some("collecting") => {
                bar.set_message("collecting frames, keep turning (tenths of a second)");
                bar.set_length((s["seconds"].as_f64().unwrap_or(0.0) * 10.0) as u64);
                bar.set_position((s["collected_s"].as_f64().unwrap_or(0.0) * 10.0) as u64);
            }
            Some("fitting") => {
                bar.set_message("fitting");
                bar.set_length(s["steps"][1].as_u64().unwrap_or(0));
                bar.set_position(s["steps"][0].as_u64().unwrap_or(0));
            }
            _ => break s,
        }
    };
    bar.finish_and_clear();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&done)?);
    }
    let fit = &done["fit"];
    let Some(ms) = fit["readout_ms"].as_f64() else {
        let why = done["error"].as_str().unwrap_or("no answer");
        bail!("the estimate failed: {why}");
    };
    if !args.json {
        println!(
            "readout {ms:.1} ms ({} frames, {} pairs; luma disagreement {:.2}, {:.2} with none)",
            done["frames"],
            fit["pairs"],
            fit["disagreement"].as_f64().unwrap_or(f64::NAN),
            fit["disagreement_global"].as_f64().unwrap_or(f64::NAN),
        );
        println!("in digiview.toml:\n[readout]\ntime_ms = {ms:.1}");
    }
    Ok(())
}
