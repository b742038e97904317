//! `digiview lens list|show|check|import|board` (`calibrate` is in calibrate_cmd.rs).

use super::locate;
use crate::lens::calibrate::Board;
use crate::lens::check::check;
use crate::lens::import::{Format, ImportOptions, import};
use crate::lens::{LensCal, LensEntry};
use crate::units::{deg, parse_angle};
use anyhow::{Result, anyhow, bail};
use clap::{Args, Subcommand};
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
    /// Draw a calibration board to print: an AprilGrid of tag36h11 tags, as Kalibr's.
    Board {
        /// The board: cols=N,rows=N,tag=LENGTH[,spacing=RATIO] (tag measured across its black
        /// border; spacing, the gap between tags over the tag's side, 0.3 by default).
        #[arg(long, value_parser = parse_board)]
        board: Board,
        /// The PNG to write.
        #[arg(long)]
        out: PathBuf,
        /// The printer's resolution, dots per inch (50 to 1200).
        #[arg(long, default_value_t = 300.0)]
        dpi: f64,
    },
}

/// What names a new lens.cal entry and where it goes: `import`'s and `calibrate`'s.
#[derive(Args, Debug)]
pub struct EntryArgs {
    #[arg(long)]
    pub name: String,
    #[arg(long)]
    pub id: u8,
    /// The valid field of view (e.g. 190deg); by default the widest the frame shows.
    #[arg(long, value_parser = parse_fov)]
    pub fov: Option<f64>,
    /// Append the entry to lens.cal.
    #[arg(long)]
    pub write: bool,
    /// With --write: replace the entry of the same name or id.
    #[arg(long, requires = "write")]
    pub replace: bool,
}

pub(super) fn parse_board(text: &str) -> Result<Board, String> {
    Board::parse(text).map_err(|e| e.to_string())
}

/// Writes the board's picture and says how to print it and what to tell other tools.
fn draw_board(board: &Board, out: &Path, dpi: f64) -> Result<()> {
    if !(50.0..=1200.0).contains(&dpi) {
        bail!("--dpi {dpi}: between 50 and 1200");
    }
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
        .save_with_format(out, image::ImageFormat::Png)
        .map_err(|e| anyhow!("cannot write {}: {e}", out.display()))?;
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
        LensCommand::Board { board, out, dpi } => draw_board(&board, &out, dpi)?,
        LensCommand::List => {
            let (cal, _) = locate::lens_cal(flag)?;
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
        }
        LensCommand::Show { lens } => {
            let (cal, _) = locate::lens_cal(flag)?;
            let e = cal.find(&lens)?;
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
        }
        LensCommand::Check { lenses } => {
            let (cal, _) = locate::lens_cal(flag)?;
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
        }
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
            output_entry(flag, &entry, &args)?;
        }
        LensCommand::Calibrate(args) => super::calibrate_cmd::run(flag, args)?,
    }
    Ok(())
}

/// Prints a new entry, or with `write` adds it to the lens.cal in use; in place of the
/// built-in one, to a new file in the user's config directory that starts as its copy.
pub(super) fn output_entry(flag: Option<&Path>, entry: &LensEntry, args: &EntryArgs) -> Result<()> {
    let text = entry.to_toml();
    if !args.write {
        print!("{text}");
        return Ok(());
    }
    let origin = locate::lens_cal_origin(flag)?;
    let (path, old) = match origin.path() {
        Some(p) => (p.to_path_buf(), std::fs::read_to_string(p)?),
        None => {
            let dir = locate::user_config_dir()
                .ok_or_else(|| anyhow!("no lens.cal to add to, and no home directory"))?
                .join("digiview");
            std::fs::create_dir_all(&dir)?;
            let text = locate::built_in_lens_cal_text().to_string();
            (dir.join("lens.cal"), text)
        }
    };
    let replaced = append(&path, &old, entry, &text, args.replace)?;
    let (what, place) = match replaced {
        Some(r) => (format!("replaced {r} with"), "in"),
        None => ("added".to_string(), "to"),
    };
    eprintln!(
        "{what} {} (lens_id {}) {place} {}",
        entry.name,
        entry.lens_id,
        path.display()
    );
    Ok(())
}

