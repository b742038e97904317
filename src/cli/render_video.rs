//! `digiview render` on a video file or an image sequence: GStreamer decodes every frame (none
//! dropped), the GPU renders it with the state's views, and the output goes to an MP4 (H.264)
//! or an image sequence, with a progress bar; or to MPEG-TS, with each frame's KLV metadata if
//! asked. Frames are pipelined: frame N uploads and renders while frame N-1 is read back and
//! encoded.

use super::output::{self, Output};
use crate::frame::PixelFormat;
use crate::lens::{LensCal, Lenses};
use crate::render::gpu::renderer::RenderedFrame;
use crate::render::gpu::{Gpu, Renderer};
use crate::render::{Filter, FramePlan};
use crate::source::{FileFrames, SourceSpec};
use crate::state::State;
use crate::stream::encoder::{AccessUnit, Side};
use crate::stream::klv::ViewMetadata;
use crate::stream::record::Container;
use crate::stream::{Codec, Encoder, EncoderConfig, Recorder};
use anyhow::{Context, Result, anyhow, bail};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub struct VideoJob {
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
            if let Some(r) = feed.lock().unwrap_or_else(|e| e.into_inner()).as_mut()
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
            let r = recorder
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
                .context("the recording was lost")?;
            r.finish()?;
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

pub fn render_video(cal: &LensCal, state: &State, job: &VideoJob) -> Result<()> {
    let text = job.input.to_string_lossy().to_string();
    let spec = if text.contains('%') {
        SourceSpec::Sequence(text)
    } else {
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
        SourceSpec::File(job.input.clone())
    };
    let mut target = Some(Target::new(job)?);
    let interrupted = output::interrupted();
    let mut frames = FileFrames::open(&spec, job.input_fps)?;
    let duration = frames.duration().or_else(|| match &spec {
        // A sequence's length: its files, counted from 0 until one is missing.
        SourceSpec::Sequence(p) => {
            let n = (0..)
                .take_while(|&i| numbered(p, i).is_ok_and(|f| Path::new(&f).is_file()))
                .count();
            Some(Duration::from_secs_f64(n as f64 / job.input_fps as f64))
        }
        _ => None,
    });
    let klv = match job.klv {
        Some((cam, start)) => Some((cam, first_capture(job, start, duration)?)),
        None => None,
    };
    let out_format = if job.out.to_string_lossy().contains('%') {
        PixelFormat::Rgba
    } else {
        PixelFormat::I420
    };
    let lenses = Lenses::new(cal);
    let gpu = Gpu::new()?;
    let mut renderer = Renderer::new(&gpu, out_format, job.filter)?;
    renderer.fixed_view_kinds();
    let bar = indicatif::ProgressBar::new(duration.map_or(0, |d| d.as_millis() as u64));
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} rendering [{bar:30}] {percent}% {msg} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let started = Instant::now();
    let mut sink: Option<Sink> = None;
    let mut plan: Option<((u32, u32), FramePlan)> = None;
    let mut times: VecDeque<Duration> = VecDeque::new();
    let mut count = 0u64;
    let mut last = None;
    loop {
        if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
            bar.finish_and_clear();
            match &mut sink {
                Some(images @ Sink::Images(_)) => {
                    // The frame still in the pipeline is written too: every frame counted
                    // is on disk.
                    while let Some(done) = renderer.flush()? {
                        let t = times.pop_front().unwrap_or_default();
                        images.write(done, t, None)?;
                    }
                    bail!(
                        "interrupted after {count} frames; the frames rendered so far are in {}",
                        job.out.display()
                    )
                }
                _ => bail!(
                    "interrupted after {count} frames: {} was not written",
                    job.out.display()
                ),
            }
        }
        let next = frames
            .next_frame()
            .with_context(|| format!("decoding {}", job.input.display()))?;
        let Some((frame, pts, fps)) = next else {
            break;
        };
        last = Some((pts, fps.unwrap_or(job.input_fps as f64)));
        let size = (frame.layout.width, frame.layout.height);
        if plan.as_ref().is_none_or(|(s, _)| *s != size) {
            let lens = lenses.for_frame(state.settings.lens, size, state.settings.sensor.roi())?;
            plan = Some((size, FramePlan::new(state, &lens)?));
        }
        if let Some(t) = target.take() {
            sink = Some(Sink::open(t, job, fps.unwrap_or(job.input_fps as f64))?);
        }
        let (_, p) = plan.as_ref().unwrap();
        times.push_back(pts);
        if let Some(done) = renderer.push(&frame.data, &frame.layout, p)? {
            let t = times.pop_front().unwrap_or_default();
            let packet = klv.and_then(|k| klv_packet(p, state, k, t));
            sink.as_mut().unwrap().write(done, t, packet)?;
        }
        count += 1;
        bar.set_position(pts.as_millis() as u64);
        bar.set_message(format!(
            "{count} frames, {:.1} fps",
            count as f64 / started.elapsed().as_secs_f64()
        ));
    }
    let Some(mut sink) = sink else {
        bail!("{}: no frames", job.input.display());
    };
    while let Some(done) = renderer.flush()? {
        let t = times.pop_front().unwrap_or_default();
        let packet = match (klv, &plan) {
            (Some(k), Some((_, p))) => klv_packet(p, state, k, t),
            _ => None,
        };
        sink.write(done, t, packet)?;
    }
    sink.finish()?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    eprintln!(
        "wrote {}: {count} frames ({}x{}) in {secs:.1} s, {:.1} fps",
        job.out.display(),
        state.settings.output.width,
        state.settings.output.height,
        count as f64 / secs
    );
    // A container that says it is longer than what decoded was cut short: the frames are
    // kept, and the exit status says the input was not whole.
    if let (Some(length), Some((pts, fps))) = (duration, last) {
        let end = pts.as_secs_f64() + 1.0 / fps;
        if end + 1.0 / fps < length.as_secs_f64() {
            bail!(
                "{} ended at {end:.2} s of the {:.2} s its container announces (truncated or \
                 damaged?); the {count} frames decoded were rendered to {}",
                job.input.display(),
                length.as_secs_f64(),
                job.out.display()
            );
        }
    }
    Ok(())
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
