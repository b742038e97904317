//! `digiview` run from anywhere, as an installed binary is: lens.cal and digiview.toml are
//! found by the flag, the environment, the working directory, the user's config directory,
//! or (lens.cal) built in; the log names the one used, and a broken file is an error, not
//! passed over.

use crate::common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use digiview::control::client::Client;
use digiview::protocol::{Param, ParamType};

/// A working directory and a home directory of its own, both empty.
struct Place {
    _dir: tempfile::TempDir,
    cwd: PathBuf,
    home: PathBuf,
}

impl Place {
    fn new() -> Place {
        let dir = tempfile::tempdir().unwrap();
        let (cwd, home) = (dir.path().join("work"), dir.path().join("home"));
        std::fs::create_dir_all(&cwd).unwrap();
        std::fs::create_dir_all(&home).unwrap();
        Place {
            _dir: dir,
            cwd,
            home,
        }
    }

    /// `digiview` in this place, with nothing of the test's environment that names a file.
    fn command(&self, args: &[&str]) -> Command {
        let mut c = Command::new(env!("CARGO_BIN_EXE_digiview"));
        c.args(args)
            .current_dir(&self.cwd)
            .env("HOME", &self.home)
            .env_remove("XDG_CONFIG_HOME")
            .env_remove("DIGIVIEW_LENS_CAL")
            .env_remove("DIGIVIEW_CONFIG")
            .env("RUST_LOG", "info");
        c
    }

    fn run(&self, args: &[&str]) -> Output {
        self.command(args).output().unwrap()
    }

