//! The control server over real sockets against `digiview serve --no-video`: UDP datagrams,
//! permissions by client address, QUIT, a misaligned stream, pipelining, stalled clients and
//! load, SIGTERM, and the `digiview ctl` client. The parameter rules are
//! tests/it/protocol_system.rs's and tests/it/protocol_camera.rs's.

use crate::common;
use common::frames::{Client, MRAD, ack, raw_frame, verdict};
use common::serve::{Serve, udp_exchange};
use common::{DEG, ctl};
use digiview::protocol::params::*;
use digiview::protocol::{Body, Message, Param, ParamType, Verdict};
use std::io::{Read, Write};
use std::time::Duration;

#[test]
fn udp_answers_each_datagram_and_calls_short_ones_data_errors() {
    let server = Serve::start(&[]);
    let reply = |d: &[u8]| Message::decode(&udp_exchange(server.addr, d)).unwrap().body;
    let get = Message::new(Body::Get(ParamType::Lens.zeroed())).encode();
    assert_eq!(reply(&get), Body::Current(Param::Lens(Lens { lens_id: 0 })));
    assert_eq!(
        reply(&get[..40]),
        Body::Verdict(Verdict::DataError, 0),
        "short datagram"
    );
    let mut long = get.to_vec();
    long.push(0);
    assert_eq!(
        reply(&long),
        Body::Verdict(Verdict::DataError, 0),
        "long datagram"
    );
    let set = Message::new(Body::Set(Param::Lens(Lens { lens_id: 1 }))).encode();
    assert_eq!(reply(&set), ack(ParamType::Lens));
    assert_eq!(reply(&get), Body::Current(Param::Lens(Lens { lens_id: 1 })));
}

#[test]
fn clients_without_permission_are_forbidden_and_change_nothing() {
    let mut server = Serve::start(&["--allow-set", "10.0.0.0/8", "--allow-quit", "none"]);
    let mut c = server.tcp();
    let set = Body::Set(Param::Lens(Lens { lens_id: 1 }));
    assert_eq!(c.ask(set), verdict(Verdict::Forbidden, ParamType::Lens));
    let udp_set = Message::decode(&udp_exchange(server.addr, &Message::new(set).encode())).unwrap();
    assert_eq!(udp_set.body, verdict(Verdict::Forbidden, ParamType::Lens));
    assert_eq!(
        c.get(ParamType::Lens.zeroed()),
        Param::Lens(Lens { lens_id: 0 }),
        "GET is open, the SET was not applied"
    );
    assert_eq!(c.ask(Body::Quit(0)), Body::Verdict(Verdict::Forbidden, 0));
    assert!(
        server.wait_exit(Duration::from_millis(300)).is_none(),
        "a forbidden QUIT does not stop the server"
    );
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
}

