//! `digiview render` on a video file or an image sequence: GStreamer decodes every frame (none
//! dropped), the GPU renders it with the state's views, and the output goes to an MP4 (H.264)
//! or an image sequence, with a progress bar; or to MPEG-TS, with each frame's KLV metadata if
//! asked. Frames are pipelined: frame N uploads and renders while frame N-1 is read back and
//! encoded.

use super::output::{self, Output};
use crate::frame::PixelFormat;
use crate::lens::{LensCal, Lenses};
use crate::modes::GpuBackend;
use crate::plan::{Filter, FramePlan};
use crate::render::choose;
use crate::render::gpu::Renderer;
use crate::render::gpu::renderer::RenderedFrame;
use crate::source::{FileFrames, SourceSpec};
use crate::state::State;
use crate::stream::encoder::{AccessUnit, Side};
use crate::stream::klv::ViewMetadata;
use crate::stream::record::Container;
use crate::stream::{Codec, Encoder, EncoderConfig, Recorder};
use crate::supervise::Locked;
use anyhow::{Context, Result, anyhow, bail};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub struct VideoJob {
    pub backend: GpuBackend,
    pub input: PathBuf,
    pub out: PathBuf,
    pub input_fps: u32,
    pub bitrate_kbps: u32,
    pub filter: Filter,
    /// KLV with every frame: the camera whose view it describes, and the first frame's
    /// capture time (UNIX seconds; None: the input's modification time less its length).
    pub klv: Option<(usize, Option<f64>)>,
}

/// Where rendered frames go.
enum Sink {
    Video {
        encoder: Encoder,
        recorder: Arc<Mutex<Option<Recorder>>>,
        fps: u32,
        out: Output,
    },
    Images(String),
}

/// `pattern` with its printf-style number (`%05d`, `%d`) replaced by `n`.
pub(super) fn numbered(pattern: &str, n: u64) -> Result<String> {
    let start = pattern.find('%').context("no % in the pattern")?;
    let rest = &pattern[start + 1..];
    let end = rest
        .find('d')
        .context("the pattern's number is %d or %0Nd")?;
    let spec = &rest[..end];
    let width: usize = if spec.is_empty() {
        0
    } else {
        spec.trim_start_matches('0')
            .parse()
            .map_err(|_| anyhow!("the pattern's number is %d or %0Nd, not %{spec}d"))?
    };
    Ok(format!(
        "{}{n:0width$}{}",
        &pattern[..start],
        &rest[end + 1..]
    ))
}

/// Where the frames will go, checked before any work.
enum Target {
    Video(Output, Container),
    Images(String),
}

impl Target {
    fn new(job: &VideoJob) -> Result<Target> {
        let out = job.out.to_string_lossy().to_string();
        // The first files each side names: none of the outputs may be an input.
        let names = |p: &Path| -> Vec<PathBuf> {
            let text = p.to_string_lossy();
            match text.contains('%') {
                true => (0..2)
                    .filter_map(|n| numbered(&text, n).ok())
                    .map(PathBuf::from)
                    .collect(),
                false => vec![p.to_path_buf()],
            }
        };
        let inputs = names(&job.input);
        let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
        for o in names(&job.out) {
            output::refuse_inputs(&o, &inputs)?;
        }
        if out.contains('%') {
            if job.klv.is_some() {
                bail!("--klv goes in an MPEG-TS output (--out NAME.ts), not an image sequence");
            }
            output::image_format(Path::new(&numbered(&out, 0)?))?;
            if let Some(dir) = Path::new(&out)
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
            {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("making {}", dir.display()))?;
            }
            return Ok(Target::Images(out));
        }
        let lower = out.to_ascii_lowercase();
        let container = match () {
            _ if lower.ends_with(".ts") => Container::Ts,
            _ if lower.ends_with(".mp4") && job.klv.is_some() => {
                bail!("{out}: MP4 carries no KLV; --klv renders to MPEG-TS (--out NAME.ts)")
            }
            _ if lower.ends_with(".mp4") => Container::Mp4,
            _ => bail!(
                "{out}: a video renders to .mp4, .ts or an image pattern such as out/%05d.png"
            ),
        };
        Ok(Target::Video(Output::create(&job.out, &inputs)?, container))
    }
}

impl Sink {
    fn open(target: Target, job: &VideoJob, fps: f64) -> Result<Sink> {
        let (out, container) = match target {
            Target::Images(pattern) => return Ok(Sink::Images(pattern)),
            Target::Video(out, container) => (out, container),
        };
        let recorder = Arc::new(Mutex::new(Some(Recorder::start(
            out.temp(),
            Codec::H264,
            container,
        )?)));
        let feed = recorder.clone();
        let fps = fps.round().clamp(1.0, 240.0) as u32;
        let cfg = EncoderConfig {
            kind: "x264".into(),
            codec: Codec::H264,
            bitrate_kbps: job.bitrate_kbps,
            key_interval_s: 2.0,
        };
        let encoder = Encoder::offline(&cfg, fps, move |au: AccessUnit| {
            if let Some(r) = feed.locked().as_mut()
                && let Err(e) = r.push_unit(&au)
            {
                tracing::error!("{e}");
            }
        })?;
        Ok(Sink::Video {
            encoder,
            recorder,
            fps,
            out,
        })
    }

