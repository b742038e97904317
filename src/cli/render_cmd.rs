//! `digiview render` (fisheye image → output frame) and `digiview synth` (synthetic fisheye
//! frames, ground-truth output frames and panoramas).

use super::readout_args::ReadoutArgs;
use super::{StateArgs, output, spinner};
use crate::frame::PixelFormat;
use crate::lens::calibrate::Board;
use crate::lens::{LensCal, Lenses};
use crate::modes::GpuBackend;
use crate::plan::{Filter, FramePlan};
use crate::render::choose;
use crate::render::cpu;
use crate::render::gpu::Renderer;
use crate::render::gpu::renderer::render_image;
use crate::scene::synth::{equirect, fisheye, rolling_fisheye, truth};
use crate::scene::{GridWorld, PanoramaWorld, World};
use anyhow::{Context, Result};
use clap::Args;
use image::RgbImage;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The fisheye input: an image (PNG or JPEG), a video file (anything GStreamer decodes,
    /// e.g. .mp4), or an image sequence named with a number pattern (frames/%05d.png).
    #[arg(long)]
    input: PathBuf,
    /// Where to write: an image (.png or .jpg) for an image input; for a video or sequence
    /// input, an MP4 (H.264) or an image sequence pattern (out/%05d.png).
    #[arg(long)]
    out: PathBuf,
    /// Frame rate of an image sequence input, 1 to 240.
    #[arg(long, default_value_t = 30, value_parser = |t: &str| crate::units::whole::<u32>(t, 1..=240))]
    input_fps: u32,
    /// H.264 bitrate of an MP4 output, 100..=100000 kbit/s.
    #[arg(long, default_value_t = 8000, value_parser = bitrate)]
    bitrate_kbps: u32,
    /// The GPU renderer on a backend (auto: the best adapter that draws right; lavapipe
    /// where there is no GPU), or the f64 CPU reference (`gpu` is `auto`).
    #[arg(long, value_enum, default_value = "auto")]
    backend: super::Backend,
    /// Minification filter (docs/decisions.md, "Filtering").
    #[arg(long, value_enum, default_value = "mip")]
    filter: Filter,
    /// With every frame of a video, the KLV metadata (MISB ST 0601, docs/klv.md) of camera
    /// --klv-camera's view as the state has it, in an MPEG-TS output (--out NAME.ts).
    #[arg(long)]
    klv: bool,
    /// The camera whose view the KLV describes.
    #[arg(long, default_value_t = 0, value_parser = klv_camera, requires = "klv")]
    klv_camera: usize,
    /// When the input's first frame was captured, seconds since 1970 (UTC), for the KLV's
    /// time stamps; default: the input file's modification time less its length.
    #[arg(long, value_parser = klv_start, requires = "klv")]
    klv_start: Option<f64>,
    /// An image input's rolling shutter, corrected (images only).
    #[command(flatten)]
    readout: ReadoutArgs,
    #[command(flatten)]
    state: StateArgs,
}

fn klv_camera(text: &str) -> Result<usize> {
    let last = crate::state::MAX_CAMERAS - 1;
    text.parse::<usize>()
        .ok()
        .filter(|&c| c <= last)
        .ok_or_else(|| anyhow::anyhow!("{text} is not a camera (0..={last})"))
}

fn klv_start(text: &str) -> Result<f64> {
    text.parse::<f64>()
        .ok()
        .filter(|t| (0.0..=MAX_KLV_START).contains(t))
        .ok_or_else(|| {
            anyhow::anyhow!("{text} is not a UNIX time in seconds (0..={MAX_KLV_START})")
        })
}

/// The latest `--klv-start`: the year 2100.
const MAX_KLV_START: f64 = 4_102_444_800.0;

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Where to write the image (.png or .jpg).
    #[arg(long)]
    out: PathBuf,
    /// The world: `grid` (procedural), an equirectangular panorama image, or `photos:DIR`, a
    /// panorama laid out from the photographs (JPEG, PNG) in DIR.
    #[arg(long, default_value = "grid")]
    world: String,
    /// Draw the exact output frame for the state instead of the fisheye frame.
    #[arg(long, conflicts_with = "equirect")]
    truth: bool,
    /// Draw the world as an equirectangular panorama of this size (e.g. 4096x2048).
    #[arg(long, value_parser = crate::units::parse_size)]
    equirect: Option<(u32, u32)>,
    /// The fisheye frame size (default: the state's sensor size, 3840x2160).
    #[arg(long, value_parser = crate::units::parse_size)]
    sensor: Option<(u32, u32)>,
    /// Draw a calibration board (cols=N,rows=N,tag=LENGTH[,spacing=RATIO]) before the lens
    /// instead of a world, at each --board-pose or at --board-sweep's poses, one frame each.
    #[arg(long, value_parser = Board::parse, conflicts_with_all = ["truth", "equirect"])]
    board: Option<Board>,
    /// Where the board is: off=ANGLE,azimuth=ANGLE,distance=LENGTH[,tilt=ANGLE][,turn=ANGLE]
    /// [,spin=ANGLE] (off the lens axis, azimuth 0 the frame's right and 90deg down; repeat
    /// for more frames).
    #[arg(long, requires = "board")]
    board_pose: Vec<String>,
    /// N board poses spread over the image circle, one frame each (--out then numbers its
    /// files: frames/%03d.png).
    #[arg(long, requires = "board", conflicts_with = "board_pose")]
    board_sweep: Option<usize>,
    /// Draw a frame of the dual-fisheye pair lens.cal calls DUAL (both images side by side,
    /// at the pair's frame size unless --size says otherwise): --lens DUAL, shorter.
    #[arg(long, conflicts_with_all = ["truth", "equirect", "board"])]
    dual: bool,
    /// With a lens pair: draw it with its second lens turned ROLL,PITCH,YAW from back to
    /// back (e.g. 2deg,0,0) rather than as lens.cal has it, to make frames of a known pose.
    #[arg(long, value_parser = parse_rotation)]
    pair_rotation: Option<[f64; 3]>,
    /// Capture the fisheye frame row by row, as a rolling-shutter camera does.
    #[command(flatten)]
    readout: ReadoutArgs,
    #[command(flatten)]
    state: StateArgs,
}

