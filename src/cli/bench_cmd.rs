//! `digiview bench`: renders N frames of a synthetic 4K fisheye with a new vehicle attitude
//! every frame and reports where the time goes. Two runs over the same frames: one with each
//! stage waited for on its own (per-stage medians), one pipelined as the video head runs
//! (frames per second, and each frame's latency from upload to readable bytes).

use super::readout_args::ReadoutArgs;
use super::{Backend, StateArgs, spinner};
use crate::frame::{PixelFormat, PlaneLayout, yuv};
use crate::lens::{Lens, LensCal, Lenses};
use crate::modes::GpuBackend;
use crate::plan::{Filter, FramePlan};
use crate::render::gpu::{Gpu, OutputId, Renderer, StageTimes};
use crate::render::{choose, cpu};
use crate::scene::GridWorld;
use crate::scene::synth::fisheye;
use crate::state::{State, Tracked};
use anyhow::{Result, bail};
use clap::Args;
use image::RgbImage;
use serde::Serialize;
use std::time::{Duration, Instant};

/// `--input-size`: a fisheye frame as a camera gives one, up to the sensor's largest.
fn input_size(text: &str) -> Result<(u32, u32)> {
    let (w, h) = crate::units::parse_size(text)?;
    let max = crate::state::MAX_SENSOR;
    if w > max || h > max {
        bail!("{w}x{h} is larger than the largest sensor, {max}x{max}");
    }
    Ok((w, h))
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Frames to time in each run.
    #[arg(long, default_value_t = 120)]
    frames: u32,
    /// Frames rendered first and not timed (pipeline builds, caches).
    #[arg(long, default_value_t = 5)]
    warmup: u32,
    /// The fisheye input's size [default: the sensor's: 3840x2160, or a lens pair's frame]
    #[arg(long, value_parser = input_size)]
    input_size: Option<(u32, u32)>,
    /// The fisheye input's pixel format.
    #[arg(long, value_enum, default_value = "nv12")]
    input_format: PixelFormat,
    /// The output frame's pixel format.
    #[arg(long, value_enum, default_value = "i420")]
    output_format: PixelFormat,
    #[arg(long, value_enum, default_value = "mip")]
    filter: Filter,
    /// The renderer: the GPU's on a backend (auto, vulkan, gl; `gpu` is `auto`) or the CPU
    /// reference; several, comma-separated (`vulkan,gl`), are timed one after the other on
    /// the same frames and shown side by side.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "auto")]
    backend: Vec<Backend>,
    /// Also draw this many views alone (0 to 4, as the per-view streams do) after each
    /// staged frame: from the frame's upload, and, interleaved, each on a renderer of its
    /// own (uploading the frame again), to time both.
    #[arg(long, default_value_t = 0, value_parser = |t: &str| crate::units::whole::<u8>(t, 0..=4))]
    views: u8,
    /// The views' size (`[cameras]` width and height).
    #[arg(long, default_value = "1280x720", value_parser = crate::units::parse_size)]
    view_size: (u32, u32),
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Correct a rolling shutter (each frame's table made from --turn, or none, about its
    /// attitude): what the correction costs.
    #[command(flatten)]
    readout: ReadoutArgs,
    /// The output (--size, default 1920x1080), layout (default 4), overlay (default 2),
    /// cameras and lens, as for `render`.
    #[command(flatten)]
    state: StateArgs,
}

#[derive(Serialize)]
struct Medians {
    upload_ms: f64,
    render_ms: f64,
    readback_ms: f64,
    total_ms: f64,
}

/// What a backend's runs measured.
#[derive(Serialize)]
struct Measured {
    adapter: String,
    backend: &'static str,
    /// Each stage waited for on its own.
    staged: Medians,
    /// Frames per second with upload, render and readback overlapped (frame N renders while
    /// N-1 is read back).
    pipelined_fps: f64,
    /// Median from a frame's upload starting to its bytes being readable, pipelined.
    pipelined_latency_ms: f64,
    /// With `--views`: what drawing them took.
    #[serde(skip_serializing_if = "Option::is_none")]
    views: Option<ViewTimes>,
}

/// Medians per frame of drawing `--views` views alone, each way.
#[derive(Serialize)]
struct ViewTimes {
    count: u8,
    size: String,
    /// All of them from the composed frame's upload, one submission, read back, each with
    /// the cheaper filter where it draws alike (as the video head draws them).
    shared_ms: f64,
    /// Each on a renderer of its own with `--filter`: upload, draw, readback (as the video
    /// head drew them before they shared the upload).
    alone_ms: f64,
}

#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    measured: Measured,
    frames: u32,
    input: String,
    output: String,
    layout: u8,
    overlay: u8,
    filter: Filter,
    /// Median time to plan a frame from the state on the CPU (included in the totals).
    plan_ms: f64,
    /// The rolling-shutter readout corrected (0: none).
    readout_ms: f64,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { 0.0 } else { v[v.len() / 2] }
}

