//! The files `render` and `synth` write, at the end of their path: each is checked before any
//! work (its format, its directory, and that it is none of the inputs, by whatever path or
//! link), written under a hidden temporary name beside it, and renamed into place only once
//! complete. A failed or interrupted command leaves no partial file, and never replaces an
//! input. An output that is a symbolic link is written through (the file it names replaced,
//! the link kept), and a file replaced keeps its mode.

use anyhow::{Context, Result, bail};
use image::ImageFormat;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A file being written: `temp()` until [`Output::keep`] renames it to its final path.
/// Dropped without `keep` (an error, a panic, an interrupt), the temporary file goes.
pub struct Output {
    path: PathBuf,
    temp: tempfile::TempPath,
    /// The mode of the file replaced, kept (None: a new file, made as the umask says).
    mode: Option<u32>,
}

/// Where writing `path` lands: through a symbolic link, the file the link names (so the link
/// stays a link), else `path` itself.
fn written_path(path: &Path) -> PathBuf {
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    if !is_link {
        return path.to_path_buf();
    }
    std::fs::canonicalize(path).unwrap_or_else(|_| {
        // A link to a file not made yet: the path it names, from the link's directory.
        let named = std::fs::read_link(path).unwrap_or_default();
        path.parent().unwrap_or(Path::new(".")).join(named)
    })
}

impl Output {
    /// Refuses `path` when it is one of `inputs`, and makes its temporary file (which shows
    /// that the directory exists and can be written).
    pub fn create(path: &Path, inputs: &[&Path]) -> Result<Output> {
        use std::os::unix::fs::PermissionsExt;
        refuse_inputs(path, inputs)?;
        let path = &written_path(path);
        let mode = std::fs::metadata(path)
            .ok()
            .map(|m| m.permissions().mode() & 0o7777);
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !dir.is_dir() {
            bail!(
                "{}: the directory {} does not exist",
                path.display(),
                dir.display()
            );
        }
        let name = path
            .file_name()
            .with_context(|| format!("{}: not a file name", path.display()))?;
        let temp = tempfile::Builder::new()
            .prefix(&format!(".{}.", name.to_string_lossy()))
            .suffix(".partial")
            .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
            .tempfile_in(dir)
            .with_context(|| format!("cannot write in {}", dir.display()))?
            .into_temp_path();
        Ok(Output {
            path: path.to_path_buf(),
            temp,
            mode,
        })
    }

    /// Where to write until the file is complete.
    pub fn temp(&self) -> &Path {
        &self.temp
    }

    /// Renames the complete file into place (replacing any file there that is not an input).
    pub fn keep(self) -> Result<PathBuf> {
        if let Some(mode) = self.mode {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&self.temp, std::fs::Permissions::from_mode(mode))
                .with_context(|| format!("cannot keep the mode of {}", self.path.display()))?;
        }
        self.temp
            .persist(&self.path)
            .map_err(|e| e.error)
            .with_context(|| format!("cannot move the finished file to {}", self.path.display()))?;
        Ok(self.path)
    }
}

/// Whether `a` and `b` are the same file: the same device and inode, so another path to it,
/// a symbolic link or a hard link all count. A path that does not exist is no file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// Refuses an output that is one of the inputs.
pub fn refuse_inputs(out: &Path, inputs: &[&Path]) -> Result<()> {
    if let Some(input) = inputs.iter().find(|i| same_file(out, i)) {
        bail!(
            "{} is the input {}: writing it would destroy the input; choose another --out",
            out.display(),
            input.display()
        );
    }
    Ok(())
}

/// The still image format of `path`, from its extension (PNG or JPEG), checked before work.
pub fn image_format(path: &Path) -> Result<ImageFormat> {
    match ImageFormat::from_path(path) {
        Ok(f @ (ImageFormat::Png | ImageFormat::Jpeg)) => Ok(f),
        _ => bail!(
            "{}: images are written as .png or .jpg (.jpeg)",
            path.display()
        ),
    }
}

/// An image to be written at `path`: its format, its directory and that it is no input are
/// checked now, before the work that makes it.
pub fn image_output(path: &Path, inputs: &[&Path]) -> Result<Output> {
    image_format(path)?;
    Output::create(path, inputs)
}

/// Writes `img` to `out` and renames it into place.
pub fn write_image(img: &image::RgbImage, out: Output) -> Result<PathBuf> {
    let format = image_format(&out.path)?;
    img.save_with_format(out.temp(), format)
        .with_context(|| format!("writing {}", out.path.display()))?;
    out.keep()
}

/// Saves `img` to `path` through a temporary file.
pub fn save_image(img: &image::RgbImage, path: &Path, inputs: &[&Path]) -> Result<()> {
    write_image(img, image_output(path, inputs)?).map(drop)
}

/// Set once Ctrl-C (SIGINT) or SIGTERM arrives, so a long command stops between frames,
/// cleans up and says so. A second signal ends the process at once (exit 130).
pub fn interrupted() -> Arc<AtomicBool> {
    use tokio::signal::unix::{SignalKind, signal};
    let flag = Arc::new(AtomicBool::new(false));
    let set = flag.clone();
    // The handlers are in place before this returns: a signal that comes at once is counted,
    // not the default ending without a word.
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            tracing::warn!("cannot watch for Ctrl-C: {e}");
            return flag;
        }
    };
    let signals = {
        let _inside = rt.enter();
        signal(SignalKind::interrupt()).and_then(|i| Ok((i, signal(SignalKind::terminate())?)))
    };
    let (mut int, mut term) = match signals {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cannot watch for Ctrl-C: {e}");
            return flag;
        }
    };
    let watcher = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            rt.block_on(async {
                for _ in 0..2 {
                    // Only a signal counts: a stream that ends (None) is no second Ctrl-C.
                    tokio::select! {
                        Some(()) = int.recv() => {}
                        Some(()) = term.recv() => {}
                        else => return,
                    }
                    if set.swap(true, Ordering::SeqCst) {
                        std::process::exit(130);
                    }
                }
            });
        });
    if let Err(e) = watcher {
        tracing::warn!("cannot watch for Ctrl-C: {e}");
    }
    flag
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_output_appears_only_when_kept_and_never_replaces_an_input() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.mp4");
        std::fs::write(&input, b"input").unwrap();
        let link = dir.path().join("link.mp4");
        std::os::unix::fs::symlink(&input, &link).unwrap();
        let hard = dir.path().join("hard.mp4");
        std::fs::hard_link(&input, &hard).unwrap();
        let other_path = dir.path().join(".").join("in.mp4");
        for out in [&input, &link, &hard, &other_path] {
            let e = Output::create(out, &[&input]).err().expect("refused");
            assert!(e.to_string().contains("would destroy the input"), "{e}");
        }

        let out = dir.path().join("out.mp4");
        let o = Output::create(&out, &[&input]).unwrap();
        std::fs::write(o.temp(), b"half").unwrap();
        drop(o);
        assert!(!out.exists());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            3,
            "no leftovers"
        );

        let o = Output::create(&out, &[&input]).unwrap();
        std::fs::write(o.temp(), b"whole").unwrap();
        o.keep().unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"whole");
        assert_eq!(std::fs::read(&input).unwrap(), b"input");

        let e = Output::create(&dir.path().join("no/such/dir.mp4"), &[])
            .err()
            .unwrap();
        assert!(e.to_string().contains("does not exist"), "{e}");
        assert!(image_format(Path::new("s.bmp")).is_err());
        assert!(image_format(Path::new("s.JPG")).is_ok());
    }
}