fn save(img: &RgbImage, out: output::Output) -> Result<()> {
    let path = output::write_image(img, out)?;
    eprintln!(
        "wrote {} ({}x{})",
        path.display(),
        img.width(),
        img.height()
    );
    Ok(())
}

/// `--bitrate-kbps`, in the range the serve config takes too.
fn bitrate(text: &str) -> Result<u32> {
    let (lo, hi) = crate::stream::encoder::BITRATE_KBPS;
    text.parse::<u32>()
        .ok()
        .filter(|b| (lo..=hi).contains(b))
        .ok_or_else(|| anyhow::anyhow!("{text} is not a bitrate in {lo}..={hi} kbit/s"))
}

/// The widest panorama `synth --equirect` draws.
const MAX_EQUIRECT: u32 = 16384;

/// Image extensions `render` reads and writes as single frames.
fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["png", "jpg", "jpeg"].contains(&e.to_ascii_lowercase().as_str()))
}

/// A sequence pattern: a printf-style number (`%05d`, `%d`) in the name.
fn is_pattern(path: &Path) -> bool {
    path.to_string_lossy().contains('%')
}

pub fn render(cal: &LensCal, args: RenderArgs) -> Result<()> {
    let state = args.state.state(cal)?;
    if is_pattern(&args.input) || !is_image(&args.input) {
        let Some(backend) = args.backend.gpu() else {
            anyhow::bail!(
                "the CPU reference renders single images; videos and sequences use --backend \
                 auto, vulkan or gl"
            );
        };
        if !args.readout.readout().is_global() {
            anyhow::bail!("--readout-ms corrects an image input; videos and sequences take none");
        }
        return super::render_video::render_video(cal, &state, &args.video(backend));
    }
    if args.klv {
        anyhow::bail!("--klv goes with a video's frames (--out NAME.ts); an image has no stream");
    }
    if is_pattern(&args.out) || !is_image(&args.out) {
        anyhow::bail!(
            "{}: an image input renders to an image (.png or .jpg); a video or an image \
             sequence renders to .mp4 or a pattern",
            args.out.display()
        );
    }
    let target = output::image_output(&args.out, &[&args.input])?;
    let input = image::open(&args.input)
        .with_context(|| format!("reading {}", args.input.display()))?
        .to_rgb8();
    let lens = Lenses::new(cal).for_frame(
        state.settings.lens,
        input.dimensions(),
        state.settings.sensor.roi(),
    )?;
    let plan = FramePlan::new(&state, &lens)?.with_shutter(args.readout.table(&state, &lens));
    let out = match args.backend.gpu() {
        None => {
            let bar = spinner("rendering on the CPU");
            let out = cpu::render(&plan, &input, args.filter);
            bar.finish_and_clear();
            out
        }
        Some(backend) => {
            let gpu = choose::open(backend)?.gpu;
            let mut renderer = Renderer::new(&gpu, PixelFormat::Rgba, args.filter)?;
            renderer.fixed_view_kinds();
            render_image(&mut renderer, &input, &plan)?.to_rgb()
        }
    };
    save(&out, target)
}

impl RenderArgs {
    fn video(&self, backend: GpuBackend) -> super::render_video::VideoJob {
        super::render_video::VideoJob {
            backend,
            input: self.input.clone(),
            out: self.out.clone(),
            input_fps: self.input_fps,
            bitrate_kbps: self.bitrate_kbps,
            filter: self.filter,
            klv: self.klv.then_some((self.klv_camera, self.klv_start)),
        }
    }
}

