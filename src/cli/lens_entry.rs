//! A new lens.cal entry, as `lens import` and `lens calibrate` make it: what names it
//! (`--name`, `--id`, `--fov`), printed, or written into the lens.cal in use with the comments
//! around it kept.

use super::locate;
use crate::lens::{LensCal, LensEntry};
use crate::units::parse_angle;
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use std::path::Path;

/// What names a new lens.cal entry and where it goes: `import`'s and `calibrate`'s.
#[derive(Args, Debug)]
pub struct EntryArgs {
    /// The lens's name: 1 to 64 printable characters, no quotes or backslashes.
    #[arg(long, value_parser = lens_name)]
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

/// `--name`: what lens.cal and the protocol's lens list show, so printable text that needs no
/// escaping there.
fn lens_name(text: &str) -> Result<String> {
    let n = text.chars().count();
    if text.trim().is_empty() || n > 64 {
        bail!("a lens name has 1 to 64 characters (this has {n})");
    }
    if let Some(c) = text
        .chars()
        .find(|c| c.is_control() || matches!(c, '"' | '\\'))
    {
        bail!("a lens name is printable text without quotes or backslashes, not {c:?}");
    }
    Ok(text.to_string())
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
fn parse_fov(text: &str) -> Result<f64> {
    let v = parse_angle(text)?;
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
    bail!(
        "{text} is {:.1}°, outside (0, 360deg]{hint}",
        v.to_degrees()
    )
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
    replace_file(path, &body)?;
    Ok(replaced)
}

/// Replaces the file at `path` with `body` whole (a temporary file beside it, renamed over
/// it): through a symbolic link, the file the link names, the link kept; with its mode kept.
fn replace_file(path: &Path, body: &str) -> Result<()> {
    use std::io::Write;
    use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
    let target = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let mode = std::fs::metadata(&target).map_or(0o644, |m| m.permissions().mode() & 0o7777);
    let tmp = target.with_extension("cal.tmp");
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(mode)
        .open(&tmp)
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    // The mode asked for at creation is masked by the umask: set it as it was.
    file.set_permissions(std::fs::Permissions::from_mode(mode))?;
    file.write_all(body.as_bytes())?;
    file.sync_all()?;
    std::fs::rename(&tmp, &target)
        .with_context(|| format!("cannot replace {}", target.display()))?;
    Ok(())
}

/// The text with the `[[lens]]` (or `[[pair]]`) table that starts on 1-based `line` replaced by `table`: its
/// keys go, its comments stay above the new table (marked as the replaced entry's notes), and
/// the comments above it and before the next table stay where they are.
fn replace_table(text: &str, line: usize, table: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let start = line - 1;
    let mut end = (start + 1..lines.len())
        .find(|&i| lines[i].trim_start().starts_with("[["))
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
                .to_string()
                .contains("for degrees write 7deg")
        );
        assert!((parse_fov("190deg").unwrap() - 190f64.to_radians()).abs() < 1e-12);
    }
}