    fn user_config(&self) -> PathBuf {
        let d = self.home.join(".config/digiview");
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}

/// lens.cal's text with one more lens, `name` with lens_id `id` (CIL018's parameters).
fn lens_cal_with(name: &str, id: u8) -> String {
    let shipped = std::fs::read_to_string(common::lens_cal_path()).unwrap();
    let cal = common::lens_cal();
    let mut extra = cal.find("CIL018").unwrap().clone();
    extra.name = name.into();
    extra.lens_id = id;
    format!("{shipped}\n{}", extra.to_toml())
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The lens names `lens list` prints, and its log.
fn lens_names(place: &Place, args: &[&str]) -> (Vec<String>, String) {
    let o = place.run(&[args, &["lens", "list"]].concat());
    let (out, log) = text(&o);
    assert!(o.status.success(), "{log}");
    let names = out
        .lines()
        .skip(1)
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .collect();
    (names, log)
}

/// `serve --no-video` in `place`: its answer to GET LENS, and its log.
fn serve_lens(place: &Place) -> (Param, String) {
    let mut child = place
        .command(&[
            "serve",
            "--no-video",
            "--control",
            "127.0.0.1:0",
            "--http",
            "127.0.0.1:0",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let answer = line.trim().strip_prefix("control listening on ").map(|a| {
        let mut ctl = Client::connect(a, false, Duration::from_secs(5)).unwrap();
        ctl.get_one(ParamType::Lens.zeroed()).unwrap()
    });
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    (
        answer.unwrap_or_else(|| panic!("serve printed {line:?}: {log}")),
        log,
    )
}

fn lens(lens_id: u8) -> Param {
    Param::Lens(digiview::protocol::params::Lens { lens_id })
}

#[test]
fn serve_runs_from_an_empty_directory_on_the_built_in_lens_cal() {
    let (answer, log) = serve_lens(&Place::new());
    assert_eq!(answer, lens(0));
    assert!(log.contains("lens.cal: built in"), "{log}");
    assert!(log.contains("config: the defaults"), "{log}");
}

#[test]
fn lens_cal_is_looked_for_flag_first_then_environment_directory_user_config_built_in() {
    let place = Place::new();
    let (names, log) = lens_names(&place, &[]);
    assert_eq!(
        names,
        [
            "CIL216", "CIL018", "LN007", "BOSON320", "DUALF", "DUALB", "DUAL"
        ],
        "built in: {log}"
    );

    let user = place.user_config().join("lens.cal");
    std::fs::write(&user, lens_cal_with("USER", 10)).unwrap();
    let (names, log) = lens_names(&place, &[]);
    assert_eq!(names.last().unwrap(), "USER");
    assert!(log.contains(&format!(
        "{} (found in the user's config directory)",
        user.display()
    )));

    std::fs::write(place.cwd.join("lens.cal"), lens_cal_with("HERE", 11)).unwrap();
    let (names, log) = lens_names(&place, &[]);
    assert_eq!(names.last().unwrap(), "HERE", "{log}");
    assert!(log.contains("(found in the working directory)"), "{log}");

    let elsewhere = place.home.join("other.cal");
    std::fs::write(&elsewhere, lens_cal_with("ENV", 12)).unwrap();
    let o = place
        .command(&["lens", "list"])
        .env("DIGIVIEW_LENS_CAL", &elsewhere)
        .output()
        .unwrap();
    let (out, log) = text(&o);
    assert!(
        out.contains("ENV") && log.contains("(from DIGIVIEW_LENS_CAL)"),
        "{out}{log}"
    );
    let o = place
        .command(&["--lens-cal", user.to_str().unwrap(), "lens", "list"])
        .env("DIGIVIEW_LENS_CAL", &elsewhere)
        .output()
        .unwrap();
    let (out, log) = text(&o);
    assert!(
        out.contains("USER") && log.contains("(from --lens-cal)"),
        "{out}{log}"
    );

    // A file named that is not there, and a broken file found: errors, not the next one.
    let o = place.run(&["--lens-cal", "missing.cal", "lens", "list"]);
    let (_, log) = text(&o);
    assert!(!o.status.success() && log.contains("missing.cal (from --lens-cal): no such file"));
    std::fs::write(place.cwd.join("lens.cal"), "[[lens]]\nname = 3\n").unwrap();
    let o = place.run(&["lens", "list"]);
    let (_, log) = text(&o);
    assert!(
        !o.status.success()
            && log.contains(&format!("{}:2: name", place.cwd.join("lens.cal").display())),
        "{log}"
    );
}

#[test]
fn importing_without_a_lens_cal_starts_the_users_own_from_the_built_in_one() {
    let place = Place::new();
    let sample =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/import/kalibr_camchain.yaml");
    let o = place.run(&[
        "lens",
        "import",
        sample.to_str().unwrap(),
        "--name",
        "KAL",
        "--id",
        "7",
        "--write",
    ]);
    let (_, log) = text(&o);
    assert!(o.status.success(), "{log}");
    let written = place.home.join(".config/digiview/lens.cal");
    assert!(
        log.contains(&format!("added KAL (lens_id 7) to {}", written.display())),
        "{log}"
    );
    let (names, _) = lens_names(&place, &[]);
    assert_eq!(
        names,
        [
            "CIL216", "CIL018", "LN007", "BOSON320", "DUALF", "DUALB", "DUAL", "KAL"
        ]
    );
}

#[test]
fn digiview_toml_is_found_in_the_users_config_directory_and_the_working_directory_wins() {
    let place = Place::new();
    let user = place.user_config().join("digiview.toml");
    std::fs::write(&user, "lens = \"LN007\"\n").unwrap();
    let (answer, log) = serve_lens(&place);
    assert_eq!(answer, lens(2), "{log}");
    assert!(
        log.contains(&format!(
            "config: {} (found in the user's config directory)",
            user.display()
        )),
        "{log}"
    );

    std::fs::write(place.cwd.join("digiview.toml"), "lens = \"CIL018\"\n").unwrap();
    let (answer, log) = serve_lens(&place);
    assert_eq!(answer, lens(1), "{log}");
    assert!(log.contains("(found in the working directory)"), "{log}");
}
