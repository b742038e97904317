//! `digiview render` on a video file or an image sequence: GStreamer decodes every frame (none
//! dropped), the GPU renders it with the state's views, and the output goes to an MP4 (H.264)
//! or an image sequence, with a progress bar. Frames are pipelined: frame N uploads and
//! renders while frame N-1 is read back and encoded.

use super::output::{self, Output};
use crate::frame::PixelFormat;
use crate::lens::{LensCal, Lenses};
use crate::render::gpu::renderer::RenderedFrame;
use crate::render::gpu::{Gpu, Renderer};
use crate::render::{Filter, FramePlan};
use crate::source::{FileFrames, SourceSpec};
use crate::state::State;
use crate::stream::encoder::AccessUnit;
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
}

/// Where rendered frames go.
enum Sink {
    Mp4 {
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
    Mp4(Output),
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
        if !out.to_ascii_lowercase().ends_with(".mp4") {
            bail!("{out}: a video renders to .mp4 or to an image pattern such as out/%05d.png");
        }
        Ok(Target::Mp4(Output::create(&job.out, &inputs)?))
    }
}

impl Sink {
    fn open(target: Target, job: &VideoJob, fps: f64) -> Result<Sink> {
        let out = match target {
            Target::Images(pattern) => return Ok(Sink::Images(pattern)),
            Target::Mp4(out) => out,
        };
        let recorder = Arc::new(Mutex::new(Some(Recorder::start(
            out.temp(),
            Codec::H264,
            Container::Mp4,
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
                && let Err(e) = r.push(&au.buffer, au.key)
            {
                tracing::error!("{e}");
            }
        })?;
        Ok(Sink::Mp4 {
            encoder,
            recorder,
            fps,
            out,
        })
    }

    fn write(&mut self, frame: RenderedFrame, pts: Duration) -> Result<()> {
        match self {
            Sink::Mp4 { encoder, fps, .. } => {
                Ok(encoder.push(frame.data, &frame.layout, pts, *fps)?)
            }
            Sink::Images(pattern) => {
                let path = numbered(pattern, frame.id)?;
                output::save_image(&frame.to_rgb(), Path::new(&path), &[])
            }
        }
    }

    fn finish(self) -> Result<()> {
        if let Sink::Mp4 {
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
            match &sink {
                Some(Sink::Images(_)) => bail!(
                    "interrupted after {count} frames; the frames rendered so far are in {}",
                    job.out.display()
                ),
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
            let lens = lenses.for_frame(state.lens, size, state.sensor.roi())?;
            plan = Some((size, FramePlan::new(state, &lens)?));
        }
        if let Some(t) = target.take() {
            sink = Some(Sink::open(t, job, fps.unwrap_or(job.input_fps as f64))?);
        }
        let (_, p) = plan.as_ref().unwrap();
        times.push_back(pts);
        if let Some(done) = renderer.push(&frame.data, &frame.layout, p)? {
            let t = times.pop_front().unwrap_or_default();
            sink.as_mut().unwrap().write(done, t)?;
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
        sink.write(done, t)?;
    }
    sink.finish()?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    eprintln!(
        "wrote {}: {count} frames ({}x{}) in {secs:.1} s, {:.1} fps",
        job.out.display(),
        state.output.width,
        state.output.height,
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
