//! `digiview lens calibrate`: pictures of a board → the board's corners in each (with a
//! progress bar) → a fitted lens → its lens.cal entry, the fit's error, and which parts of the
//! image circle the board covered.

use super::lens_cmd::{EntryArgs, output_entry, parse_board};
use crate::lens::calibrate::fit::{Frame, fit};
use crate::lens::calibrate::{Board, Finder, RINGS, SECTORS, coverage, entry};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// A directory of frames (PNG or JPEG, all the same size), taken in name order.
    #[arg(long)]
    images: PathBuf,
    /// The board as printed: cols=N,rows=N,tag=LENGTH[,spacing=RATIO], with the tag size
    /// measured on the print.
    #[arg(long, value_parser = parse_board)]
    board: Board,
    #[command(flatten)]
    entry: EntryArgs,
}

/// The frames in a directory, in name order.
fn frame_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read the directory {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        bail!("{}: no PNG or JPEG frames", dir.display());
    }
    Ok(files)
}

pub fn run(flag: Option<&Path>, args: CalibrateArgs) -> Result<()> {
    let files = frame_files(&args.images)?;
    let finder = Finder::new(args.board);
    let bar = indicatif::ProgressBar::new(files.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("finding the board {bar:30} {pos}/{len} frames")
            .expect("valid template"),
    );
    let mut size = None;
    let (mut frames, mut without, mut corners) = (vec![], vec![], vec![]);
    for file in &files {
        let picture =
            image::open(file).with_context(|| format!("cannot read {}", file.display()))?;
        let this = (picture.width(), picture.height());
        match size {
            None => size = Some(this),
            Some(s) if s != this => bail!(
                "{} is {}x{}, the frames before it {}x{}: one camera mode at a time",
                file.display(),
                this.0,
                this.1,
                s.0,
                s.1
            ),
            _ => {}
        }
        let found = finder.find(&picture);
        if found.len() < 2 {
            without.push(
                file.file_name()
                    .map_or(String::new(), |n| n.to_string_lossy().into()),
            );
        } else {
            let frame = Frame::from_sightings(&found);
            corners.extend(frame.image.iter().copied());
            frames.push(frame);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let size = size.expect("at least one frame");
    eprintln!(
        "board found in {} of {} frames ({} corners)",
        frames.len(),
        files.len(),
        corners.len()
    );
    if !without.is_empty() {
        eprintln!(
            "no board in {} frames: {}",
            without.len(),
            without.join(", ")
        );
    }
    let got = fit(&frames, size, |stage| eprintln!("{stage}…"))?;
    eprintln!(
        "fx {:.2} fy {:.2} cx {:.2} cy {:.2} k {:?}: reprojection error {:.3} px RMS, {:.3} px worst \
         ({} corners, {} left out as outliers)",
        got.fx, got.fy, got.cx, got.cy, got.k, got.rms, got.worst, got.kept, got.dropped
    );
    let source = format!(
        "{} frames of the board {}x{} tags of {:.1} mm, spacing {}, from {}",
        frames.len(),
        args.board.cols,
        args.board.rows,
        args.board.tag * 1000.0,
        args.board.spacing,
        args.images.display()
    );
    let a = &args.entry;
    let e = entry(&got, &a.name, a.id, size, a.fov, &today(), source)?;
    let lens = e.lens();
    let (covered, widest) = coverage(&lens, &corners);
    eprintln!(
        "the corners reach {:.1}° from the axis, of the {:.1}° the entry is valid to",
        widest.to_degrees(),
        lens.half_fov.to_degrees()
    );
    if widest < 0.9 * lens.half_fov {
        eprintln!(
            "warning: beyond {:.1}° from the axis the lens is extrapolated: film the board nearer \
             the circle's edge, or give --fov {:.0}deg",
            widest.to_degrees(),
            2.0 * widest.to_degrees()
        );
    }
    let ring_names = ["inner", "middle", "outer"];
    for (r, row) in covered.iter().enumerate().take(RINGS) {
        let missing: Vec<String> = (0..SECTORS)
            .filter(|&s| !row[s])
            .map(|s| format!("{}-{}°", s * 45, s * 45 + 45))
            .collect();
        if !missing.is_empty() {
            eprintln!(
                "warning: no corners in the {} third of the circle at azimuths {} (0° is the \
                 frame's right, 90° down): film the board there too",
                ring_names[r],
                missing.join(", ")
            );
        }
    }
    output_entry(flag, &e, &args.entry)
}

/// Today's date (UTC), YYYY-MM-DD.
fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86400) as i64;
    // Days since 1970-01-01 to a civil date (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}
