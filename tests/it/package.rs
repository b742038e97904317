//! The Debian package, built by `scripts/package-deb.sh` from this build's binary: its
//! contents and control fields, its systemd unit through `systemd-analyze verify`, its
//! maintainer scripts through `sh -n`, and the packaged binary, run from an unpacked copy with
//! the packaged configuration, serving the demo over RTSP.

use crate::common;

use common::viewer::Viewer;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{cmd:?} failed: {text}");
    text
}

/// Builds the package into `dir` and unpacks it into `dir/root`: the .deb and the root.
fn package(dir: &Path) -> (PathBuf, PathBuf) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/package-deb.sh");
    let out = Command::new("bash")
        .arg(script)
        .args(["--binary", env!("CARGO_BIN_EXE_digiview"), "--out"])
        .arg(dir)
        .stderr(Stdio::inherit())
        .output()
        .unwrap();
    assert!(out.status.success(), "package-deb.sh failed");
    let deb = PathBuf::from(String::from_utf8(out.stdout).unwrap().trim());
    let root = dir.join("root");
    run(Command::new("dpkg-deb").arg("-x").arg(&deb).arg(&root));
    (deb, root)
}

#[test]
fn the_package_holds_the_service_and_the_packaged_binary_serves_the_demo() {
    let dir = tempfile::tempdir().unwrap();
    let (deb, root) = package(dir.path());
    let listing = run(Command::new("dpkg-deb").arg("-c").arg(&deb));
    for path in [
        "./usr/bin/digiview",
        "./etc/digiview/digiview.toml",
        "./etc/digiview/lens.cal",
        "./lib/systemd/system/digiview.service",
        "./usr/share/doc/digiview/serve.md",
        "./usr/share/doc/digiview/copyright",
    ] {
        assert!(
            listing.contains(path),
            "{path} not in the package:\n{listing}"
        );
    }
    let info = run(Command::new("dpkg-deb").arg("-I").arg(&deb));
    for field in [
        "Package: digiview",
        "gstreamer1.0-plugins-ugly",
        "libgstrtspserver-1.0-0",
    ] {
        assert!(
            info.contains(field),
            "{field} not in the control file:\n{info}"
        );
    }
    let control = dir.path().join("control");
    run(Command::new("dpkg-deb").arg("-e").arg(&deb).arg(&control));
    assert_eq!(
        std::fs::read_to_string(control.join("conffiles")).unwrap(),
        "/etc/digiview/digiview.toml\n/etc/digiview/lens.cal\n",
        "dpkg keeps the user's configuration and calibrations on upgrade"
    );
    for script in ["postinst", "prerm", "postrm"] {
        run(Command::new("sh").arg("-n").arg(control.join(script)));
    }

    // The unit, in the unpacked root beside the system's targets it names.
    let units = root.join("usr/lib/systemd/system");
    std::fs::create_dir_all(&units).unwrap();
    for entry in std::fs::read_dir("/usr/lib/systemd/system").unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "target") {
            std::fs::copy(&p, units.join(p.file_name().unwrap())).unwrap();
        }
    }
    let verified = run(Command::new("systemd-analyze")
        .arg("verify")
        .arg(format!("--root={}", root.display()))
        .arg("/lib/systemd/system/digiview.service"));
    assert_eq!(verified.trim(), "", "systemd-analyze verify has warnings");
    let unit = std::fs::read_to_string(root.join("lib/systemd/system/digiview.service")).unwrap();
    for line in [
        "User=digiview",
        "SupplementaryGroups=video dialout",
        "Restart=on-failure",
    ] {
        assert!(unit.lines().any(|l| l == line), "{line} not in the unit");
    }

    // The packaged binary with the packaged configuration and lens.cal, ports moved to free
    // ones and captures into the test's folder (the service's are /var/lib/digiview).
    let mut serve = Command::new(root.join("usr/bin/digiview"))
        .arg("--lens-cal")
        .arg(root.join("etc/digiview/lens.cal"))
        .arg("serve")
        .arg("--config")
        .arg(root.join("etc/digiview/digiview.toml"))
        .args([
            "--control",
            "127.0.0.1:0",
            "--rtsp-port",
            "0",
            "--http",
            "127.0.0.1:0",
        ])
        .args(["--mavlink", "off", "--capture-dir"])
        .arg(dir.path().join("captures"))
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(serve.stdout.take().unwrap()).lines();
    let rtsp = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|l| l.strip_prefix("rtsp serving ").map(String::from))
        .expect("the packaged binary serves");
    let frame = Viewer::open(&rtsp).fresh_frame();
    let mean =
        frame.pixels().map(|p| p[1] as f64).sum::<f64>() / (frame.width() * frame.height()) as f64;
    let _ = serve.kill();
    let _ = serve.wait();
    let o = digiview::state::State::default().settings.output;
    assert_eq!((frame.width(), frame.height()), (o.width, o.height));
    assert!(
        mean > 20.0,
        "the demo's picture, not black: mean green {mean:.1}"
    );
}
