//! Where the command line finds lens.cal and digiview.toml, so `digiview` runs from any
//! directory and as an installed binary. First match wins: the flag, the environment
//! variable, the working directory, the user's config directory (`$XDG_CONFIG_HOME/digiview`
//! or `~/.config/digiview`), `/etc/digiview`; failing all, the lens.cal shipped with the
//! source (built into the binary) or the configuration's defaults. A file named by the flag
//! or the variable must exist; a file found must parse (a broken file is an error, never
//! passed over for the next). Start-up logs which one was used.

use crate::app::Config;
use crate::lens::LensCal;
use anyhow::{Result, bail};
use std::fmt;
use std::path::{Path, PathBuf};

/// The lens.cal shipped with DigiView, used when no file is found.
const BUILT_IN_LENS_CAL: &str = include_str!("../../lens-cal/lens.cal");

/// Where a file came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// Named by a flag or its environment variable (the name says which).
    Named(PathBuf, &'static str),
    /// Found in a searched directory (described).
    Found(PathBuf, &'static str),
    /// None found: the built-in lens.cal or the default configuration.
    BuiltIn,
}

impl Origin {
    /// The file, unless built in.
    pub fn path(&self) -> Option<&Path> {
        match self {
            Origin::Named(p, _) | Origin::Found(p, _) => Some(p),
            Origin::BuiltIn => None,
        }
    }
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Origin::Named(p, by) => write!(f, "{} (from {by})", p.display()),
            Origin::Found(p, place) => write!(f, "{} (found in {place})", p.display()),
            Origin::BuiltIn => write!(f, "built in (no file found)"),
        }
    }
}

/// The file a `flag` or `env` variable names, else the first of `name` in the searched
/// directories that exists.
fn find(
    flag: Option<&Path>,
    flag_name: &'static str,
    env: &'static str,
    names: &[&str],
) -> Result<Origin> {
    let named = match (flag, std::env::var_os(env).filter(|v| !v.is_empty())) {
        (Some(p), _) => Some((p.to_path_buf(), flag_name)),
        (None, Some(v)) => Some((PathBuf::from(v), env)),
        (None, None) => None,
    };
    if let Some((path, by)) = named {
        if path.is_dir() {
            bail!(
                "{} (from {by}) is a directory: name the file in it",
                path.display()
            );
        }
        if !path.is_file() {
            bail!("{} (from {by}): no such file", path.display());
        }
        return Ok(Origin::Named(absolute(path), by));
    }
    for (dir, place) in search_dirs() {
        for name in names {
            let path = dir.join(name);
            if path.is_file() {
                return Ok(Origin::Found(absolute(path), place));
            }
        }
    }
    Ok(Origin::BuiltIn)
}

/// The path as the log shows it: absolute, so it says which file whatever the directory.
fn absolute(path: PathBuf) -> PathBuf {
    std::path::absolute(&path).unwrap_or(path)
}

/// The directories searched, in order, with how the log names them.
fn search_dirs() -> Vec<(PathBuf, &'static str)> {
    let mut dirs = vec![(PathBuf::from("."), "the working directory")];
    if let Some(d) = user_config_dir() {
        dirs.push((d.join("digiview"), "the user's config directory"));
    }
    dirs.push((PathBuf::from("/etc/digiview"), "/etc/digiview"));
    dirs
}

/// The XDG base directory for configuration: `$XDG_CONFIG_HOME`, else `~/.config` (two
/// variables; a crate for it would add more than it saves).
pub fn user_config_dir() -> Option<PathBuf> {
    let set = |k| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    set("XDG_CONFIG_HOME")
        .filter(|p| p.is_absolute())
        .or_else(|| set("HOME").map(|h| h.join(".config")))
}

/// lens.cal, from `--lens-cal`, `DIGIVIEW_LENS_CAL`, `./lens.cal`, `./lens-cal/lens.cal` (a
/// source checkout), the user's and the system's config directories, or the built-in one.
pub fn lens_cal(flag: Option<&Path>) -> Result<(LensCal, Origin)> {
    let origin = lens_cal_origin(flag)?;
    let cal = match origin.path() {
        Some(p) => LensCal::load(p)?,
        None => built_in_lens_cal(),
    };
    if cal.entries.is_empty() {
        anyhow::bail!(
            "{}: no [[lens]] entries; every command needs at least one lens (add one with \
             `digiview lens import --write`, or remove the file to use the built-in lenses)",
            cal.path.display()
        );
    }
    tracing::info!("lens.cal: {origin}");
    Ok((cal, origin))
}

/// Which lens.cal is in use, without reading it (`lens import --write` adds to it, even
/// when it is still empty).
pub fn lens_cal_origin(flag: Option<&Path>) -> Result<Origin> {
    find(
        flag,
        "--lens-cal",
        "DIGIVIEW_LENS_CAL",
        &["lens.cal", "lens-cal/lens.cal"],
    )
}

/// The lens.cal built into the binary.
pub fn built_in_lens_cal() -> LensCal {
    LensCal::parse(Path::new("<built-in lens.cal>"), BUILT_IN_LENS_CAL)
        .expect("the shipped lens.cal parses (a unit test checks it)")
}

/// The text of the built-in lens.cal, where `lens import --write` starts a new file.
pub fn built_in_lens_cal_text() -> &'static str {
    BUILT_IN_LENS_CAL
}

/// digiview.toml, from `--config`, `DIGIVIEW_CONFIG`, `./digiview.toml`, the user's and the
/// system's config directories, or the defaults.
pub fn config(flag: Option<&Path>) -> Result<(Config, Origin)> {
    let origin = find(flag, "--config", "DIGIVIEW_CONFIG", &["digiview.toml"])?;
    let cfg = match origin.path() {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    match origin {
        Origin::BuiltIn => tracing::info!("config: the defaults (no digiview.toml found)"),
        _ => tracing::info!("config: {origin}"),
    }
    Ok((cfg, origin))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_built_in_lens_cal_is_the_shipped_file_and_parses() {
        let cal = super::built_in_lens_cal();
        let names: Vec<_> = cal.entries.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "CIL216", "CIL018", "LN007", "BOSON320", "DUALF", "DUALB", "DUAL"
            ]
        );
    }
}
