//! `digiview ctl`: get, set, watch and quit over the control protocol, for people (fields
//! with units) and scripts (`--json`, one object per line).

use crate::control::client::{Client, ClientError, query};
use crate::protocol::edit::{self, Given};
use crate::protocol::text::{annotate, describe};
use crate::protocol::{Param, ParamType, Unit};
use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::time::Duration;

#[derive(Args, Debug)]
pub struct CtlArgs {
    /// The control server.
    #[arg(long, env = "DIGIVIEW_CONTROL", default_value = "127.0.0.1:5010")]
    addr: String,
    /// Use UDP instead of TCP.
    #[arg(long)]
    udp: bool,
    /// Print JSON, one object per reply and line.
    #[arg(long)]
    json: bool,
    /// Print every frame sent and received, annotated byte by byte, on stderr.
    #[arg(long)]
    hex: bool,
    /// Seconds to wait for a reply (up to an hour).
    #[arg(long, default_value = "2", value_parser = reply_wait)]
    timeout: Duration,
    #[command(subcommand)]
    action: Action,
}

#[derive(Subcommand, Debug)]
enum Action {
    /// Read a parameter type: PARAM [cam=N] [index=N] [x=.. y=.. frame_rel=..].
    Get {
        param: String,
        /// field=value pairs of the query (cam is short for cam_id).
        fields: Vec<String>,
    },
    /// Change a parameter type: PARAM field=value ... (angles in radians or with `deg`).
    ///
    /// For VIDEO_OUTPUT, DETECTION, CAM_EULER (unless is_delta), CAM_SENSOR and
    /// GENERAL_SETTINGS the current values are read first, so fields you do not name keep
    /// their value; in the other types unnamed fields are sent as 0.
    Set { param: String, fields: Vec<String> },
    /// Poll a parameter type and print it whenever it changes (Ctrl-C stops).
    Watch {
        param: String,
        fields: Vec<String>,
        /// Seconds between polls (0.01 to a day).
        #[arg(long, default_value = "0.5", value_parser = poll_interval)]
        interval: Duration,
        /// Stop after this many prints (the first value counts).
        #[arg(long)]
        count: Option<usize>,
    },
    /// Stop the server (permitted from loopback by default).
    Quit,
    /// Send EMPTY (keep-alive) and wait for the acknowledgement.
    Ping,
    /// List the parameter types, or one type's fields and units.
    Params { param: Option<String> },
    /// Load test: many clients pipelining SET CAM_FOV / GET CAM_LOCK_FLAGS, every reply
    /// checked, with one more client stalled mid-frame; prints requests/s and reply times.
    Load {
        /// Clients at once, 1 to 1000.
        #[arg(long, default_value_t = 50, value_parser = |t: &str| crate::units::whole::<u16>(t, 1..=1000))]
        clients: u16,
        /// Requests per client, 1 to 1,000,000.
        #[arg(long, default_value_t = 2000, value_parser = |t: &str| crate::units::whole::<u32>(t, 1..=1_000_000))]
        requests: u32,
        /// Do not keep a client stalled mid-frame during the run.
        #[arg(long)]
        no_stall: bool,
    },
}

pub fn run(args: CtlArgs) -> Result<()> {
    match &args.action {
        Action::Params { param } => return list_params(param.as_deref()),
        Action::Load {
            clients,
            requests,
            no_stall,
        } => {
            let (clients, requests) = (*clients as usize, *requests as usize);
            return load(&args.addr, clients, requests, !no_stall, args.json);
        }
        _ => {}
    }
    let mut client = Client::connect(&args.addr, args.udp, args.timeout)?;
    if args.hex {
        client.trace = Some(Box::new(|sent, frame| {
            eprintln!("{} 80 bytes", if sent { ">>" } else { "<<" });
            eprint!("{}", annotate(frame));
        }));
    }
    let json = args.json;
    match args.action {
        Action::Get { param, fields } => {
            let q = build(&param, &fields, None)?;
            for p in client.get(q)? {
                print_param(&p, json);
            }
        }
        Action::Set { param, fields } => set(&mut client, &param, &fields, json)?,
        Action::Watch {
            param,
            fields,
            interval,
            count,
        } => watch(
            &mut client,
            build(&param, &fields, None)?,
            (interval, count),
            json,
        )?,
        Action::Quit => {
            client.quit()?;
            if !json {
                println!("the server is stopping");
            }
        }
        Action::Ping => {
            let t = std::time::Instant::now();
            client.ping()?;
            println!("acknowledged in {:.2} ms", t.elapsed().as_secs_f64() * 1e3);
        }
        Action::Params { .. } | Action::Load { .. } => unreachable!("handled above"),
    }
    Ok(())
}

