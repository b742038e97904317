//! The command line: `digiview lens …`, `synth`, `render`, `bench`, `serve`, `ctl` and `doctor`. Parses flags into
//! the library's plain types and reports errors with anyhow; no rendering logic lives here.

mod bench_cmd;
mod calibrate_cmd;
mod calibrate_frames;
mod ctl_cmd;
mod detect_cmd;
mod doctor;
mod lens_cmd;
mod lens_entry;
pub mod locate;
mod output;
mod pair_fit_cmd;
mod readout_args;
mod readout_cmd;
mod render_cmd;
mod render_video;
pub(crate) mod serve_cmd;
mod sim_cmd;

use crate::modes::{Crop, LayoutMode, OverlayMode};
use crate::state::State;
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use tracing::warn;

#[derive(Parser, Debug)]
#[command(
    name = "digiview",
    version,
    about = "Onboard fisheye virtual-camera video head"
)]
pub struct Cli {
    /// The lens calibration file. Without it: $DIGIVIEW_LENS_CAL, else the first of
    /// ./lens.cal, ./lens-cal/lens.cal, ~/.config/digiview/lens.cal, /etc/digiview/lens.cal,
    /// else the lens.cal built into the binary (the log says which).
    #[arg(long, global = true)]
    pub lens_cal: Option<PathBuf>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List, show, check and import lens calibrations.
    #[command(subcommand)]
    Lens(lens_cmd::LensCommand),
    /// Render the output frame from a fisheye image.
    Render(render_cmd::RenderArgs),
    /// Synthesise a fisheye frame (or, with --truth, the exact output frame) from a known world.
    Synth(render_cmd::SynthArgs),
    /// Run the ONNX detector on a photograph and print what it finds.
    Detect(detect_cmd::DetectArgs),
    /// Time the renderer: N frames of a 4K fisheye, a new attitude each, per-stage medians.
    Bench(bench_cmd::BenchArgs),
    /// Run the system; `--no-video` runs the control server alone on the live state.
    Serve(Box<serve_cmd::ServeArgs>),
    /// Talk to a running server over the control protocol: get, set, watch, quit.
    Ctl(ctl_cmd::CtlArgs),
    /// Check that this machine has what `serve` needs (GPU, GStreamer, camera, lens.cal,
    /// config, ports, autopilot, disk); one line each, exit code 0 only when all pass.
    Doctor(doctor::DoctorArgs),
    /// Send the demo's flight as a MAVLink autopilot, to try a setup without a drone.
    SimAutopilot(sim_cmd::SimArgs),
    /// Measure a running head's rolling-shutter readout while the vehicle turns.
    Readout(readout_cmd::ReadoutCmdArgs),
}

/// Which renderer `render` and `bench` use: the CPU reference, or the GPU renderer on a
/// backend as `serve --backend` takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// The f64 CPU reference.
    Cpu,
    /// The GPU renderer on the best adapter that draws right (lavapipe where there is no GPU).
    #[value(alias = "gpu")]
    Auto,
    /// The GPU renderer on Vulkan (Metal on macOS, DX12 on Windows).
    Vulkan,
    /// The GPU renderer on OpenGL or OpenGL ES through EGL (llvmpipe where there is no GPU).
    Gl,
}

impl Backend {
    /// The GPU backend, for all but the CPU reference.
    pub fn gpu(self) -> Option<crate::modes::GpuBackend> {
        use crate::modes::GpuBackend;
        match self {
            Backend::Cpu => None,
            Backend::Auto => Some(GpuBackend::Auto),
            Backend::Vulkan => Some(GpuBackend::Vulkan),
            Backend::Gl => Some(GpuBackend::Gl),
        }
    }
}

