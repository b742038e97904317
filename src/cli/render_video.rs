//! `digiview render` on a video file or an image sequence: GStreamer decodes every frame (none
//! dropped), the GPU renders it with the state's views, and the output goes to an MP4 (H.264)
//! or an image sequence, with a progress bar. Frames are pipelined: frame N uploads and
//! renders while frame N-1 is read back and encoded.

use crate::frame::PixelFormat;
use crate::lens::{LensCal, Lenses};
use crate::render::gpu::renderer::RenderedFrame;
use crate::render::gpu::{Gpu, Renderer};
use crate::render::{Filter, FramePlan};
use crate::source::{FileFrames, SourceSpec};
use crate::state::State;
use crate::stream::encoder::AccessUnit;
use crate::stream::{Encoder, EncoderConfig, Recorder};
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
    },
    Images(String),
}

/// `pattern` with its printf-style number (`%05d`, `%d`) replaced by `n`.
fn numbered(pattern: &str, n: u64) -> Result<String> {
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

impl Sink {
    fn open(job: &VideoJob, fps: f64) -> Result<Sink> {
        let out = job.out.to_string_lossy().to_string();
        if out.contains('%') {
            numbered(&out, 0)?;
            if let Some(dir) = Path::new(&out)
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
            {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("making {}", dir.display()))?;
            }
            return Ok(Sink::Images(out));
        }
        if !out.to_ascii_lowercase().ends_with(".mp4") {
            bail!("{out}: a video renders to .mp4 or to an image pattern such as out/%05d.png");
        }
        let recorder = Arc::new(Mutex::new(Some(Recorder::start(&job.out)?)));
        let feed = recorder.clone();
        let fps = fps.round().clamp(1.0, 240.0) as u32;
        let cfg = EncoderConfig {
            kind: "x264".into(),
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
        })
    }

    fn write(&mut self, frame: RenderedFrame, pts: Duration) -> Result<()> {
        match self {
            Sink::Mp4 { encoder, fps, .. } => {
                Ok(encoder.push(frame.data, &frame.layout, pts, *fps)?)
            }
            Sink::Images(pattern) => {
                let path = numbered(pattern, frame.id)?;
                frame
                    .to_rgb()
                    .save(&path)
                    .with_context(|| format!("writing {path}"))
            }
        }
    }

    fn finish(self) -> Result<()> {
        if let Sink::Mp4 {
            encoder, recorder, ..
        } = self
        {
            encoder.finish()?;
            let r = recorder
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
                .context("the recording was lost")?;
            r.finish()?;
        }
        Ok(())
    }
}

pub fn render_video(cal: &LensCal, state: &State, job: &VideoJob) -> Result<()> {
    let text = job.input.to_string_lossy().to_string();
    let spec = if text.contains('%') {
        SourceSpec::Sequence(text)
    } else {
        if !job.input.is_file() {
            bail!("{}: no such file", job.input.display());
        }
        SourceSpec::File(job.input.clone())
    };
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
    loop {
        let next = frames
            .next_frame()
            .with_context(|| format!("decoding {}", job.input.display()))?;
        let Some((frame, pts, fps)) = next else {
            break;
        };
        let size = (frame.layout.width, frame.layout.height);
        if plan.as_ref().is_none_or(|(s, _)| *s != size) {
            let lens = lenses.for_frame(state.lens, size, state.sensor.roi())?;
            plan = Some((size, FramePlan::new(state, &lens)?));
        }
        if sink.is_none() {
            sink = Some(Sink::open(job, fps.unwrap_or(job.input_fps as f64))?);
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