    /// Writes `frame`, shown at `pts`, with its KLV packet if there is one.
    fn write(&mut self, frame: RenderedFrame, pts: Duration, klv: Option<Arc<[u8]>>) -> Result<()> {
        match self {
            Sink::Video { encoder, fps, .. } => {
                let side = Side { stamps: None, klv };
                Ok(encoder.push_with(frame.data, &frame.layout, pts, *fps, side)?)
            }
            Sink::Images(pattern) => {
                let path = numbered(pattern, frame.id)?;
                output::save_image(&frame.to_rgb(), Path::new(&path), &[])
            }
        }
    }

    fn finish(self) -> Result<()> {
        if let Sink::Video {
            encoder,
            recorder,
            out,
            ..
        } = self
        {
            encoder.finish()?;
            let r = recorder.locked().take().context("the recording was lost")?;
            if r.finish()? == crate::stream::record_file::Left::Removed {
                bail!("no frame was written to the video");
            }
            out.keep()?;
        }
        Ok(())
    }
}

/// The KLV packet of the frame shown at `pts`: camera `cam`'s view of `plan`, drawn with
/// `state`, the first frame captured at `start_us`.
fn klv_packet(
    plan: &FramePlan,
    state: &State,
    (cam, start_us): (usize, u64),
    pts: Duration,
) -> Option<Arc<[u8]>> {
    let time_us = start_us + pts.as_micros() as u64;
    ViewMetadata::of_camera(plan, state, cam, time_us).map(|m| m.packet().into())
}

/// When the input's first frame was captured, µs since 1970: as given, else its file's (a
/// sequence's first file's) modification time, less its `length` for a video file.
fn first_capture(job: &VideoJob, given: Option<f64>, length: Option<Duration>) -> Result<u64> {
    if let Some(t) = given {
        return Ok((t * 1e6) as u64);
    }
    let text = job.input.to_string_lossy();
    let (file, less) = match text.contains('%') {
        true => (PathBuf::from(numbered(&text, 0)?), Duration::ZERO),
        false => (job.input.clone(), length.unwrap_or_default()),
    };
    let modified = std::fs::metadata(&file)
        .and_then(|m| m.modified())
        .with_context(|| format!("{}: no modification time for --klv", file.display()))?;
    let since = modified
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .saturating_sub(less);
    Ok(since.as_micros() as u64)
}

/// The input as a source: an image sequence (a `%d` pattern) or a video file.
fn source_spec(job: &VideoJob) -> Result<SourceSpec> {
    let text = job.input.to_string_lossy().to_string();
    if text.contains('%') {
        return Ok(SourceSpec::Sequence(text));
    }
    if job.input.is_dir() {
        bail!(
            "{} is a directory; give a video file or an image sequence such as {}/%05d.png",
            job.input.display(),
            job.input.display()
        );
    }
    if !job.input.is_file() {
        bail!("{}: no such file", job.input.display());
    }
    Ok(SourceSpec::File(job.input.clone()))
}

/// A sequence's length: its files, counted from 0 until one is missing.
fn sequence_length(spec: &SourceSpec, fps: u32) -> Option<Duration> {
    let SourceSpec::Sequence(p) = spec else {
        return None;
    };
    let n = (0..)
        .take_while(|&i| numbered(p, i).is_ok_and(|f| Path::new(&f).is_file()))
        .count();
    Some(Duration::from_secs_f64(n as f64 / fps as f64))
}

fn progress_bar(duration: Option<Duration>) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(duration.map_or(0, |d| d.as_millis() as u64));
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} rendering [{bar:30}] {percent}% {msg} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

/// A render under way: the frames pushed and not yet out (their times), where they go, the
/// plan for the input's size, and what was done.
struct Run<'a> {
    state: &'a State,
    job: &'a VideoJob,
    lenses: Lenses,
    renderer: Renderer,
    /// Where the frames go, once the first frame gave the rate.
    target: Option<Target>,
    sink: Option<Sink>,
    plan: Option<((u32, u32), FramePlan)>,
    times: VecDeque<Duration>,
    /// KLV with every frame: its camera and the first frame's capture time (µs, UNIX).
    klv: Option<(usize, u64)>,
    count: u64,
    /// The last frame's time and the input's rate then.
    last: Option<(Duration, f64)>,
    started: Instant,
    bar: indicatif::ProgressBar,
}

