//! The pair from two synchronised sources: each lens's camera a source of its own, put side by
//! side in one frame by GStreamer's `compositor` (which pairs their frames by timestamp) in a
//! `gst:` source, as docs/sphere.md shows. Served through DUAL, the views are those of the
//! same pair frame given whole.

use super::*;

/// A `gst:` description of one still as a live camera would give it: NV12 at 30 fps.
fn camera(path: &std::path::Path, pad: &str) -> String {
    format!(
        "filesrc location={} ! decodebin ! videoconvert \
         ! video/x-raw,format=NV12,colorimetry=bt709 ! imagefreeze is-live=true \
         ! video/x-raw,framerate=30/1 ! mix.{pad}",
        path.display()
    )
}

#[test]
fn two_sources_side_by_side_draw_the_views_of_one_pair_frame() {
    let dir = tempfile::tempdir().unwrap();
    let frame = fisheye(world(), &pair(0.0), &state(ON_THE_SEAM));
    let (w, h) = frame.dimensions();
    let whole = dir.path().join("pair.png");
    frame.save(&whole).unwrap();
    let (front, back) = (dir.path().join("front.png"), dir.path().join("back.png"));
    let half = |x| image::imageops::crop_imm(&frame, x, 0, w / 2, h).to_image();
    half(0).save(&front).unwrap();
    half(w / 2).save(&back).unwrap();

    let (_, one) = served_through_dual(&format!("image:{}", whole.display()));
    let (_, two) = served_through_dual(&format!(
        "gst:{} {} compositor name=mix background=black sink_1::xpos={}",
        camera(&front, "sink_0"),
        camera(&back, "sink_1"),
        w / 2,
    ));
    let all = Rect::new(0, 0, one.width(), one.height());
    let same = psnr(&one, &two, all);
    // The lenses swapped: the seam's two sides from the wrong cameras.
    let (_, swapped) = served_through_dual(&format!(
        "gst:{} {} compositor name=mix background=black sink_1::xpos={}",
        camera(&back, "sink_0"),
        camera(&front, "sink_1"),
        w / 2,
    ));
    let wrong = psnr(&one, &swapped, all);
    eprintln!("two sources against the pair frame whole: {same:.1} dB (swapped: {wrong:.1} dB)");
    assert!(same >= 40.0, "{same:.1} dB");
    assert!(wrong < 20.0, "swapped: {wrong:.1} dB");
}

#[test]
fn a_source_of_another_shape_than_the_pairs_is_refused_saying_why() {
    use common::serve::Serve;
    let dir = tempfile::tempdir().unwrap();
    // A 16:9 camera where the pair's two images come in a 2:1 frame.
    let wide = dir.path().join("wide.png");
    RgbImage::from_pixel(1280, 720, image::Rgb([90, 90, 90]))
        .save(&wide)
        .unwrap();
    let source = format!("image:{}", wide.display());
    let why = "lens DUAL sees two images side by side in a 3840x1920 frame; a 1280x720 frame is \
               another shape, which would squeeze them (a frame of the pair's shape is needed)";
    // `serve`: no signal, and the status says why.
    let serve = Serve::start_video(&["--source", &source, "--lens", "DUAL", "--size", "640x480"]);
    let url = format!("{}api/status", serve.http.as_ref().unwrap());
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    let status = loop {
        let (_, body) = common::gcs::http_get(&url);
        let status: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
        if status["video"]["source_down"].is_string() || std::time::Instant::now() > deadline {
            break status;
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    assert_eq!(
        (&status["status"], &status["failure"]),
        (&3.into(), &1.into()),
        "{status}"
    );
    assert_eq!(status["video"]["source_down"], why, "{status}");
    // `render`: refused, with the same words.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "render",
            "--lens",
            "DUAL",
            "--input",
            wide.to_str().unwrap(),
            "--out",
        ])
        .arg(dir.path().join("out.png"))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && said.contains(why), "{said}");
    assert!(!dir.path().join("out.png").exists());
}
