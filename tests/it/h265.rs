//! H.265 (`[encoder] codec = "h265"`), as the players users have take it: FFmpeg and a
//! GStreamer client each decode `serve`'s stream of a still fisheye image clean and see the
//! offline render of it; a view's own stream is H.265 too, and the MAVLink cameras tell
//! ground stations so (VIDEO_STREAM_INFORMATION's encoding).

use crate::common;
use crate::players::{SIZE, complaints, pull, still_and_render};

use common::autopilot::free_udp_port;
use common::gcs::{Gcs, accepted, cameras, params};
use common::serve::{Serve, until_running};
use common::viewer::Viewer;
use digiview::image_ops;
use digiview::layout::Rect;
use mavlink::MessageData;
use mavlink::dialects::common::*;

#[test]
fn h265_streams_play_in_ffmpeg_and_gstreamer_and_mavlink_says_h265() {
    let dir = tempfile::tempdir().unwrap();
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    let (source, want) = still_and_render(dir.path());
    let config = dir.path().join("digiview.toml");
    std::fs::write(
        &config,
        "[encoder]\ncodec = \"h265\"\n[cameras]\nwidth = 640\nheight = 480\n\
         public_host = \"127.0.0.1\"\n",
    )
    .unwrap();
    let port = free_udp_port();
    let serve = Serve::start_video(&[
        "--config",
        config.to_str().unwrap(),
        "--source",
        &source,
        "--size",
        &size,
        "--mavlink",
        &format!("udpin:127.0.0.1:{port}"),
    ]);
    let url = serve.rtsp.clone().unwrap();
    until_running(&serve);

    // FFmpeg: HEVC, every frame clean, the offline render.
    let probe = common::probe_rtsp(&url, "codec_name,width,height");
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        format!("hevc,{},{}", SIZE.0, SIZE.1),
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );
    let got = pull(url.clone(), "tcp").join().unwrap();
    let bad = complaints(&got.log);
    assert!(bad.is_empty(), "FFmpeg reports {bad:#?}");
    let whole = Rect::new(0, 0, SIZE.0, SIZE.1);
    for (which, frame) in [("first", &got.first), ("last", &got.last)] {
        let psnr = image_ops::psnr(frame, &want, whole);
        eprintln!("FFmpeg, H.265: {which} frame {psnr:.1} dB against the offline render");
        assert!(psnr >= 30.0, "{which} frame only {psnr:.1} dB");
    }

    // GStreamer's own RTP depayloader and libav's decoder.
    let viewer = Viewer::open_with(&url, "rtph265depay ! h265parse ! avdec_h265");
    for _ in 0..9 {
        viewer.frame();
    }
    let frame = viewer.frame().0;
    let psnr = image_ops::psnr(&frame, &want, whole);
    eprintln!("GStreamer, H.265: {psnr:.1} dB against the offline render");
    assert!(psnr >= 30.0, "GStreamer's frame only {psnr:.1} dB");

    // A view's own stream is H.265 too, and the MAVLink cameras say so.
    let view = format!("{url}/cam0");
    let probe = common::probe_rtsp(&view, "codec_name,width,height");
    assert_eq!(
        String::from_utf8_lossy(&probe.stdout).trim(),
        "hevc,640,480",
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );
    let gcs = Gcs::connect(port);
    let (system, _) = cameras(&gcs);
    let request = MavCmd::MAV_CMD_REQUEST_MESSAGE;
    let asked = params(&[VIDEO_STREAM_INFORMATION_DATA::ID as f32, 0.0]);
    let told = accepted(gcs.command(system, 100, request, asked), "streams");
    let encodings: Vec<_> = told
        .iter()
        .filter_map(|m| match m {
            MavMessage::VIDEO_STREAM_INFORMATION(v) => Some(v.encoding),
            _ => None,
        })
        .collect();
    assert!(!encodings.is_empty(), "{told:?}");
    assert!(
        encodings
            .iter()
            .all(|e| *e == VideoStreamEncoding::VIDEO_STREAM_ENCODING_H265),
        "{encodings:?}"
    );
}

#[test]
fn an_h264_encoder_named_with_codec_h265_is_a_clear_error_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("digiview.toml");
    std::fs::write(&config, "[encoder]\ncodec = \"h265\"\nkind = \"x264\"\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["serve", "--config", config.to_str().unwrap(), "--no-video"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("encoder kind x264 does not encode H.265"),
        "{err}"
    );
}
