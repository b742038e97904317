//! The `digiview` binary's errors as a user meets them: bad flags and missing files, state
//! files and lens.cal mistakes named, a service that cannot start, no Vulkan driver, odd
//! sizes rounded as over the protocol, careless values refused with what to change; and
//! `bench`'s report.

use crate::cli::{digiview, kalibr_sample, shipped, stderr};
use std::path::Path;
use std::process::{Command, Output};

#[test]
fn bad_flags_and_missing_files_get_clear_errors() {
    let cases: [(&[&str], &str); 12] = [
        (
            &[
                "render",
                "--input",
                "a.png",
                "--out",
                "b.png",
                "--input-fps",
                "nan",
            ],
            "give a whole number from 1 to 240, not `nan`",
        ),
        (
            &[
                "render",
                "--input",
                "/nonexistent.png",
                "--out",
                "/tmp/x.png",
            ],
            "reading /nonexistent.png",
        ),
        (
            &["synth", "--out", "/tmp/x.png", "--cam", "5:yaw=0"],
            "camera id 5 is outside 0..=3",
        ),
        (
            &["synth", "--out", "/tmp/x.png", "--attitude", "roll=lots"],
            "`lots` is not an angle",
        ),
        (
            &["synth", "--out", "/tmp/x.png", "--lens", "NOPE"],
            "no lens named or numbered `NOPE`",
        ),
        (
            &["synth", "--truth", "--out", "/tmp/x.png", "--layout", "9"],
            "output layout 9 is outside 0..=6",
        ),
        // Checked before any work: nothing is rendered for minutes first.
        (
            &["synth", "--out", "/tmp/s.bmp"],
            "s.bmp: images are written as .png or .jpg",
        ),
        (
            &["synth", "--size", "20000x20000", "--out", "/tmp/x.png"],
            "--size (the fisheye frame): sensor width 20000 is outside 1..=8192 px",
        ),
        (
            &["synth", "--out", "/tmp/x.png", "--cam", "0:lock=99"],
            "camera 0 lock flags 99 is outside 0..=7",
        ),
        (
            &["render", "--input", "/tmp", "--out", "/tmp/x.mp4"],
            "/tmp is a directory; give a video file or an image sequence",
        ),
        (
            &[
                "render",
                "--input",
                "a.mp4",
                "--out",
                "b.mp4",
                "--bitrate-kbps",
                "0",
            ],
            "0 is not a bitrate in 100..=100000 kbit/s",
        ),
        (
            &["synth", "--out", "/no/such/dir/x.png"],
            "/no/such/dir/x.png: the directory /no/such/dir does not exist",
        ),
    ];
    for (args, want) in cases {
        let o = digiview(args, &shipped());
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(want), "{args:?}: `{err}` lacks `{want}`");
        assert!(
            !err.contains("panicked") && !err.contains("GLib"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("wrote"), "{args:?} wrote something: {err}");
        // Each cause once: `No such file or directory (os error 2): No such file or …`
        // was printed twice before.
        assert!(err.matches("os error").count() <= 1, "{args:?}: {err}");
        let last = err.lines().last().unwrap_or_default();
        let parts: Vec<&str> = last.split(": ").collect();
        for (i, p) in parts.iter().enumerate() {
            assert!(
                !parts[i + 1..].contains(p),
                "{args:?}: `{p}` twice in {last}"
            );
        }
    }
}

