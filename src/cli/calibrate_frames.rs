//! Where `lens calibrate` reads its frames: a directory of pictures (in name order) or a video
//! (any file GStreamer decodes, every Nth frame), each as its luma, the board finder's input.

use crate::frame::Frame;
use crate::source::{FileFrames, SourceSpec};
use anyhow::{Context, Result, bail};
use image::{DynamicImage, GrayImage};
use std::path::{Path, PathBuf};

/// A video longer than this many frames is looked at every Nth frame by default, N chosen to
/// look at about this many.
const LOOKED_AT: u64 = 200;

/// One frame to look for the board in.
pub struct Picture {
    /// The file's name, or the frame's number and time in the video.
    pub name: String,
    /// Its luma (an 8-bit grey image), as the finder takes it.
    pub luma: DynamicImage,
}

pub enum Pictures {
    Images(std::vec::IntoIter<PathBuf>, usize),
    Video {
        frames: FileFrames,
        /// The first frame, read to learn the frame rate.
        first: Option<(Frame, f64)>,
        every: u64,
        /// The next frame's number.
        index: u64,
        /// How many frames will be looked at, when the container says how long it is.
        count: Option<u64>,
    },
}

impl Pictures {
    /// The PNG and JPEG files in `dir`, in name order.
    pub fn images(dir: &Path) -> Result<Pictures> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot read the directory {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg")
                })
            })
            .collect();
        files.sort();
        if files.is_empty() {
            bail!("{}: no PNG or JPEG frames", dir.display());
        }
        let n = files.len();
        Ok(Pictures::Images(files.into_iter(), n))
    }

    /// Every `every`th frame of the video at `path` (by default as many as make about
    /// [`LOOKED_AT`] frames).
    pub fn video(path: &Path, every: Option<u64>) -> Result<Pictures> {
        if !path.is_file() {
            bail!("{}: no such video file", path.display());
        }
        let mut frames = FileFrames::open(&SourceSpec::File(path.to_path_buf()), 30)
            .with_context(|| format!("cannot decode {}", path.display()))?;
        let Some((first, _, fps)) = frames.next_frame()? else {
            bail!("{}: the video has no frames", path.display());
        };
        let total = match (frames.duration(), fps) {
            (Some(d), Some(fps)) => Some((d.as_secs_f64() * fps).round() as u64),
            _ => None,
        };
        let every = match every {
            Some(0) => bail!("--every 0: give 1 to look at every frame"),
            Some(n) => n,
            None => total.map_or(1, |t| t.div_ceil(LOOKED_AT).max(1)),
        };
        if let Some(t) = total {
            eprintln!(
                "{}: about {t} frames at {:.2} fps; looking at every {}",
                path.display(),
                fps.unwrap_or(0.0),
                match every {
                    1 => "frame".to_string(),
                    n => format!("{n}th (--every to change)"),
                }
            );
        }
        Ok(Pictures::Video {
            frames,
            first: Some((first, 0.0)),
            every,
            index: 0,
            count: total.map(|t| t.div_ceil(every)),
        })
    }

    /// How many frames it gives, when known.
    pub fn len(&self) -> Option<u64> {
        match self {
            Pictures::Images(_, n) => Some(*n as u64),
            Pictures::Video { count, .. } => *count,
        }
    }

    /// The next frame, or None at the end.
    pub fn next(&mut self) -> Result<Option<Picture>> {
        match self {
            Pictures::Images(files, _) => {
                let Some(file) = files.next() else {
                    return Ok(None);
                };
                let picture = image::open(&file)
                    .with_context(|| format!("cannot read {}", file.display()))?;
                let name = file
                    .file_name()
                    .map_or(String::new(), |n| n.to_string_lossy().into());
                Ok(Some(Picture {
                    name,
                    luma: DynamicImage::ImageLuma8(picture.to_luma8()),
                }))
            }
            Pictures::Video {
                frames,
                first,
                every,
                index,
                ..
            } => loop {
                let next = match first.take() {
                    Some(f) => Some(f),
                    None => frames.next_frame()?.map(|(f, t, _)| (f, t.as_secs_f64())),
                };
                let Some((frame, seconds)) = next else {
                    return Ok(None);
                };
                let n = *index;
                *index += 1;
                if n % *every == 0 {
                    return Ok(Some(Picture {
                        name: format!("frame {n} ({seconds:.2} s)"),
                        luma: DynamicImage::ImageLuma8(luma(&frame)?),
                    }));
                }
            },
        }
    }
}

/// A decoded frame's luma.
fn luma(frame: &Frame) -> Result<GrayImage> {
    frame
        .luma()
        .context("a decoded frame smaller than its layout")
}