/// `ctl set`: the fields given over the parameter's current values where it has them (read
/// first), so unnamed fields keep theirs.
fn set(client: &mut Client, param: &str, fields: &[String], json: bool) -> Result<()> {
    if fields.is_empty() {
        bail!("nothing to set: give field=value pairs (see `digiview ctl params {param}`)");
    }
    let kind = param_type(param)?;
    let current = if reads_first(kind, fields) {
        let cam = cam_of(kind, fields)?;
        // A refusal here is the SET's refusal (a cam_id out of range), so it says SET.
        let read = client.get_one(query(kind, cam)).map_err(|e| match e {
            ClientError::Refused {
                verdict, reason, ..
            } => ClientError::Refused {
                request: format!("SET {kind}"),
                verdict,
                reason,
            },
            e => e,
        });
        Some(read?)
    } else {
        None
    };
    client.set(build(param, fields, current)?)?;
    if json {
        println!(
            "{}",
            serde_json::json!({"param": kind.name(), "result": "ACKNOWLEDGEMENT"})
        );
    } else {
        println!("{kind}: set");
    }
    Ok(())
}

/// `ctl watch`: the answer each time it changes, `count` times at most.
fn watch(
    client: &mut Client,
    q: Param,
    (interval, count): (Duration, Option<usize>),
    json: bool,
) -> Result<()> {
    let mut last = None;
    let mut printed = 0;
    loop {
        let now = client.get(q)?;
        if last.as_ref() != Some(&now) {
            for p in &now {
                print_param(p, json);
            }
            printed += 1;
            last = Some(now);
            if count.is_some_and(|c| printed >= c) {
                return Ok(());
            }
        }
        std::thread::sleep(interval);
    }
}

fn param_type(name: &str) -> Result<ParamType> {
    ParamType::parse(name).with_context(|| {
        format!(
            "`{name}` is not a parameter type; one of: {}",
            ParamType::ALL
                .iter()
                .map(|p| p.name())
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// Whether `set` reads the current values first, so unnamed fields keep them.
fn reads_first(kind: ParamType, fields: &[String]) -> bool {
    let is_delta = fields.iter().any(|f| {
        f.split_once('=')
            .is_some_and(|(k, v)| k.trim() == "is_delta" && v.trim() != "0")
    });
    edit::reads_first(kind, is_delta)
}

fn cam_of(kind: ParamType, fields: &[String]) -> Result<u8> {
    let p = build(kind.name(), fields, None)?;
    Ok(p.cam_id().unwrap_or(0))
}

/// A parameter from `field=value` pairs over `base` (or all zeros).
fn build(name: &str, pairs: &[String], base: Option<Param>) -> Result<Param> {
    let kind = param_type(name)?;
    let mut p = base.unwrap_or_else(|| kind.zeroed());
    for pair in pairs {
        let (key, value) = pair
            .split_once('=')
            .with_context(|| format!("`{pair}` is not field=value"))?;
        edit::set(&mut p, key, Given::Text(value))?;
    }
    Ok(p)
}

fn print_param(p: &Param, json: bool) {
    let kind = p.param_type();
    if json {
        println!("{}", serde_json::json!({"param": kind.name(), "values": p}));
    } else {
        print!("{kind}\n{}", describe(p));
    }
}

fn list_params(param: Option<&str>) -> Result<()> {
    let Some(name) = param else {
        for p in ParamType::ALL {
            let access = if p.settable() { "GET SET" } else { "GET    " };
            println!("{:2}  {access}  {}", *p as u8, p.name());
        }
        return Ok(());
    };
    let kind = param_type(name)?;
    println!(
        "{kind} ({}):",
        if kind.settable() {
            "GET and SET"
        } else {
            "GET only"
        }
    );
    for f in kind.fields() {
        let unit = match f.unit {
            Unit::Integer => "integer",
            Unit::Radians => "radians (or 30deg)",
            Unit::Degrees => "degrees",
            Unit::Metres => "metres",
            Unit::Ratio => "ratio in [0, 1)",
            Unit::Offset => "normalized offset in [-1, 1]",
            Unit::Boxes => "bounding boxes (GET only)",
            Unit::Text => "text (GET only)",
            Unit::Seconds => "seconds",
            Unit::Kelvin => "kelvin",
        };
        println!("  {:28} {unit}", f.name);
    }
    Ok(())
}

fn load(addr: &str, clients: usize, requests: usize, stall: bool, json: bool) -> Result<()> {
    let target = crate::control::client::resolve(addr)?;
    let r = crate::control::load::run(target, clients, requests, stall)
        .with_context(|| format!("load against {addr}"))?;
    if json {
        println!("{}", serde_json::to_string(&r)?);
    } else {
        println!(
            "{} clients x {} requests{}: {} replies, {} wrong, {:.2} s, {:.0} requests/s, \
             reply time p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
            r.clients,
            r.requests_per_client,
            if r.stalled_client {
                " (+1 stalled mid-frame)"
            } else {
                ""
            },
            r.replies,
            r.wrong,
            r.seconds,
            r.requests_per_second,
            r.p50_ms,
            r.p99_ms,
            r.max_ms
        );
    }
    if r.wrong > 0 {
        bail!("{} replies did not answer their request", r.wrong);
    }
    Ok(())
}

/// `--timeout`: a reply is waited for 1 ms to an hour.
fn reply_wait(text: &str) -> Result<Duration, crate::units::UnitError> {
    crate::units::parse_seconds(text, 0.001..=3600.0)
}

/// `ctl watch --interval`: 10 ms to a day between polls.
fn poll_interval(text: &str) -> Result<Duration, crate::units::UnitError> {
    crate::units::parse_seconds(text, 0.01..=86_400.0)
}
