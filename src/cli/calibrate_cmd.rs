//! `digiview lens calibrate`: a video or pictures of a board → the board's corners in each
//! (with a progress bar) → a well-spread subset → a fitted lens → its lens.cal entry, the
//! fit's error, and which parts of the image circle the board covered. Also `synth --board`,
//! the frames a lens would capture of the board at known poses.

use super::calibrate_frames::Pictures;
use super::lens_entry::{EntryArgs, output_entry};
use crate::lens::Model;
use crate::lens::calibrate::fit::{FitModel, Frame, fit};
use crate::lens::calibrate::{Board, Finder, RINGS, SECTORS, coverage, entry, select};
use anyhow::{Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// A video of the board (any file GStreamer decodes, e.g. .mp4 or .mov).
    #[arg(long, required_unless_present = "images", conflicts_with = "images")]
    video: Option<PathBuf>,
    /// A directory of frames (PNG or JPEG, all the same size), taken in name order.
    #[arg(long)]
    images: Option<PathBuf>,
    /// Look at every Nth frame of the video (default: about 200 frames in all).
    #[arg(long, requires = "video")]
    every: Option<u64>,
    /// The board as printed: cols=N,rows=N,tag=LENGTH[,spacing=RATIO], with the tag size
    /// measured on the print.
    #[arg(long, value_parser = Board::parse)]
    board: Board,
    /// The lens model to fit: kannala_brandt (OpenCV's fisheye, Kalibr's equidistant) or
    /// double_sphere (Kalibr's ds).
    #[arg(long, default_value = "kannala_brandt", value_parser = str::parse::<FitModel>)]
    model: FitModel,
    /// The most frames the fit uses: more frames with the board are thinned to a subset
    /// spread over the image.
    #[arg(long, default_value_t = 40, value_parser = |t: &str| crate::units::whole::<u32>(t, 3..=500))]
    max_frames: u32,
    #[command(flatten)]
    entry: EntryArgs,
}

/// Frames found with the board: their corners, and the names of those without it.
struct Found {
    frames: Vec<Frame>,
    without: Vec<String>,
    looked: usize,
    size: (u32, u32),
}

/// Looks for the board in every picture, a batch of frames on all cores at a time, with a
/// progress bar; stops between batches on Ctrl-C.
fn find_all(mut pictures: Pictures, finder: &Finder) -> Result<Found> {
    use rayon::prelude::*;
    let bar = match pictures.len() {
        Some(n) => indicatif::ProgressBar::new(n),
        None => indicatif::ProgressBar::no_length(),
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "finding the board {bar:30} {pos}/{len} frames, {per_sec} eta {eta}",
        )
        .expect("valid template"),
    );
    let stop = super::output::interrupted();
    let batch = 2 * rayon::current_num_threads();
    let mut found = Found {
        frames: vec![],
        without: vec![],
        looked: 0,
        size: (0, 0),
    };
    loop {
        let mut pics = vec![];
        while pics.len() < batch
            && let Some(p) = pictures.next()?
        {
            let this = (p.luma.width(), p.luma.height());
            if found.looked == 0 && pics.is_empty() {
                found.size = this;
            } else if this != found.size {
                bail!(
                    "{} is {}x{}, the frames before it {}x{}: one camera mode at a time",
                    p.name,
                    this.0,
                    this.1,
                    found.size.0,
                    found.size.1
                );
            }
            pics.push(p);
        }
        if pics.is_empty() {
            break;
        }
        let sightings: Vec<_> = pics.par_iter().map(|p| finder.find(&p.luma)).collect();
        for (p, seen) in pics.into_iter().zip(sightings) {
            if seen.len() < 2 {
                found.without.push(p.name);
            } else {
                found.frames.push(Frame::from_sightings(&seen));
            }
            found.looked += 1;
            bar.inc(1);
        }
        if stop.load(std::sync::atomic::Ordering::SeqCst) {
            bar.abandon();
            bail!("interrupted after {} frames: nothing written", found.looked);
        }
    }
    bar.finish_and_clear();
    Ok(found)
}

