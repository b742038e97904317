//! `digiview lens list|show|check|import|board` (`calibrate` is in calibrate_cmd.rs).

use super::lens_entry::{EntryArgs, output_entry};
use super::locate;
use crate::lens::calibrate::Board;
use crate::lens::check::check;
use crate::lens::import::{Format, ImportOptions, import};
use crate::lens::{LensCal, LensEntry};
use crate::units::deg;
use anyhow::{Result, anyhow, bail};
use clap::Subcommand;
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum LensCommand {
    /// One line per lens in lens.cal.
    List,
    /// Everything lens.cal says about one lens, and what follows from it.
    Show { lens: String },
    /// Check lenses (all by default) for consistency; exits 1 if any check fails.
    Check { lenses: Vec<String> },
    /// Turn an existing calibration into a lens.cal entry (printed; --write adds it to lens.cal).
    Import {
        file: PathBuf,
        #[arg(long, value_enum)]
        format: Option<Format>,
        /// Which camera of a Kalibr camchain (default: the first).
        #[arg(long)]
        camera: Option<String>,
        #[command(flatten)]
        entry: EntryArgs,
    },
    /// Calibrate a lens from pictures of a board (printed with `lens board`): prints the
    /// lens.cal entry (--write adds it), with the fit's error and which parts of the image
    /// circle the board covered.
    Calibrate(super::calibrate_cmd::CalibrateArgs),
    /// Measure a lens pair's rotation (how its second lens sits from back to back) from a
    /// frame of any scene with detail around the seam: prints the fitted angles, how well the
    /// two lenses then agree, and the pair's lens.cal table (--write puts it in place).
    PairFit(super::pair_fit_cmd::PairFitArgs),
    /// Draw a calibration board to print: an AprilGrid of tag36h11 tags, as Kalibr's.
    Board {
        /// The board: cols=N,rows=N,tag=LENGTH[,spacing=RATIO] (tag measured across its black
        /// border; spacing, the gap between tags over the tag's side, 0.3 by default).
        #[arg(long, value_parser = Board::parse)]
        board: Board,
        /// The PNG to write (.png: a board is printed from lossless pixels).
        #[arg(long)]
        out: PathBuf,
        /// The printer's resolution, dots per inch (50 to 1200).
        #[arg(long, default_value_t = 300.0)]
        dpi: f64,
    },
}

/// Writes the board's picture and says how to print it and what to tell other tools.
fn draw_board(board: &Board, out: &Path, dpi: f64) -> Result<()> {
    if !(50.0..=1200.0).contains(&dpi) {
        bail!("--dpi {dpi}: between 50 and 1200");
    }
    if super::output::image_format(out)? != image::ImageFormat::Png {
        bail!(
            "{}: a board is written as PNG (.png); JPEG's losses blur the tags' edges",
            out.display()
        );
    }
    let target = super::output::Output::create(out, &[])?;
    let dots_per_metre = dpi / 0.0254;
    let (low, high) = board.extent();
    let size = (high - low) * 1000.0;
    let pixels = (high - low) * dots_per_metre;
    if pixels.max_element() > 30000.0 {
        bail!(
            "a {:.0} x {:.0} mm board at {dpi} dpi is {:.0} x {:.0} px: lower --dpi",
            size.x,
            size.y,
            pixels.x,
            pixels.y
        );
    }
    board
        .picture(dots_per_metre)
        .save_with_format(target.temp(), image::ImageFormat::Png)
        .map_err(|e| anyhow!("cannot write {}: {e}", out.display()))?;
    target.keep()?;
    println!(
        "{}: {} x {} tags, {:.0} x {:.0} px; print at {dpi} dpi with no scaling to get {:.1} x {:.1} mm",
        out.display(),
        board.cols,
        board.rows,
        pixels.x,
        pixels.y,
        size.x,
        size.y
    );
    println!(
        "tags {:.1} mm across their black border, gaps {:.1} mm: measure a printed tag, and give \
         the measured size to `lens calibrate --board`",
        board.tag * 1000.0,
        board.gap() * 1000.0
    );
    println!(
        "Kalibr: target_type: 'aprilgrid', tagCols: {}, tagRows: {}, tagSize: {}, tagSpacing: {}",
        board.cols, board.rows, board.tag, board.spacing
    );
    Ok(())
}

pub fn run(flag: Option<&Path>, cmd: LensCommand) -> Result<()> {
    match cmd {
        LensCommand::Board { board, out, dpi } => draw_board(&board, &out, dpi),
        LensCommand::List => list(&locate::lens_cal(flag)?.0),
        LensCommand::Show { lens } => show(&locate::lens_cal(flag)?.0, &lens),
        LensCommand::Check { lenses } => check_all(&locate::lens_cal(flag)?.0, &lenses),
        LensCommand::Import {
            file,
            format,
            camera,
            entry: args,
        } => {
            let opts = ImportOptions {
                name: &args.name,
                lens_id: args.id,
                fov: args.fov,
                camera: camera.as_deref(),
            };
            let entry = import(&file, format, &opts)?;
            output_entry(flag, &entry, &args)
        }
        LensCommand::Calibrate(args) => super::calibrate_cmd::run(flag, args),
        LensCommand::PairFit(args) => super::pair_fit_cmd::run(flag, args),
    }
}

/// `lens list`: one line a lens.
fn list(cal: &LensCal) -> Result<()> {
    println!(
        "{:<10} {:>3}  {:<15} {:>10} {:>10} {:>9}  provenance",
        "name", "id", "model", "frame", "fov", "circle"
    );
    for e in &cal.entries {
        let lens = e.lens();
        println!(
            "{:<10} {:>3}  {:<15} {:>10} {:>10} {:>7.1}px  {}",
            e.name,
            e.lens_id,
            e.model.name(),
            format!("{}x{}", e.width, e.height),
            deg(lens.fov()),
            lens.circle_radius(),
            e.provenance.kind
        );
    }
    Ok(())
}

/// `lens show`: the entry as lens.cal holds it, with what it works out to.
fn show(cal: &LensCal, lens: &str) -> Result<()> {
    let e = cal.find(lens)?;
    let l = e.lens();
    println!(
        "# {} (lens_id {}), {}:{}",
        e.name,
        e.lens_id,
        cal.path.display(),
        e.line
    );
    println!(
        "# model {}, valid fov {}, model limit {}",
        e.model.name(),
        deg(l.fov()),
        deg(2.0 * l.radial.limits.theta_max)
    );
    println!(
        "# image circle radius {:.1} px about ({:.1}, {:.1})",
        l.circle_radius(),
        l.centre().x,
        l.centre().y
    );
    println!(
        "# {:.1} px per degree at the centre",
        l.pixels_per_radian(0.0).to_radians()
    );
    print!("{}", e.to_toml());
    Ok(())
}

/// `lens check`: every check of the lenses named (all of them by default), one line each.
fn check_all(cal: &LensCal, lenses: &[String]) -> Result<()> {
    let chosen: Vec<&LensEntry> = if lenses.is_empty() {
        cal.entries.iter().collect()
    } else {
        lenses
            .iter()
            .map(|n| cal.find(n))
            .collect::<Result<_, _>>()?
    };
    let mut failures = 0;
    for e in chosen {
        for f in check(e) {
            println!(
                "{:<10} {}  {}",
                e.name,
                if f.ok { "ok  " } else { "FAIL" },
                f.what
            );
            failures += usize::from(!f.ok);
        }
    }
    if failures > 0 {
        bail!("{failures} check(s) failed");
    }
    Ok(())
}
