//! No value typed on a command line makes `digiview` panic (exit status 101): hostile numbers
//! (NaN, infinities, negatives, zero, huge, subnormal) and sizes go to every numeric and
//! time-like flag of `render`, `synth`, `bench`, `ctl`, `doctor` and `serve`, and each is
//! refused with a reason or taken. The MAVLink, HTTP and protocol paths have their own
//! tests (trust_mavlink, trust_web, entry_paths, fuzz_corpus).

use crate::common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const HOSTILE: [&str; 9] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e30",
    "4.9e-324",
    "100000x100000",
    "",
];

/// `digiview ARGS`: killed after `limit` if it runs on (a value it took); its exit status
/// is judged, never its output.
fn exits_cleanly(args: &[String], dir: &std::path::Path, limit: Duration) -> Result<(), String> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(args)
        .current_dir(dir)
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            break child.wait().unwrap();
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    if let Some(mut e) = child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut e, &mut err);
    }
    match status.code() == Some(101) || err.contains("panicked") {
        true => Err(format!(
            "{args:?}: {}",
            err.lines().take(3).collect::<Vec<_>>().join(" | ")
        )),
        false => Ok(()),
    }
}

#[test]
fn no_hostile_flag_value_makes_any_command_panic() {
    let dir = tempfile::tempdir().unwrap();
    let synth = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["synth", "--out", "f.png", "--sensor", "320x180"])
        .current_dir(dir.path())
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .output()
        .unwrap();
    assert!(synth.status.success());
    let s = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<String>>();
    let mut runs: Vec<Vec<String>> = vec![];
    let render = s(&[
        "render", "--input", "f.png", "--out", "o.png", "--size", "640x480",
    ]);
    let bench = s(&[
        "bench",
        "--frames",
        "1",
        "--warmup",
        "0",
        "--input-size",
        "320x180",
    ]);
    let synth = s(&["synth", "--out", "s.png", "--sensor", "160x90"]);
    let state = ["--size", "--fps", "--time", "--layout", "--overlay"];
    for v in HOSTILE {
        for flag in state.iter().chain(&["--input-fps", "--bitrate-kbps"]) {
            runs.push([render.clone(), s(&[flag, v])].concat());
        }
        for (flag, form) in [("--cam", "0:yaw={v},fov={v}"), ("--attitude", "yaw={v}")] {
            runs.push([render.clone(), s(&[flag, &form.replace("{v}", v)])].concat());
        }
        for flag in ["--frames", "--warmup", "--input-size"] {
            runs.push([bench.clone(), s(&[flag, v])].concat());
        }
        for flag in ["--equirect", "--sensor", "--board-sweep", "--time"] {
            runs.push([synth.clone(), s(&[flag, v])].concat());
        }
        runs.push(s(&["ctl", "--addr", "127.0.0.1:9", "--timeout", v, "ping"]));
        runs.push(s(&[
            "ctl",
            "--addr",
            "127.0.0.1:9",
            "watch",
            "--interval",
            v,
            "cam_fov",
        ]));
        runs.push(s(&["doctor", "--mavlink", "off", "--heartbeat-wait", v]));
        let serve = [
            "serve",
            "--no-video",
            "--control",
            "127.0.0.1:0",
            "--mavlink",
            "off",
        ];
        for flag in ["--http", "--rtsp-port", "--fps", "--demo-size"] {
            runs.push([s(&serve), s(&[flag, v])].concat());
        }
    }
    // Four at a time; a command that takes the value runs until killed, which is fine.
    let failures: Vec<String> = runs
        .chunks(runs.len().div_ceil(4))
        .map(|chunk| {
            let chunk = chunk.to_vec();
            let dir = dir.path().to_path_buf();
            std::thread::spawn(move || {
                chunk
                    .iter()
                    .filter_map(|a| exits_cleanly(a, &dir, Duration::from_secs(8)).err())
                    .collect::<Vec<_>>()
            })
        })
        .collect::<Vec<_>>()
        .into_iter()
        .flat_map(|t| t.join().unwrap())
        .collect();
    assert!(failures.is_empty(), "panicked:\n{}", failures.join("\n"));
}