#[test]
fn state_files_and_lens_cal_mistakes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let state = p("state.toml");
    let fish = p("fish.png");
    let synth = |extra: &[&str]| {
        let args = [&["synth", "--sensor", "640x480", "--out", &fish][..], extra].concat();
        digiview(&args, &shipped())
    };
    // A lens by name, as the config takes it.
    std::fs::write(&state, "lens = \"CIL018\"\n").unwrap();
    let o = synth(&["--state", &state]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(&state, "lens = \"NOPE\"\n").unwrap();
    let o = synth(&["--state", &state]);
    assert!(
        stderr(&o).contains("state.toml:1: lens `NOPE` is not in lens.cal"),
        "{}",
        stderr(&o)
    );
    // A sensor crop larger than the lens's frame: refused, as over the protocol.
    std::fs::write(&state, "[sensor]\nroi = [0, 0, 5000, 5000]\n").unwrap();
    let o = synth(&["--state", &state]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("sensor crop 5000x5000 at 0,0 does not fit"),
        "{e}"
    );
    // What the protocol would clamp or refuse, refused from a file too, naming the field.
    for (text, says) in [
        (
            "[detection]\ncrop_box_limit = 5\n",
            "detection crop_box_limit 5 is outside 10..=500",
        ),
        (
            "[detection]\nvar_box_limit = 60000\n",
            "detection var_box_limit 60000 is outside 10..=500",
        ),
        (
            "[vehicle.position]\nlat = 47.4\nlon = 8.5\nalt = nan\nrelative_alt = 30\n",
            "vehicle altitude NaN is outside -1000..=20000 m",
        ),
    ] {
        std::fs::write(&state, text).unwrap();
        let o = synth(&["--state", &state]);
        let e = stderr(&o);
        assert!(!o.status.success() && e.contains(says), "{text:?}: {e}");
    }

    // An empty lens.cal is an error, not an empty list.
    let empty = dir.path().join("empty.cal");
    std::fs::write(&empty, "# nothing yet\n").unwrap();
    let o = digiview(&["lens", "list"], &empty);
    assert!(
        !o.status.success() && stderr(&o).contains("no [[lens]] entries"),
        "{}",
        stderr(&o)
    );
    // A fov given as a bare number is radians, and the error says so (no invented line).
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/import/opencv_fisheye.xml");
    let args = [
        "lens",
        "import",
        sample.to_str().unwrap(),
        "--name",
        "X",
        "--id",
        "9",
    ];
    let o = digiview(&[&args[..], &["--fov", "7"]].concat(), &shipped());
    let e = stderr(&o);
    assert!(
        e.contains("for degrees write 7deg") && !e.contains("(imported):"),
        "{e}"
    );
    // A file without an extension is recognised by its content.
    let bare = p("calibration");
    std::fs::copy(&sample, &bare).unwrap();
    let o = digiview(
        &["lens", "import", &bare, "--name", "X", "--id", "9"],
        &shipped(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("name = \"X\""));
}

/// `digiview serve` as a script starts it: what it printed on stdout and stderr, and how it
/// ended, within `limit`.
fn serve_briefly(args: &[&str], limit: std::time::Duration) -> (Output, bool) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "serve",
            "--control",
            "127.0.0.1:0",
            "--mavlink",
            "off",
            "--http",
            "127.0.0.1:0",
        ])
        .args(args)
        .env("DIGIVIEW_LENS_CAL", shipped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let end = std::time::Instant::now() + limit;
    let mut ended = false;
    while std::time::Instant::now() < end {
        if child.try_wait().unwrap().is_some() {
            ended = true;
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    if !ended {
        let _ = child.kill();
    }
    (child.wait_with_output().unwrap(), ended)
}

#[test]
fn serve_fails_at_once_and_says_nothing_on_stdout_when_a_service_cannot_start() {
    let taken = std::net::TcpListener::bind("0.0.0.0:0").unwrap();
    let port = taken.local_addr().unwrap().port().to_string();
    let cases: [(&[&str], &str); 4] = [
        (&["--rtsp-port", &port], "cannot serve RTSP on 0.0.0.0:"),
        (
            &["--rtsp-port", "0", "--thermal", "image:/no/such/heat.png"],
            "thermal source: /no/such/heat.png: no such file",
        ),
        // Sources that can never open are not retried for ever.
        (
            &["--rtsp-port", "0", "--source", "image:/no/such/fish.png"],
            "/no/such/fish.png: no such file",
        ),
        (
            &[
                "--rtsp-port",
                "0",
                "--source",
                "gst:videotestsrc ! ! fakesink",
            ],
            "syntax error",
        ),
    ];
    for (args, want) in cases {
        let (o, ended) = serve_briefly(args, std::time::Duration::from_secs(20));
        let err = stderr(&o);
        assert!(ended && !o.status.success(), "{args:?}: {err}");
        assert!(
            err.contains(want) && err.matches(want).count() == 1,
            "{args:?}: {err}"
        );
        assert_eq!(
            String::from_utf8_lossy(&o.stdout),
            "",
            "{args:?} announced a service"
        );
    }
}

/// A thermal lens lens.cal lacks is named with the lenses it has.
#[test]
fn a_thermal_lens_that_lens_cal_lacks_is_refused_with_the_lenses_it_has() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("thermal.toml");
    std::fs::write(&config, "[thermal]\nsource = \"demo\"\nlens = \"NOPE\"\n").unwrap();
    let args = ["--config", config.to_str().unwrap(), "--rtsp-port", "0"];
    let (o, ended) = serve_briefly(&args, std::time::Duration::from_secs(20));
    let err = stderr(&o);
    assert!(ended && !o.status.success(), "{err}");
    let want = "thermal lens \"NOPE\" is not in lens.cal; its lenses are CIL216, CIL018, LN007, \
                BOSON320";
    assert!(err.contains(want), "{err}");
}

/// A listen address in the config file is checked even where its flag replaces it (the
/// control one was silently dropped then): the mistake would come back with the flag gone.
#[test]
fn a_bad_listen_address_in_the_config_is_refused_even_with_its_flag_given() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("control", "control.listen \"nowhere\""),
        ("http", "http listen \"nowhere\""),
    ];
    for (section, want) in cases {
        let config = dir.path().join(format!("{section}.toml"));
        std::fs::write(&config, format!("[{section}]\nlisten = \"nowhere\"\n")).unwrap();
        let args = ["--config", config.to_str().unwrap(), "--rtsp-port", "0"];
        let (o, ended) = serve_briefly(&args, std::time::Duration::from_secs(20));
        let err = stderr(&o);
        assert!(ended && !o.status.success(), "{section}: {err}");
        assert!(
            err.contains(want) && err.contains("ADDR:PORT"),
            "{section}: {err}"
        );
    }
}

