//! `digiview doctor`: checks everything `serve` needs on this machine, with the same
//! configuration and flags, and reports one line per check with what to do about a failure:
//! the configuration, lens.cal, the GPU, the GStreamer elements (and which hardware encoders
//! there are), the camera source, the ports, the MAVLink endpoint and the disk for captures.
//! Exits 0 only when every check passes.

mod checks;
mod links;

use super::serve_cmd::SetupArgs;
use crate::app::Config;
use anyhow::{Result, bail};
use clap::Args;
use std::path::Path;

#[derive(Args, Debug)]
pub struct DoctorArgs {
    #[command(flatten)]
    setup: SetupArgs,
    /// How long to wait for the autopilot's HEARTBEAT, seconds (up to an hour).
    #[arg(long, default_value = "3", value_parser = heartbeat_wait)]
    heartbeat_wait: std::time::Duration,
}

/// One check's outcome: its line, and what to do when it failed.
pub struct Outcome {
    pub name: &'static str,
    pub ok: bool,
    pub line: String,
}

impl Outcome {
    pub fn pass(name: &'static str, line: impl Into<String>) -> Outcome {
        Outcome {
            name,
            ok: true,
            line: line.into(),
        }
    }

    pub fn fail(name: &'static str, line: impl Into<String>) -> Outcome {
        Outcome {
            name,
            ok: false,
            line: line.into(),
        }
    }
}

pub fn doctor(lens_cal: Option<&Path>, args: DoctorArgs) -> Result<()> {
    let mut outcomes = vec![];
    let mut report = |o: Outcome| {
        println!(
            "{:<5} {:<10} {}",
            if o.ok { "ok" } else { "FAIL" },
            o.name,
            o.line
        );
        outcomes.push(o.ok);
    };
    let cfg = match args.setup.config() {
        Ok((cfg, origin)) => match cfg.check() {
            Ok(()) => {
                report(Outcome::pass("config", origin.to_string()));
                cfg
            }
            Err(e) => {
                report(Outcome::fail(
                    "config",
                    format!("{origin}: {e} (fix the key it names)"),
                ));
                Config::default()
            }
        },
        Err(e) => {
            report(Outcome::fail("config", format!("{e:#}")));
            Config::default()
        }
    };
    report(checks::lens_cal(lens_cal, &cfg));
    report(checks::gpu(&cfg));
    report(checks::gstreamer(&cfg));
    report(checks::source(&cfg, lens_cal));
    for o in links::ports(&cfg) {
        report(o);
    }
    report(links::mavlink(&cfg, args.heartbeat_wait));
    report(checks::disk(&cfg));
    let failed = outcomes.iter().filter(|ok| !**ok).count();
    if failed > 0 {
        bail!("{failed} of {} checks failed", outcomes.len());
    }
    println!("all {} checks passed", outcomes.len());
    Ok(())
}

/// `--heartbeat-wait`: 0 s to an hour.
fn heartbeat_wait(text: &str) -> Result<std::time::Duration, crate::units::UnitError> {
    crate::units::parse_seconds(text, 0.0..=3600.0)
}