impl Run<'_> {
    /// Renders one frame (pipelined: what comes out is the one before).
    fn frame(&mut self, frame: crate::frame::Frame, pts: Duration, fps: Option<f64>) -> Result<()> {
        let (state, job) = (self.state, self.job);
        self.last = Some((pts, fps.unwrap_or(job.input_fps as f64)));
        let size = (frame.layout.width, frame.layout.height);
        if self.plan.as_ref().is_none_or(|(s, _)| *s != size) {
            let settings = &state.settings;
            let lens = self
                .lenses
                .for_frame(settings.lens, size, settings.sensor.roi())?;
            self.plan = Some((size, FramePlan::new(state, &lens)?));
        }
        if let Some(t) = self.target.take() {
            self.sink = Some(Sink::open(t, job, fps.unwrap_or(job.input_fps as f64))?);
        }
        let (_, p) = self.plan.as_ref().expect("planned above");
        self.times.push_back(pts);
        if let Some(done) = self.renderer.push(&frame.data, &frame.layout, p)? {
            let t = self.times.pop_front().unwrap_or_default();
            let packet = self.klv.and_then(|k| klv_packet(p, state, k, t));
            self.sink
                .as_mut()
                .expect("opened above")
                .write(done, t, packet)?;
        }
        self.count += 1;
        self.bar.set_position(pts.as_millis() as u64);
        let rate = self.count as f64 / self.started.elapsed().as_secs_f64();
        self.bar
            .set_message(format!("{} frames, {rate:.1} fps", self.count));
        Ok(())
    }

    /// Ctrl-C: an image sequence keeps every frame counted (the one in the pipeline written
    /// too); a video is not written.
    fn interrupted(mut self) -> Result<()> {
        self.bar.finish_and_clear();
        let (count, out) = (self.count, self.job.out.display());
        let Some(images @ Sink::Images(_)) = &mut self.sink else {
            bail!("interrupted after {count} frames: {out} was not written")
        };
        while let Some(done) = self.renderer.flush()? {
            let t = self.times.pop_front().unwrap_or_default();
            images.write(done, t, None)?;
        }
        bail!("interrupted after {count} frames; the frames rendered so far are in {out}")
    }

    /// The frames still in the pipeline written, the output closed, and what was done said;
    /// an input shorter than its container announces is an error once its frames are kept.
    fn finish(mut self, duration: Option<Duration>) -> Result<()> {
        let (state, job, count) = (self.state, self.job, self.count);
        let Some(mut sink) = self.sink.take() else {
            bail!("{}: no frames", job.input.display());
        };
        while let Some(done) = self.renderer.flush()? {
            let t = self.times.pop_front().unwrap_or_default();
            let packet = match (self.klv, &self.plan) {
                (Some(k), Some((_, p))) => klv_packet(p, state, k, t),
                _ => None,
            };
            sink.write(done, t, packet)?;
        }
        sink.finish()?;
        self.bar.finish_and_clear();
        let secs = self.started.elapsed().as_secs_f64();
        let out = &state.settings.output;
        eprintln!(
            "wrote {}: {count} frames ({}x{}) in {secs:.1} s, {:.1} fps",
            job.out.display(),
            out.width,
            out.height,
            count as f64 / secs
        );
        if let (Some(length), Some((pts, fps))) = (duration, self.last) {
            let end = pts.as_secs_f64() + 1.0 / fps;
            if end + 1.0 / fps < length.as_secs_f64() {
                bail!(
                    "{} ended at {end:.2} s of the {:.2} s its container announces (truncated \
                     or damaged?); the {count} frames decoded were rendered to {}",
                    job.input.display(),
                    length.as_secs_f64(),
                    job.out.display()
                );
            }
        }
        Ok(())
    }
}

pub fn render_video(cal: &LensCal, state: &State, job: &VideoJob) -> Result<()> {
    let spec = source_spec(job)?;
    let target = Some(Target::new(job)?);
    let interrupted = output::interrupted();
    let mut frames = FileFrames::open(&spec, job.input_fps)?;
    let duration = frames
        .duration()
        .or_else(|| sequence_length(&spec, job.input_fps));
    let klv = match job.klv {
        Some((cam, start)) => Some((cam, first_capture(job, start, duration)?)),
        None => None,
    };
    let out_format = match job.out.to_string_lossy().contains('%') {
        true => PixelFormat::Rgba,
        false => PixelFormat::I420,
    };
    let mut renderer = Renderer::new(&choose::open(job.backend)?.gpu, out_format, job.filter)?;
    renderer.fixed_view_kinds();
    let mut run = Run {
        state,
        job,
        lenses: Lenses::new(cal),
        renderer,
        target,
        sink: None,
        plan: None,
        times: VecDeque::new(),
        klv,
        count: 0,
        last: None,
        started: Instant::now(),
        bar: progress_bar(duration),
    };
    loop {
        if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
            return run.interrupted();
        }
        let next = frames
            .next_frame()
            .with_context(|| format!("decoding {}", job.input.display()))?;
        let Some((frame, pts, fps)) = next else {
            break;
        };
        run.frame(frame, pts, fps)?;
    }
    run.finish(duration)
}

#[cfg(test)]
mod tests {
    use super::numbered;

    #[test]
    fn sequence_patterns_number_their_files() {
        assert_eq!(numbered("out/%05d.png", 42).unwrap(), "out/00042.png");
        assert_eq!(numbered("f%d.jpg", 7).unwrap(), "f7.jpg");
        assert!(numbered("f%s.png", 1).is_err());
        assert!(numbered("f.png", 1).is_err());
    }
}
