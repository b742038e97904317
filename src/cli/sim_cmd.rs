//! `digiview sim-autopilot`: the demo's flight sent as a MAVLink autopilot to an endpoint
//! (DigiView's link, a ground station, a router), for trying a setup without a drone.

use crate::autopilot::Endpoint;
use crate::autopilot::sim::{SYSTEM, SimAutopilot};
use crate::source::demo::Flight;
use crate::state::State;
use anyhow::{Result, bail};
use clap::Args;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct SimArgs {
    /// Where to send: udpout:HOST:PORT (DigiView's link, QGroundControl's 14550), tcpout:,
    /// tcpin: (a ground station connects), udpin:, or serial:DEVICE:BAUD.
    #[arg(long, value_name = "ENDPOINT")]
    to: String,
    /// ATTITUDE messages per second.
    #[arg(long, default_value_t = 100.0)]
    rate: f64,
    /// Hover at the position instead of flying the demo's 30 m circle.
    #[arg(long)]
    hover: bool,
    /// Where: lat=..,lon=..,alt=..,rel=.. (degrees; metres above sea level and above home).
    #[arg(long)]
    position: Option<String>,
}

pub fn sim_autopilot(args: SimArgs) -> Result<()> {
    if args.to.parse::<Endpoint>()? == Endpoint::Off {
        bail!("--to names where to send, not off");
    }
    if !(1.0..=1000.0).contains(&args.rate) {
        bail!("--rate {} is outside 1..=1000", args.rate);
    }
    let mut state = State::default();
    if let Some(p) = &args.position {
        state.apply_position(p)?;
    }
    state.validate_fields()?;
    let flight = Flight {
        hover: state.vehicle.position,
        attitude: state.vehicle.attitude.euler(),
        motion: !args.hover,
        spin: false,
        radius: 30.0,
        lap: 90.0,
    };
    eprintln!(
        "sending the demo's {} to {} as system {SYSTEM} (ATTITUDE at {} Hz); Ctrl-C stops",
        if args.hover { "hover" } else { "flight" },
        args.to,
        args.rate
    );
    let _sim = SimAutopilot::start(&args.to, flight, Instant::now(), args.rate);
    loop {
        std::thread::park();
    }
}