pub fn run(flag: Option<&Path>, args: CalibrateArgs) -> Result<()> {
    let (pictures, from) = match (&args.video, &args.images) {
        (Some(video), _) => (Pictures::video(video, args.every)?, video),
        (None, Some(dir)) => (Pictures::images(dir)?, dir),
        (None, None) => bail!("give the frames: --video FILE or --images DIR"),
    };
    let found = find_all(pictures, &Finder::new(args.board))?;
    let size = found.size;
    let frames = chosen(found, args.max_frames as usize);
    let corners: Vec<_> = frames
        .iter()
        .flat_map(|f| f.image.iter().copied())
        .collect();
    let got = fit(args.model, &frames, size, |stage| eprintln!("{stage}…"))?;
    eprintln!(
        "{} fx {:.2} fy {:.2} cx {:.2} cy {:.2} {}: reprojection error {:.3} px RMS, {:.3} px \
         worst ({} corners, {} left out as outliers)",
        got.model.name(),
        got.fx,
        got.fy,
        got.cx,
        got.cy,
        coefficients(&got.model),
        got.rms,
        got.worst,
        got.kept,
        got.dropped
    );
    let source = format!(
        "{} frames of the board {}x{} tags of {:.1} mm, spacing {}, from {}",
        frames.len(),
        args.board.cols,
        args.board.rows,
        args.board.tag * 1000.0,
        args.board.spacing,
        from.display()
    );
    let a = &args.entry;
    let e = entry(&got, &a.name, a.id, size, a.fov, &today(), source)?;
    warn_coverage(&e.lens(), &corners);
    output_entry(flag, &e, &args.entry)
}

/// The frames the board was found in, said, and those fitted: at most `max`, chosen to spread
/// over the image.
fn chosen(found: Found, max: usize) -> Vec<Frame> {
    let Found {
        frames,
        without,
        looked,
        size,
    } = found;
    let corners: usize = frames.iter().map(|f| f.image.len()).sum();
    eprintln!(
        "board found in {} of {looked} frames ({corners} corners)",
        frames.len()
    );
    if !without.is_empty() {
        let shown = without.len().min(20);
        eprintln!(
            "no board in {} frames: {}{}",
            without.len(),
            without[..shown].join(", "),
            if shown < without.len() { ", …" } else { "" }
        );
    }
    let chosen = select::spread(&frames, size, max);
    if chosen.len() < frames.len() {
        eprintln!(
            "fitting {} of them, chosen to spread over the image (--max-frames)",
            chosen.len()
        );
    }
    chosen.into_iter().map(|i| frames[i].clone()).collect()
}

/// Warns where the board's corners leave the lens's circle uncovered: beyond the widest angle
/// they reach (extrapolated), and each third of the circle's sectors with none.
fn warn_coverage(lens: &crate::lens::Lens, corners: &[glam::DVec2]) {
    let (covered, widest) = coverage(lens, corners);
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
}

/// A fitted model's own coefficients, as lens.cal names them.
fn coefficients(model: &Model) -> String {
    match model {
        Model::KannalaBrandt(m) => format!(
            "k1 {:.6} k2 {:.6} k3 {:.6} k4 {:.6}",
            m.k[0], m.k[1], m.k[2], m.k[3]
        ),
        Model::DoubleSphere(m) => format!("xi {:.5} alpha {:.5}", m.xi, m.alpha),
        other => format!("{other:?}"),
    }
}

/// Today's date (UTC), YYYY-MM-DD.
pub(super) fn today() -> String {
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

/// `synth --board`: the board before `lens` at each pose (parsed from `poses`, or `sweep`
/// spread over the circle), one frame each, written to `out` (numbered when there are more).
pub fn synth_boards(
    board: &Board,
    poses: &[String],
    sweep: Option<usize>,
    lens: &crate::lens::Lens,
    out: &Path,
) -> Result<()> {
    use crate::scene::board::{BoardPose, board_fisheye};
    let poses: Vec<BoardPose> = match sweep {
        Some(n) if !(1..=1000).contains(&n) => bail!("--board-sweep {n}: 1..=1000 poses"),
        Some(n) => BoardPose::sweep(board, n, lens.half_fov),
        None => poses
            .iter()
            .map(|p| BoardPose::parse(board, p).map_err(anyhow::Error::from))
            .collect::<Result<_>>()?,
    };
    let pattern = out.to_string_lossy().into_owned();
    let name = |i: usize| -> Result<PathBuf> {
        Ok(match pattern.contains('%') {
            true => PathBuf::from(super::render_video::numbered(&pattern, i as u64)?),
            false if poses.len() == 1 => out.to_path_buf(),
            false => bail!(
                "{} poses make {} frames: number --out's files, e.g. frames/%03d.png",
                poses.len(),
                poses.len()
            ),
        })
    };
    // Every name is checked before the first frame is drawn.
    for i in 0..poses.len() {
        super::output::image_format(&name(i)?)?;
    }
    let bar = indicatif::ProgressBar::new(poses.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("drawing the board {bar:30} {pos}/{len} frames")
            .expect("valid template"),
    );
    for (i, pose) in poses.iter().enumerate() {
        let picture = board_fisheye(board, pose, lens, 2);
        super::output::save_image(&picture, &name(i)?, &[])?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    eprintln!(
        "wrote {} frame{} of the board ({}x{}) to {}",
        poses.len(),
        if poses.len() == 1 { "" } else { "s" },
        lens.width,
        lens.height,
        out.display()
    );
    Ok(())
}