/// Everything a state file holds, as flags that override it.
#[derive(Args, Debug, Default, Clone)]
pub struct StateArgs {
    /// A TOML state file (docs/cli.md); flags below override it.
    #[arg(long)]
    pub state: Option<PathBuf>,
    /// Lens by name or lens_id in lens.cal.
    #[arg(long)]
    pub lens: Option<String>,
    /// Layout mode 0..=6.
    #[arg(long)]
    pub layout: Option<u8>,
    /// Detection overlay mode 0..=5.
    #[arg(long)]
    pub overlay: Option<u8>,
    /// Output size WxH.
    #[arg(long, value_parser = crate::units::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Output frame rate (5..=30).
    #[arg(long)]
    pub fps: Option<u32>,
    /// A camera: N:yaw=45deg,pitch=-30deg,roll=0,fov=90deg,zoom=0,crop=1,lock=7,control=1 (repeatable).
    #[arg(long = "cam")]
    pub cams: Vec<String>,
    /// Vehicle attitude: yaw=..,pitch=..,roll=..
    #[arg(long)]
    pub attitude: Option<String>,
    /// Fisheye mount on the vehicle: yaw=..,pitch=..,roll=.. (default pitch=-90deg, looking down).
    #[arg(long)]
    pub mount: Option<String>,
    /// Vehicle position: lat=..,lon=..,alt=..,rel=.. (degrees; metres AMSL and above home).
    #[arg(long)]
    pub position: Option<String>,
    /// The camera's exposure (CAM_SENSOR): ae=0|1,target=1..254,exposure=US,gain=THOUSANDTHS.
    #[arg(long)]
    pub cam_sensor: Option<String>,
    /// A tracked object for a detection tile: yaw=..,pitch=..,size=..,score=.. (repeatable).
    #[arg(long = "track")]
    pub tracks: Vec<String>,
    /// Scene time in seconds (moves the synthetic world's objects).
    #[arg(long)]
    pub time: Option<f64>,
}

impl StateArgs {
    /// The state file (or the defaults) with every flag applied, checked for range. The lens
    /// flag is resolved by the caller, which has lens.cal.
    pub fn state(&self, cal: &crate::lens::LensCal) -> Result<State> {
        let mut s = match &self.state {
            Some(p) => State::load(p, cal)?,
            None => State::default(),
        };
        if let Some(l) = &self.lens {
            let entry = cal.find(l)?;
            s.settings.lens = entry.lens_id;
            // A pair's two images come in one frame of its own shape: the sensor's, until a
            // source or --size says otherwise.
            if entry.pair.is_some() {
                (s.settings.sensor.width, s.settings.sensor.height) = (entry.width, entry.height);
                s.settings.sensor.roi = None;
            }
        }
        if let Some(v) = self.layout {
            s.settings.output.layout = LayoutMode::try_from(v).context("--layout")?;
        }
        if let Some(v) = self.overlay {
            s.settings.output.overlay = OverlayMode::try_from(v).context("--overlay")?;
        }
        if let Some((w, h)) = self.size {
            (s.settings.output.width, s.settings.output.height) = (w, h);
        }
        if let Some(v) = self.fps {
            s.settings.output.fps = v;
        }
        for c in &self.cams {
            s.apply_camera_flag(c)
                .with_context(|| format!("--cam {c}"))?;
        }
        if let Some(a) = &self.attitude {
            State::apply_angles(&mut s.vehicle.attitude, a).context("--attitude")?;
        }
        if let Some(a) = &self.mount {
            State::apply_angles(&mut s.settings.mount, a).context("--mount")?;
        }
        if let Some(p) = &self.position {
            s.apply_position(p).context("--position")?;
        }
        if let Some(v) = &self.cam_sensor {
            s.apply_sensor(v).context("--cam-sensor")?;
        }
        for t in &self.tracks {
            s.add_tracked(t).with_context(|| format!("--track {t}"))?;
        }
        if let Some(t) = self.time {
            s.time = t;
        }
        s.settings.output.even();
        s.validate(&crate::lens::Lenses::new(cal))?;
        for (i, c) in s.settings.cameras.iter().enumerate() {
            if let Crop::Unknown(m) = c.crop() {
                warn!("camera {i}: crop mode {m} is not one of 0..=4; its view is black");
            }
        }
        Ok(s)
    }
}

pub fn run(cli: Cli) -> Result<()> {
    let lens_cal = || locate::lens_cal(cli.lens_cal.as_deref()).map(|(cal, _)| cal);
    match cli.command {
        Command::Lens(cmd) => lens_cmd::run(cli.lens_cal.as_deref(), cmd),
        Command::Render(args) => render_cmd::render(&lens_cal()?, args),
        Command::Synth(args) => render_cmd::synth(&lens_cal()?, args),
        Command::Bench(args) => bench_cmd::bench(&lens_cal()?, args),
        Command::Detect(args) => detect_cmd::detect(args),
        Command::Serve(args) => serve_cmd::serve(&lens_cal()?, *args),
        Command::Doctor(args) => doctor::doctor(cli.lens_cal.as_deref(), args),
        Command::Ctl(args) => ctl_cmd::run(args),
        Command::SimAutopilot(args) => sim_cmd::sim_autopilot(args),
        Command::Readout(args) => readout_cmd::run(args),
    }
}

/// A spinner on stderr for work that takes seconds; hidden when stderr is not a terminal.
pub(crate) fn spinner(message: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            .expect("valid template"),
    );
    bar.set_message(message.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    bar
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_commands_flags_are_well_formed_and_none_is_named_twice() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