/// The state of frame `i`: the vehicle yaws, pitches and rolls a little more each frame.
fn attitude_at(base: &State, i: u32) -> State {
    let mut s = base.clone();
    let t = i as f64;
    let a = &mut s.vehicle.attitude;
    a.yaw = (1.7 * t).to_radians();
    a.pitch = (8.0 * (0.11 * t).sin()).to_radians();
    a.roll = (12.0 * (0.07 * t).cos()).to_radians();
    s
}

/// Four detections, so the overlay's tiles are drawn, not left black.
fn four_objects() -> Vec<Tracked> {
    (0..4)
        .map(|i| Tracked {
            id: i,
            yaw: (50.0 * i as f64 - 75.0).to_radians(),
            pitch: (-40.0f64).to_radians(),
            size: 10f64.to_radians(),
            score: 90,
            ..Tracked::default()
        })
        .collect()
}

/// Every frame's plan, built up front (as the video head builds one per frame) and timed;
/// with `--views`, each frame's views alone too.
fn plans(
    args: &BenchArgs,
    base: &State,
    lens: &Lens,
) -> Result<(Vec<FramePlan>, Vec<Vec<FramePlan>>, f64)> {
    let (mut plans, mut view_plans, mut times) = (vec![], vec![], vec![]);
    for i in 0..args.warmup + args.frames {
        let t = Instant::now();
        let state = attitude_at(base, i);
        plans.push(FramePlan::new(&state, lens)?.with_shutter(args.readout.table(&state, lens)));
        times.push(ms(t.elapsed()));
        let (w, h) = args.view_size;
        view_plans.push(
            (0..args.views as usize)
                .map(|v| FramePlan::single_view(&state, lens, v, w, h))
                .collect::<Vec<_>>(),
        );
    }
    Ok((plans, view_plans, median(times)))
}

pub fn bench(cal: &LensCal, args: BenchArgs) -> Result<()> {
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let mut base = args.state.state(cal)?;
    if base.tracked.is_empty() {
        base.tracked = four_objects();
    }
    let settings = &base.settings;
    let sensor = (settings.sensor.width, settings.sensor.height);
    let (w, h) = args.input_size.unwrap_or(sensor);
    let lens = Lenses::new(cal).for_frame(settings.lens, (w, h), settings.sensor.roi())?;
    let input_layout = PlaneLayout::tight(args.input_format, w, h)?;
    let bar = spinner(&format!("synthesising the {w}x{h} fisheye input"));
    let fish = fisheye(&GridWorld::default(), &lens, &base);
    let input = yuv::encode(&fish, &input_layout);
    bar.finish_and_clear();
    let (plans, view_plans, plan_ms) = plans(&args, &base, &lens)?;
    let output = &base.settings.output;
    let mut reports = vec![];
    for backend in &args.backend {
        let measured = match backend.gpu() {
            Some(b) => bench_gpu(&args, b, &input, &input_layout, &plans, &view_plans)?,
            None => bench_cpu(&args, &fish, &plans),
        };
        reports.push(Report {
            measured,
            input: format!("{w}x{h} {}", args.input_format),
            output: format!("{}x{} {}", output.width, output.height, args.output_format),
            layout: output.layout.code(),
            overlay: output.overlay.code(),
            filter: args.filter,
            frames: args.frames,
            plan_ms,
            readout_ms: args.readout.readout_ms,
        });
    }
    match (args.json, reports.as_slice()) {
        (true, [one]) => println!("{}", serde_json::to_string_pretty(one)?),
        (true, all) => println!("{}", serde_json::to_string_pretty(all)?),
        (false, all) => print_table(all),
    }
    Ok(())
}