#[test]
fn bench_reports_every_stage_and_the_frame_rate_as_json() {
    let o = digiview(
        &[
            "bench",
            "--frames",
            "3",
            "--warmup",
            "1",
            "--input-size",
            "640x360",
            "--size",
            "640x480",
            "--json",
        ],
        &shipped(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for stage in ["upload_ms", "render_ms", "readback_ms", "total_ms"] {
        let v = report["staged"][stage].as_f64().unwrap();
        assert!(v > 0.0, "{stage} = {v}");
    }
    assert!(report["pipelined_fps"].as_f64().unwrap() > 0.0);
    assert_eq!(report["output"], "640x480 i420");
}

/// `render` of a small black image with `args` and `env`: its exit, stderr (info log) and
/// whether it wrote the output.
fn render_with_drivers(args: &[&str], env: &[(&str, &Path)]) -> (bool, String, bool) {
    let dir = tempfile::tempdir().unwrap();
    let fish = dir.path().join("fish.png");
    image::RgbImage::new(64, 36).save(&fish).unwrap();
    let out = dir.path().join("out.png");
    let o = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["render", "--input", fish.to_str().unwrap(), "--out"])
        .arg(&out)
        .arg("--lens-cal")
        .arg(shipped())
        .args(args)
        .env("RUST_LOG", "info")
        .envs(env.iter().copied())
        .output()
        .unwrap();
    (o.status.success(), stderr(&o), out.exists())
}

#[test]
fn without_a_vulkan_driver_render_runs_on_gl_and_without_either_says_what_to_install() {
    let nowhere = tempfile::tempdir().unwrap();
    let no_vulkan = (
        "VK_ICD_FILENAMES",
        nowhere.path().join("no-such-driver.json"),
    );
    let no_egl = (
        "__EGL_VENDOR_LIBRARY_FILENAMES",
        nowhere.path().join("no-such-egl.json"),
    );
    let (ok, err, wrote) = render_with_drivers(&[], &[(no_vulkan.0, &no_vulkan.1)]);
    assert!(ok && wrote, "{err}");
    assert!(
        err.contains("(Gl, ") && err.contains("no Vulkan adapter was found"),
        "{err}"
    );

    let vulkan = ["--backend", "vulkan"];
    let (ok, err, wrote) = render_with_drivers(&vulkan, &[(no_vulkan.0, &no_vulkan.1)]);
    assert!(!ok && !wrote, "{err}");
    assert!(
        err.contains("with --backend vulkan") && err.contains("mesa-vulkan-drivers"),
        "{err}"
    );

    let neither = [(no_vulkan.0, &*no_vulkan.1), (no_egl.0, &*no_egl.1)];
    let (ok, err, wrote) = render_with_drivers(&[], &neither);
    assert!(!ok && !wrote, "{err}");
    assert!(
        err.contains("mesa-vulkan-drivers") && err.contains("libegl-mesa0"),
        "{err}"
    );
}

#[test]
fn an_odd_output_size_is_rounded_down_on_every_entry_as_over_the_protocol() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let fish = p("fish.png");
    let sized = |o: &Output| {
        assert!(o.status.success(), "{}", stderr(o));
        stderr(o).contains("rounded down to 640x480")
    };
    // The flag (digiview once panicked in its frame loop on this very size).
    let o = digiview(
        &[
            "synth", "--sensor", "1280x720", "--size", "641x481", "--out", &fish,
        ],
        &shipped(),
    );
    assert!(sized(&o), "{}", stderr(&o));
    let out = p("out.png");
    let o = digiview(
        &[
            "render", "--input", &fish, "--size", "641x481", "--out", &out,
        ],
        &shipped(),
    );
    assert!(sized(&o));
    assert_eq!(
        image::open(&out).unwrap().to_rgb8().dimensions(),
        (640, 480)
    );
    // A state file.
    let state = p("state.toml");
    std::fs::write(&state, "[output]\nwidth = 641\nheight = 481\n").unwrap();
    let o = digiview(
        &["render", "--input", &fish, "--state", &state, "--out", &out],
        &shipped(),
    );
    assert!(sized(&o));
    assert_eq!(
        image::open(&out).unwrap().to_rgb8().dimensions(),
        (640, 480)
    );
}