pub fn synth(cal: &LensCal, args: SynthArgs) -> Result<()> {
    let world_file: Vec<&Path> = match args.world.as_str() {
        "grid" => vec![],
        w => vec![Path::new(w)],
    };
    if args.board.is_some() && args.board_pose.is_empty() && args.board_sweep.is_none() {
        anyhow::bail!("--board: give its place with --board-pose, or --board-sweep N");
    }
    let target = (args.board.is_none())
        .then(|| output::image_output(&args.out, &world_file))
        .transpose()?;
    let mut state_args = args.state.clone();
    if args.dual {
        let pair = cal
            .find("DUAL")
            .context("--dual draws the pair lens.cal calls DUAL")?;
        state_args.lens = Some(pair.name.clone());
        state_args.size = state_args.size.or(Some((pair.width, pair.height)));
    }
    // Without --truth, --size names the fisheye frame (as in `synth --size 3840x2160`).
    let mut sensor = args.sensor;
    if !args.truth && args.equirect.is_none() && sensor.is_none() {
        sensor = state_args.size.take();
    }
    let mut state = state_args.state(cal)?;
    if let Some((w, h)) = sensor {
        (state.settings.sensor.width, state.settings.sensor.height) = (w, h);
        state
            .validate(&Lenses::new(cal))
            .context("--size (the fisheye frame)")?;
    }
    if let Some((w, h)) = args.equirect
        && !(2..=MAX_EQUIRECT).contains(&w.max(h))
    {
        anyhow::bail!("--equirect {w}x{h}: each side is 2..={MAX_EQUIRECT}");
    }
    let world = world_of(&args.world)?;
    let sensor = (state.settings.sensor.width, state.settings.sensor.height);
    let mut lens =
        Lenses::new(cal).for_frame(state.settings.lens, sensor, state.settings.sensor.roi())?;
    if let Some(rotation) = args.pair_rotation {
        lens = turned_pair(cal, state.settings.lens, rotation)?.for_frame(
            sensor.0,
            sensor.1,
            state.settings.sensor.roi(),
        );
    }
    if let Some(board) = &args.board {
        return super::calibrate_cmd::synth_boards(
            board,
            &args.board_pose,
            args.board_sweep,
            &lens,
            &args.out,
        );
    }
    let bar = spinner("synthesising");
    let img = if let Some((w, h)) = args.equirect {
        equirect(world.as_ref(), &state, w, h)
    } else if args.truth {
        truth(world.as_ref(), &FramePlan::new(&state, &lens)?, &state)
    } else if !args.readout.readout().is_global() {
        let attitude = args.readout.attitude(&state);
        rolling_fisheye(
            world.as_ref(),
            &lens,
            &state,
            &args.readout.readout(),
            attitude,
        )
    } else {
        fisheye(world.as_ref(), &lens, &state)
    };
    bar.finish_and_clear();
    save(&img, target.expect("made without a board"))
}

/// `--pair-rotation`: three angles, roll,pitch,yaw (each radians, or degrees with "deg").
fn parse_rotation(text: &str) -> Result<[f64; 3]> {
    let angles: Vec<f64> = text
        .split(',')
        .map(crate::units::parse_angle)
        .collect::<Result<_, _>>()?;
    let Ok(angles) = <[f64; 3]>::try_from(angles) else {
        anyhow::bail!("{text}: three angles, roll,pitch,yaw (e.g. 2deg,0,0)");
    };
    Ok(angles)
}

/// The pair `id` of lens.cal with its second lens turned `rotation` from back to back.
fn turned_pair(cal: &LensCal, id: u8, rotation: [f64; 3]) -> Result<crate::lens::Lens> {
    let entry = cal.by_id(id).context("the lens is not in lens.cal")?;
    let Some(pair) = &entry.pair else {
        anyhow::bail!(
            "--pair-rotation: {} is a single lens, not a pair",
            entry.name
        );
    };
    let mut pair = pair.clone();
    pair.rotation = rotation;
    Ok(pair.lens(&entry.name, entry.lens_id))
}

/// `--world`: the grid, a panorama image, or a panorama of the photographs in a directory.
fn world_of(spec: &str) -> Result<Box<dyn World>> {
    if spec == "grid" {
        return Ok(Box::new(GridWorld::default()));
    }
    let image = match spec.strip_prefix("photos:") {
        Some(dir) => photo_panorama(Path::new(dir))?,
        None => image::open(spec)
            .with_context(|| format!("reading the panorama {spec}"))?
            .to_rgb8(),
    };
    Ok(Box::new(PanoramaWorld::new(image)))
}

/// `--world photos:DIR`: the photographs in DIR (JPEG and PNG, by name) laid out as a 4096x2048
/// panorama, eight across (`scene::panorama::mosaic`).
fn photo_panorama(dir: &Path) -> Result<RgbImage> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading the photographs in {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
            matches!(ext.to_ascii_lowercase().as_str(), "jpg" | "jpeg" | "png")
        })
        .collect();
    paths.sort();
    if paths.is_empty() {
        anyhow::bail!(
            "{}: no photographs (.jpg, .jpeg, .png) to lay out",
            dir.display()
        );
    }
    let photos = paths
        .iter()
        .map(|p| {
            image::open(p)
                .map(|i| i.to_rgb8())
                .with_context(|| format!("reading {}", p.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(crate::scene::panorama::mosaic(&photos, 4096, 2048, 8))
}