/// The reports as a table, a column per backend.
fn print_table(reports: &[Report]) {
    let first = &reports[0];
    for r in reports {
        println!(
            "adapter      {} ({})",
            r.measured.adapter, r.measured.backend
        );
    }
    println!(
        "frames       {} of {} → {}, layout {} overlay {}, filter {:?}",
        first.frames, first.input, first.output, first.layout, first.overlay, first.filter
    );
    if first.readout_ms > 0.0 {
        println!("rolling shutter corrected, {} ms readout", first.readout_ms);
    }
    let row = |label: &str, f: &dyn Fn(&Measured) -> String| {
        let cells: Vec<String> = reports
            .iter()
            .map(|r| format!("{:>14}", f(&r.measured)))
            .collect();
        println!("  {label:<10}{}", cells.concat());
    };
    println!("median per stage (each waited for on its own):");
    row("", &|m| m.backend.to_string());
    row("plan", &|_| format!("{:.2} ms", first.plan_ms));
    row("upload", &|m| format!("{:.2} ms", m.staged.upload_ms));
    row("render", &|m| format!("{:.2} ms", m.staged.render_ms));
    row("readback", &|m| format!("{:.2} ms", m.staged.readback_ms));
    row("total", &|m| format!("{:.2} ms", m.staged.total_ms));
    row("", &|m| format!("({:.1} fps)", 1e3 / m.staged.total_ms));
    println!("pipelined (frame N renders while N-1 is read back):");
    row("rate", &|m| format!("{:.1} fps", m.pipelined_fps));
    row("latency", &|m| format!("{:.2} ms", m.pipelined_latency_ms));
    for r in reports {
        if let Some(v) = &r.measured.views {
            println!(
                "{} views alone at {} ({}): {:.2} ms from the frame's upload, {:.2} ms each \
                 uploading it again",
                v.count, v.size, r.measured.backend, v.shared_ms, v.alone_ms
            );
        }
    }
}

fn progress(n: u32, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} {bar:30} {pos}/{len} frames")
            .expect("valid template"),
    );
    bar.set_message(what.to_string());
    bar
}