/// Values a careless hand gives are refused before any work, saying what to change: a
/// sequence read at 0 fps, a bench frame larger than any sensor, a load test of no client or
/// of 100,000, a directory where a file is wanted and a file where a directory is, and a
/// lens name with a control character.
#[test]
fn careless_values_are_refused_with_what_to_change() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let file = dir.path().join("captures");
    std::fs::write(&file, "not a directory").unwrap();
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        format!("[capture]\ndir = {:?}\n", file.to_str().unwrap()),
    )
    .unwrap();
    let config = config.to_str().unwrap();
    let sample = kalibr_sample();
    let sample = sample.to_str().unwrap();
    let bin = |args: &[&str]| digiview(args, &shipped());
    for (args, says) in [
        (
            vec![
                "render",
                "--input",
                "f/%03d.png",
                "--out",
                "o.mp4",
                "--input-fps",
                "0",
            ],
            "give a whole number from 1 to 240, not `0`",
        ),
        (
            vec!["bench", "--input-size", "100000x100000", "--frames", "1"],
            "larger than the largest sensor, 8192x8192",
        ),
        (
            vec!["ctl", "load", "--clients", "100000"],
            "give a whole number from 1 to 1000",
        ),
        (
            vec!["ctl", "load", "--clients", "0"],
            "give a whole number from 1 to 1000",
        ),
        (vec!["--lens-cal", d, "lens", "list"], "is a directory"),
        (vec!["serve", "--config", d], "is a directory"),
        (vec!["serve", "--config", config], "is not a directory"),
        (
            vec!["lens", "import", sample, "--name", "A\u{7}B", "--id", "9"],
            "without quotes or backslashes, not '\\u{7}'",
        ),
    ] {
        let o = bin(&args);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    }
    // State flags out of what they can be, refused before the (missing) input is read.
    for (flag, value, says) in [
        ("--position", "alt=nan", "alt=`nan`: give a finite number"),
        (
            "--position",
            "alt=1e9",
            "vehicle altitude 1e9 is outside -1000..=20000 m",
        ),
        (
            "--attitude",
            "roll=1e300",
            "vehicle attitude roll 1e300 is outside ±π rad",
        ),
        (
            "--mount",
            "pitch=1e300",
            "mount pitch 1e300 is outside ±π/2 rad",
        ),
        (
            "--track",
            "size=-4deg",
            "tracked object 0 size -0.069813 rad (-4°) is outside 0.000001..=π rad, and more than 0",
        ),
        (
            "--track",
            "size=0deg",
            "tracked object 0 size 0 rad (0°) is outside 0.000001..=π rad, and more than 0",
        ),
        (
            "--cam",
            "0:roll=3",
            "camera 0 roll 3 rad (171.887°) is outside ±π/2 rad",
        ),
        (
            "--cam",
            "1:pitch=1e300",
            "camera 1 pitch 1e300 is outside ±π/2 rad",
        ),
    ] {
        let o = bin(&["render", "--input", "f.png", "--out", "o.png", flag, value]);
        assert!(!o.status.success(), "{flag} {value} succeeded");
        assert!(stderr(&o).contains(says), "{flag} {value}: {}", stderr(&o));
    }
}