#[test]
fn quit_from_loopback_acknowledges_then_ends_the_process_cleanly() {
    let mut server = Serve::start(&[]);
    let mut other = server.tcp();
    assert_eq!(
        other.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
    let mut c = server.tcp();
    assert_eq!(
        c.ask(Body::Quit(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
    let status = server
        .wait_exit(Duration::from_secs(5))
        .expect("the server exits");
    assert!(status.success(), "{status:?}");
    let mut rest = Vec::new();
    assert_eq!(
        other.stream.read_to_end(&mut rest).unwrap_or(0),
        0,
        "other clients are closed"
    );
}

#[test]
fn sixteen_bad_checksums_in_a_row_are_a_misaligned_stream_the_server_hangs_up_on() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let mut f = Message::new(Body::Set(Param::CamFov(CamFov {
        cam_id: 0,
        fov: 0.5,
    })))
    .encode();
    f[75] ^= 0x5a;
    // 16 bad frames in a row: the stream is misaligned, the server hangs up.
    for _ in 0..16 {
        c.send_bytes(&f);
    }
    for _ in 0..16 {
        assert_eq!(
            c.recv().body,
            verdict(Verdict::ChecksumError, ParamType::CamFov)
        );
    }
    let mut rest = Vec::new();
    assert_eq!(
        c.stream.read_to_end(&mut rest).unwrap_or(0),
        0,
        "closed after 16 bad frames"
    );
}

#[test]
fn pipelined_requests_are_answered_in_order() {
    let server = Serve::start(&[]);
    let mut c = server.tcp();
    let requests: Vec<Body> = (0..300)
        .map(|i| match i % 3 {
            0 => Body::Get(Param::CamFov(CamFov {
                cam_id: (i % 4) as u8,
                fov: 0.0,
            })),
            1 => Body::Set(Param::CamLockFlags(CamLockFlags {
                cam_id: (i % 4) as u8,
                flags: (i % 8) as u8,
            })),
            _ => Body::Get(Param::CamLockFlags(CamLockFlags {
                cam_id: (i % 4) as u8,
                flags: 0,
            })),
        })
        .collect();
    let bytes: Vec<u8> = requests
        .iter()
        .flat_map(|b| Message::new(*b).encode())
        .collect();
    c.send_bytes(&bytes);
    let mut last_flags = [7u8; 4];
    for (i, req) in requests.iter().enumerate() {
        let cam = (i % 4) as u8;
        match (req, c.recv().body) {
            (Body::Get(Param::CamFov(_)), Body::Current(Param::CamFov(f))) => {
                assert_eq!(f.cam_id, cam)
            }
            (Body::Set(Param::CamLockFlags(p)), b) => {
                assert_eq!(b, ack(ParamType::CamLockFlags));
                last_flags[cam as usize] = p.flags;
            }
            (Body::Get(_), Body::Current(Param::CamLockFlags(f))) => {
                assert_eq!(
                    (f.cam_id, f.flags),
                    (cam, last_flags[cam as usize]),
                    "reply {i}"
                )
            }
            (req, reply) => panic!("reply {i} to {req:?} is {reply:?}"),
        }
    }
}

#[test]
fn a_client_that_never_reads_is_dropped_and_others_carry_on() {
    let server = Serve::start(&[]);
    let hog = std::net::TcpStream::connect(server.addr).unwrap();
    let frame = Message::new(Body::Get(ParamType::VideoOutput.zeroed())).encode();
    let burst: Vec<u8> = std::iter::repeat_n(frame, 4096).flatten().collect();
    let writer = {
        let mut hog = hog.try_clone().unwrap();
        std::thread::spawn(move || {
            // Up to 64 MB of requests whose replies are never read: the server must give up
            // on this client (the write then fails) rather than queue without bound.
            for _ in 0..200 {
                if hog.write_all(&burst).is_err() {
                    return true;
                }
            }
            false
        })
    };
    // Meanwhile, another client is served.
    let mut c = server.tcp();
    for _ in 0..50 {
        assert_eq!(
            c.ask(Body::Empty(0)),
            Body::Verdict(Verdict::Acknowledgement, 0)
        );
    }
    assert!(
        writer.join().unwrap(),
        "the server dropped the client that never reads"
    );
    assert_eq!(
        c.ask(Body::Empty(0)),
        Body::Verdict(Verdict::Acknowledgement, 0)
    );
}

#[test]
fn fifty_pipelining_clients_all_get_correct_replies_beside_a_stalled_one() {
    let server = Serve::start(&[]);
    let r = digiview::control::load::run(server.addr, 50, 2000, true).unwrap();
    assert_eq!((r.replies, r.wrong), (100_000, 0), "{r:?}");
    // One client pipelining far more than its reply queue holds is slowed, not dropped.
    let r = digiview::control::load::run(server.addr, 1, 50_000, false).unwrap();
    assert_eq!((r.replies, r.wrong), (50_000, 0), "{r:?}");
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn ctl_reads_and_changes_values_for_people_and_scripts() {
    let mut server = Serve::start(&["--track", "yaw=10deg,pitch=-40deg,size=3deg"]);
    let addr = server.addr.to_string();
    let o = ctl(&addr, &["get", "cam_euler", "cam=1"]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        out.starts_with("CAM_EULER\n") && out.contains("yaw       1.571 rad (90.01°)"),
        "{out}"
    );

    // Set only the layout: the client reads first, so the size is kept.
    let o = ctl(&addr, &["set", "video_output", "layout_mode=0"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = ctl(&addr, &["--json", "get", "video_output"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["param"], "VIDEO_OUTPUT");
    assert_eq!(
        (
            v["values"]["width"].as_u64(),
            v["values"]["layout_mode"].as_u64()
        ),
        (Some(1920), Some(0))
    );

    // Degrees on the command line, radians on the wire; over UDP too.
    assert!(
        ctl(&addr, &["--udp", "set", "cam_fov", "cam=0", "fov=50deg"])
            .status
            .success()
    );
    let o = ctl(&addr, &["--json", "--udp", "get", "cam_fov", "cam=0"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["values"]["fov"].as_f64().unwrap() - 50.0 * DEG).abs() < MRAD);

    // One JSON line per detection.
    let o = ctl(&addr, &["--json", "get", "detected_roi", "index=255"]);
    assert_eq!(text(&o.stdout).lines().count(), 1);

    // Error replies and bad input are explained.
    let o = ctl(&addr, &["get", "cam_fov", "cam=4"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("DATA_ERROR to GET CAM_FOV"),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["set", "cam_fov", "cam=0", "fvo=1"]);
    assert!(
        text(&o.stderr).contains("CAM_FOV has no field `fvo`; its fields: cam_id, fov"),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["get", "cam_angles"]);
    assert!(
        text(&o.stderr).contains("`cam_angles` is not a parameter type"),
        "{}",
        text(&o.stderr)
    );

    // watch prints the first value and each change.
    let watcher = std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "ctl",
            "--addr",
            &addr,
            "--json",
            "watch",
            "lens",
            "--interval",
            "0.05",
            "--count",
            "2",
        ])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert!(ctl(&addr, &["set", "lens", "lens_id=2"]).status.success());
    let out = watcher.wait_with_output().unwrap();
    let lines: Vec<String> = text(&out.stdout).lines().map(String::from).collect();
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(
        lines[0].contains("\"lens_id\":0") && lines[1].contains("\"lens_id\":2"),
        "{lines:?}"
    );

    let o = ctl(&addr, &["quit"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(server.wait_exit(Duration::from_secs(5)).unwrap().success());
}

#[test]
fn a_refusal_says_why_in_ctl_and_in_the_log() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "not a directory").unwrap();
    let captures = file.join("captures");
    let mut server =
        Serve::start_video_logging("info", &["--capture-dir", captures.to_str().unwrap()]);
    let addr = server.addr.to_string();

    // The cause, however long, reaches the user (REFUSAL comes in 62-byte parts).
    let o = ctl(&addr, &["set", "capture", "flags=1"]);
    let err = text(&o.stderr);
    assert!(!o.status.success());
    let want = format!(
        "DATA_ERROR to SET CAPTURE: capture directory {}: Not a directory",
        captures.display()
    );
    assert!(err.contains(&want), "{err}");

    // A SET that reads the current values first is still reported as the SET.
    let o = ctl(&addr, &["set", "cam_euler", "cam=9", "yaw=10deg"]);
    let err = text(&o.stderr);
    assert!(
        err.contains("DATA_ERROR to SET CAM_EULER: cam_id 9 is outside 0..=3"),
        "{err}"
    );

    // A flood of refusals is counted, not logged line by line.
    let mut c = server.tcp();
    for _ in 0..200 {
        c.send_bytes(&raw_frame(0, 2, 99));
    }
    for _ in 0..200 {
        c.recv();
    }
    server.terminate();
    assert!(server.wait_exit(Duration::from_secs(10)).is_some());
    let log = server.log();
    let line = log
        .lines()
        .find(|l| l.contains("refused SET CAPTURE"))
        .unwrap_or_else(|| panic!("{log}"));
    assert!(
        line.contains("INFO") && line.contains("Not a directory"),
        "{line}"
    );
    let unknown = log.lines().filter(|l| l.contains("refused GET")).count();
    assert!(unknown <= 10, "{unknown} lines for 200 refusals:\n{log}");
}

#[test]
fn ctl_says_when_no_server_answers() {
    // A port nothing listens on (bound, then released).
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let o = ctl(&addr, &["get", "lens"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains(&format!(
            "cannot reach the DigiView control server at {addr}"
        )),
        "{}",
        text(&o.stderr)
    );
    let o = ctl(&addr, &["--udp", "--timeout", "0.3", "get", "lens"]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("cannot reach") || e.contains("no reply from"),
        "{e}"
    );
    let o = ctl("nowhere", &["get", "lens"]);
    assert!(
        text(&o.stderr).contains("`nowhere` is not a HOST:PORT address"),
        "{}",
        text(&o.stderr)
    );
}

#[test]
fn sigterm_stops_the_server_even_when_nobody_reads_its_log() {
    // `digiview serve 2>&1 | head -1`, or a terminal closed under it: its log lines go
    // nowhere, and it must still stop on SIGTERM (it used to keep running).
    let mut serve = Serve::start_unread(&[]);
    // A client connecting is logged at info level: a write into the dead pipe before the
    // signal.
    let status = serve.tcp().get(ParamType::SystemStatus.zeroed());
    assert_eq!(status.param_type(), ParamType::SystemStatus);
    serve.terminate();
    let exit = serve
        .wait_exit(Duration::from_secs(10))
        .expect("serve exits on SIGTERM with nobody reading its log");
    assert!(exit.success(), "{exit:?}");
}