/// `--fov`: an angle in (0, 360°].
fn parse_fov(text: &str) -> Result<f64, String> {
    let v = parse_angle(text).map_err(|e| e.to_string())?;
    if v > 0.0 && v <= std::f64::consts::TAU {
        return Ok(v);
    }
    let hint = if text.trim().parse::<f64>().is_ok() {
        format!(
            " (a bare number is radians; for degrees write {}deg)",
            text.trim()
        )
    } else {
        String::new()
    };
    Err(format!(
        "{text} is {:.1}°, outside (0, 360deg]{hint}",
        v.to_degrees()
    ))
}

/// Adds an entry to lens.cal: at the end, or in place of the clashing one with `replace`
/// (the comments around it stay). Only a file that parses is written. Returns
/// the replaced entry's name and line.
fn append(
    path: &Path,
    old: &str,
    entry: &LensEntry,
    text: &str,
    replace: bool,
) -> Result<Option<String>> {
    let entries = if old.contains("[[lens]]") {
        LensCal::parse(path, old)?.entries
    } else {
        Vec::new()
    };
    let clash = entries
        .iter()
        .find(|e| e.name.eq_ignore_ascii_case(&entry.name) || e.lens_id == entry.lens_id);
    let (body, replaced) = match clash {
        Some(c) if !replace => bail!(
            "{} already has {} (lens_id {}) on line {}; use --replace",
            path.display(),
            c.name,
            c.lens_id,
            c.line
        ),
        Some(c) => (
            replace_table(old, c.line, text),
            Some(format!(
                "{} (lens_id {}, line {})",
                c.name, c.lens_id, c.line
            )),
        ),
        None => {
            let mut body = old.to_string();
            if !body.ends_with('\n') && !body.is_empty() {
                body.push('\n');
            }
            body.push('\n');
            body.push_str(text);
            (body, None)
        }
    };
    LensCal::parse(path, &body)?;
    let tmp = path.with_extension("cal.tmp");
    std::fs::write(&tmp, &body)?;
    std::fs::rename(&tmp, path)?;
    Ok(replaced)
}

/// The text with the `[[lens]]` table that starts on 1-based `line` replaced by `table`: its
/// keys go, its comments stay above the new table (marked as the replaced entry's notes), and
/// the comments above it and before the next table stay where they are.
fn replace_table(text: &str, line: usize, table: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let start = line - 1;
    let mut end = (start + 1..lines.len())
        .find(|&i| lines[i].trim_start().starts_with("[[lens]]"))
        .unwrap_or(lines.len());
    while end > start + 1 && {
        let l = lines[end - 1].trim_start();
        l.is_empty() || l.starts_with('#')
    } {
        end -= 1;
    }
    let mut out = lines[..start].join("\n");
    if !out.is_empty() {
        out.push('\n');
    }
    // The replaced entry's own notes are kept above the new one, marked as its.
    let notes: Vec<&str> = lines[start + 1..end]
        .iter()
        .copied()
        .filter(|l| l.trim_start().starts_with('#'))
        .collect();
    if !notes.is_empty() {
        out.push_str("# Notes of the entry this one replaced:\n");
        for n in notes {
            out.push_str(n.trim_start());
            out.push('\n');
        }
    }
    out.push_str(table.trim_end());
    out.push('\n');
    if end < lines.len() {
        out.push('\n');
        out.push_str(&lines[end..].join("\n"));
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replaced_entry_keeps_its_place_and_every_comment() {
        let text = "# lenses of drone 2\n\n# the old one\n[[lens]]\nname = \"A\"\n\
                    # measured 2025\nlens_id = 0\n# inside A\n\n# about B\n[[lens]]\n\
                    name = \"B\"\n";
        let out = replace_table(text, 4, "[[lens]]\nname = \"A2\"\n");
        assert_eq!(
            out,
            "# lenses of drone 2\n\n# the old one\n# Notes of the entry this one \
             replaced:\n# measured 2025\n[[lens]]\nname = \"A2\"\n\n# inside A\n\n\
             # about B\n[[lens]]\nname = \"B\"\n"
        );
        let last = replace_table(text, 11, "[[lens]]\nname = \"B2\"\n");
        assert!(
            last.ends_with("# about B\n[[lens]]\nname = \"B2\"\n"),
            "{last}"
        );
        assert!(
            parse_fov("7")
                .unwrap_err()
                .contains("for degrees write 7deg")
        );
        assert!((parse_fov("190deg").unwrap() - 190f64.to_radians()).abs() < 1e-12);
    }
}
