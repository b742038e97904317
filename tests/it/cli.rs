//! The `digiview` binary as a user runs it: lens commands, synth → render against truth,
//! importing into lens.cal, outputs through links. Its errors for bad input are
//! `cli_errors`'s.

use digiview::image_ops::psnr;
use digiview::layout::layout;
use digiview::modes::{LayoutMode, OverlayMode};
use std::path::Path;
use std::process::{Command, Output};

pub(crate) fn digiview(args: &[&str], cal: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(args)
        .env("DIGIVIEW_LENS_CAL", cal)
        .output()
        .expect("the binary runs")
}

pub(crate) fn shipped() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal")
}

/// A Kalibr camera chain to import.
pub(crate) fn kalibr_sample() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/import/kalibr_camchain.yaml")
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_shipped_lenses_pass_lens_check() {
    let o = digiview(&["lens", "check"], &shipped());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    for name in ["CIL216", "CIL018", "LN007"] {
        assert_eq!(
            out.lines()
                .filter(|l| l.starts_with(name) && l.contains(" ok "))
                .count(),
            5,
            "{out}"
        );
    }
    assert!(!out.contains("FAIL"));
}

#[test]
fn a_malformed_lens_cal_is_reported_with_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.cal");
    let text = std::fs::read_to_string(shipped())
        .unwrap()
        .replacen("fx = 775.0", "fx = -775.0", 1);
    std::fs::write(&bad, &text).unwrap();
    let line = text
        .lines()
        .position(|l| l.starts_with("fx = -775.0"))
        .unwrap()
        + 1;
    let o = digiview(&["lens", "list"], &bad);
    assert!(!o.status.success());
    let want = format!("{}:{line}: fx: must be positive (got -775)", bad.display());
    assert!(stderr(&o).contains(&want), "{} lacks {want}", stderr(&o));
}

#[test]
fn synth_then_render_matches_synth_truth_through_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let state = [
        "--lens",
        "LN007",
        "--size",
        "640x480",
        "--layout",
        "3",
        "--overlay",
        "5",
        "--attitude",
        "roll=15deg,pitch=-5deg",
    ];
    let run = |extra: &[&str]| {
        let args: Vec<&str> = extra.iter().chain(state.iter()).copied().collect();
        let o = digiview(&args, &shipped());
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    let (fish, out, truth) = (p("fish.png"), p("out.png"), p("truth.png"));
    run(&["synth", "--sensor", "1280x720", "--out", &fish]);
    run(&["render", "--input", &fish, "--out", &out]);
    run(&["synth", "--truth", "--sensor", "1280x720", "--out", &truth]);
    let (a, b) = (
        image::open(&out).unwrap().to_rgb8(),
        image::open(&truth).unwrap().to_rgb8(),
    );
    assert_eq!(a.dimensions(), (640, 480));
    for (rect, _) in layout(640, 480, LayoutMode::TwoAndPanorama, OverlayMode::Bottom)
        .unwrap()
        .views
    {
        let db = psnr(&a, &b, rect);
        assert!(db >= 32.0, "view {rect:?}: {db:.1} dB");
    }
}

/// `lens import --write` through a symbolic link to lens.cal writes the file the link names,
/// the link kept, and keeps the file's mode (640 here).
#[test]
fn import_through_a_link_writes_the_linked_file_and_keeps_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("real.cal");
    std::fs::copy(shipped(), &real).unwrap();
    std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o640)).unwrap();
    let link = dir.path().join("lens.cal");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let sample = kalibr_sample();
    let args = [
        "lens",
        "import",
        sample.to_str().unwrap(),
        "--name",
        "KAL",
        "--id",
        "7",
    ];
    let o = digiview(&[&args[..], &["--write"]].concat(), &link);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(std::fs::read_to_string(&real).unwrap().contains("KAL"));
    let mode = std::fs::metadata(&real).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640, "mode {mode:o}");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "no temporary file left: {names:?}");
}

#[test]
fn an_output_through_a_link_writes_the_linked_file_and_keeps_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("real.png");
    std::fs::write(&real, b"an older picture").unwrap();
    std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o640)).unwrap();
    let link = dir.path().join("fish.png");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let out = link.to_str().unwrap();
    let o = digiview(&["synth", "--sensor", "320x240", "--out", out], &shipped());
    assert!(o.status.success(), "{}", stderr(&o));
    let is_link = std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink();
    assert!(is_link, "the link is still a link");
    assert_eq!(image::image_dimensions(&real).unwrap(), (320, 240));
    let mode = std::fs::metadata(&real).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640, "mode {mode:o}");
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 2, "no temporary file left: {names:?}");
}

#[test]
fn import_writes_a_new_lens_and_replaces_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let cal = dir.path().join("lens.cal");
    std::fs::copy(shipped(), &cal).unwrap();
    let sample = kalibr_sample();
    let sample = sample.to_str().unwrap();
    let o = digiview(
        &[
            "lens", "import", sample, "--name", "KAL", "--id", "7", "--fov", "185deg", "--write",
        ],
        &cal,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let list = String::from_utf8_lossy(&digiview(&["lens", "list"], &cal).stdout).into_owned();
    assert!(
        list.contains("KAL") && list.contains("185.00deg") && list.contains("calibrated"),
        "{list}"
    );
    assert!(list.contains("CIL216"), "existing lenses are kept");
    let o = digiview(
        &[
            "lens", "import", sample, "--name", "KAL", "--id", "8", "--write",
        ],
        &cal,
    );
    assert!(
        !o.status.success() && stderr(&o).contains("use --replace"),
        "{}",
        stderr(&o)
    );
    let o = digiview(
        &[
            "lens",
            "import",
            sample,
            "--camera",
            "cam1",
            "--name",
            "KAL",
            "--id",
            "7",
            "--write",
            "--replace",
        ],
        &cal,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("replaced KAL (lens_id 7, line "),
        "{}",
        stderr(&o)
    );
    let text = std::fs::read_to_string(&cal).unwrap();
    let shipped_text = std::fs::read_to_string(shipped()).unwrap();
    for comment in shipped_text
        .lines()
        .filter(|l| l.trim_start().starts_with('#'))
    {
        assert!(
            text.contains(comment),
            "the comment `{comment}` was dropped"
        );
    }
    let list = String::from_utf8_lossy(&digiview(&["lens", "list"], &cal).stdout).into_owned();
    assert_eq!(
        list.lines().count(),
        9,
        "header, seven shipped lenses, one imported: {list}"
    );
    assert!(list.contains("double_sphere"));
    // A shipped lens in the middle of the file: its notes, and every other comment, stay.
    let o = digiview(
        &[
            "lens",
            "import",
            sample,
            "--name",
            "CIL018",
            "--id",
            "1",
            "--write",
            "--replace",
        ],
        &cal,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&cal).unwrap();
    for comment in shipped_text
        .lines()
        .filter(|l| l.trim_start().starts_with('#'))
    {
        assert!(
            text.contains(comment),
            "the comment `{comment}` was dropped"
        );
    }
    assert!(
        text.contains("# Notes of the entry this one replaced:\n# 1.8 mm, F/2.8"),
        "{text}"
    );
    let o = digiview(&["lens", "check", "KAL"], &cal);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
}
