//! `--readout-ms`, `--readout-direction` and `--turn`: a rolling-shutter camera for the
//! commands that work on single frames (`synth` captures one row by row, `render` corrects
//! one, `bench` times the correction), the vehicle turning at a steady rate through the
//! readout.

use crate::geometry::shutter::{MAX_READOUT_MS, Readout, ReadoutDirection, ShutterTable};
use crate::geometry::{Euler, lens_from_world};
use crate::lens::Lens;
use crate::state::State;
use anyhow::{Result, bail};
use clap::Args;

#[derive(Args, Debug, Clone, Default)]
pub struct ReadoutArgs {
    /// The camera's rolling-shutter readout: milliseconds from the first row read to the
    /// last, 0..=100 (0: a global shutter). The state's attitude is the middle row's.
    #[arg(long, default_value_t = 0.0, value_parser = readout_ms)]
    pub readout_ms: f64,
    /// Which way the readout runs: top_to_bottom, bottom_to_top, left_to_right or
    /// right_to_left.
    #[arg(long, default_value = "top_to_bottom", value_parser = direction)]
    pub readout_direction: ReadoutDirection,
    /// How the vehicle turns during the readout, in degrees per second of each angle:
    /// yaw=90,pitch=0,roll=0 (unnamed angles 0).
    #[arg(long, value_parser = turn)]
    pub turn: Option<Euler>,
}

fn readout_ms(text: &str) -> Result<f64> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=MAX_READOUT_MS).contains(&v) => Ok(v),
        _ => bail!("{text} is not a readout in 0..={MAX_READOUT_MS} ms"),
    }
}

fn direction(text: &str) -> Result<ReadoutDirection> {
    use ReadoutDirection::*;
    Ok(match text {
        "top_to_bottom" => TopToBottom,
        "bottom_to_top" => BottomToTop,
        "left_to_right" => LeftToRight,
        "right_to_left" => RightToLeft,
        _ => bail!(
            "{text} is not a readout direction (top_to_bottom, bottom_to_top, left_to_right, \
             right_to_left)"
        ),
    })
}

/// The fastest turn taken, degrees per second each way.
const MAX_TURN: f64 = 3600.0;

fn turn(text: &str) -> Result<Euler> {
    let mut rate = Euler::new(0.0, 0.0, 0.0);
    for part in text.split(',') {
        let (name, value) = part
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("{part}: give NAME=DEG/S (yaw, pitch or roll)"))?;
        let v = match value.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= MAX_TURN => v.to_radians(),
            _ => bail!("{part}: a rate in -{MAX_TURN}..={MAX_TURN} degrees per second"),
        };
        match name.trim() {
            "yaw" => rate.yaw = v,
            "pitch" => rate.pitch = v,
            "roll" => rate.roll = v,
            other => bail!("{other} is not yaw, pitch or roll"),
        }
    }
    Ok(rate)
}

impl ReadoutArgs {
    pub fn readout(&self) -> Readout {
        Readout {
            time_ms: self.readout_ms,
            direction: self.readout_direction,
            ..Readout::default()
        }
    }

    /// The vehicle's attitude `dt_us` after the middle row: `state`'s turning at `--turn`.
    pub fn attitude(&self, state: &State) -> impl Fn(f64) -> Euler + Sync + use<> {
        let (base, rate) = (
            state.vehicle.attitude.euler(),
            self.turn.unwrap_or_default(),
        );
        move |dt_us| {
            let s = dt_us * 1e-6;
            Euler::new(
                base.yaw + rate.yaw * s,
                base.pitch + rate.pitch * s,
                base.roll + rate.roll * s,
            )
        }
    }

    /// The shutter table of a frame of `state` through `lens` (None for a global shutter).
    pub fn table(&self, state: &State, lens: &Lens) -> Option<ShutterTable> {
        let (attitude, mount) = (self.attitude(state), state.settings.mount.euler());
        ShutterTable::new(&self.readout(), (lens.width, lens.height), |dt| {
            lens_from_world(attitude(dt), mount)
        })
    }
}