fn bench_gpu(
    args: &BenchArgs,
    backend: GpuBackend,
    input: &[u8],
    input_layout: &PlaneLayout,
    plans: &[FramePlan],
    view_plans: &[Vec<FramePlan>],
) -> Result<Measured> {
    let gpu = choose::open(backend)?.gpu;
    let mut renderer = Renderer::new(&gpu, args.output_format, args.filter)?;
    renderer.fixed_view_kinds();
    let (warm, timed) = plans.split_at(args.warmup as usize);
    for plan in warm {
        renderer.render(input, input_layout, plan)?;
    }
    let bar = progress(args.frames, "staged");
    let mut stages: Vec<StageTimes> = vec![];
    let mut views = ViewBench::new(&gpu, &mut renderer, args)?;
    for (plan, view_plans) in timed.iter().zip(&view_plans[args.warmup as usize..]) {
        let (_, times) = renderer.render_staged(input, input_layout, plan)?;
        stages.push(times);
        views.time(&mut renderer, input, input_layout, view_plans)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let bar = progress(args.frames, "pipelined");
    let mut latencies = vec![];
    let start = Instant::now();
    for plan in timed {
        if let Some(frame) = renderer.push(input, input_layout, plan)? {
            latencies.push(ms(frame.latency));
        }
        bar.inc(1);
    }
    while let Some(frame) = renderer.flush()? {
        latencies.push(ms(frame.latency));
    }
    let elapsed = start.elapsed();
    bar.finish_and_clear();
    let pick = |f: fn(&StageTimes) -> Duration| median(stages.iter().map(|s| ms(f(s))).collect());
    Ok(Measured {
        adapter: gpu.describe(),
        backend: gpu.backend(),
        staged: Medians {
            upload_ms: pick(|s| s.upload),
            render_ms: pick(|s| s.render),
            readback_ms: pick(|s| s.readback),
            total_ms: pick(|s| s.upload + s.render + s.readback),
        },
        pipelined_fps: args.frames as f64 / elapsed.as_secs_f64(),
        pipelined_latency_ms: median(latencies),
        views: views.report(args),
    })
}

/// `--views`: the views' outputs of the renderer, a renderer of their own, and the times.
struct ViewBench {
    outputs: Vec<OutputId>,
    /// With the mip filter, each view drawn from the upload takes the cheaper filter where
    /// it draws alike, as the video head's do (`FramePlan::cheapest_filter`).
    choose_filter: bool,
    alone: Option<Renderer>,
    shared: Vec<f64>,
    alone_ms: Vec<f64>,
}

impl ViewBench {
    fn new(gpu: &Gpu, renderer: &mut Renderer, args: &BenchArgs) -> Result<ViewBench> {
        let outputs = (0..args.views)
            .map(|_| renderer.add_output(args.output_format, args.filter))
            .collect::<Result<_, _>>()?;
        let alone = match args.views {
            0 => None,
            _ => Some(Renderer::new(gpu, args.output_format, args.filter)?),
        };
        Ok(ViewBench {
            outputs,
            choose_filter: args.filter == Filter::Mip,
            alone,
            shared: vec![],
            alone_ms: vec![],
        })
    }

    /// Draws the views of the frame just rendered (`plans`) both ways, timing each.
    fn time(
        &mut self,
        renderer: &mut Renderer,
        input: &[u8],
        layout: &PlaneLayout,
        plans: &[FramePlan],
    ) -> Result<()> {
        let Some(alone) = &mut self.alone else {
            return Ok(());
        };
        let jobs: Vec<_> = self.outputs.iter().copied().zip(plans).collect();
        if self.choose_filter {
            for &(id, plan) in &jobs {
                renderer.set_filter(id, plan.cheapest_filter())?;
            }
        }
        let t = Instant::now();
        renderer.redraw(&jobs)?;
        self.shared.push(ms(t.elapsed()));
        let t = Instant::now();
        for plan in plans {
            alone.render(input, layout, plan)?;
        }
        self.alone_ms.push(ms(t.elapsed()));
        Ok(())
    }

    fn report(self, args: &BenchArgs) -> Option<ViewTimes> {
        self.alone.as_ref()?;
        Some(ViewTimes {
            count: args.views,
            size: format!("{}x{}", args.view_size.0, args.view_size.1),
            shared_ms: median(self.shared),
            alone_ms: median(self.alone_ms),
        })
    }
}

/// The CPU reference at the same job, for scale (no upload or readback: it renders the RGB
/// image in memory).
fn bench_cpu(args: &BenchArgs, fish: &RgbImage, plans: &[FramePlan]) -> Measured {
    let bar = progress(args.frames, "cpu");
    let mut times = vec![];
    for plan in &plans[args.warmup as usize..] {
        let t = Instant::now();
        std::hint::black_box(cpu::render(plan, fish, args.filter));
        times.push(ms(t.elapsed()));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let m = median(times);
    Measured {
        adapter: format!("CPU reference ({} threads)", rayon::current_num_threads()),
        backend: "cpu",
        staged: Medians {
            upload_ms: 0.0,
            render_ms: m,
            readback_ms: 0.0,
            total_ms: m,
        },
        pipelined_fps: 1e3 / m,
        pipelined_latency_ms: m,
        views: None,
    }
}
