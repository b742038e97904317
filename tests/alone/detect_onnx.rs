//! The ONNX detector (NanoDet-m, as shipped) on real photographs: Debian's darknet samples,
//! which scripts/setup.sh unpacks. Laid flat (aspect kept) at known directions in a panorama,
//! seen through a fisheye lens by `synth`, then scanned by `serve`: every object the model
//! finds in a photograph itself, `serve` reports too, with its class, where the panorama put
//! it. And a missing runtime, model or class is a clear error, not a crash.

use crate::common;

use common::gcs::reported;
use common::{ctl, photos};
use digiview::detect::scan::model_views;
use digiview::geometry::rotation::direction;
use digiview::scene::PanoramaWorld;
use glam::{DVec2, DVec3};
use image::RgbImage;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// A photograph laid on the plane tangent to the sky at `yaw`, `pitch` (its top towards the
/// zenith).
struct Placed {
    file: &'static str,
    yaw: f64,
    pitch: f64,
}

/// Five photographs, before a lens that looks ahead (mount pitch 0), each alone in its
/// panorama (at the scale below, two would not fit side by side in the lens's field): three on
/// the horizon, two 45° below it, each centred on one of the scan views.
const PLACES: [Placed; 5] = [
    Placed {
        file: "person.jpg",
        yaw: 0.0,
        pitch: 0.0,
    },
    Placed {
        file: "dog.jpg",
        yaw: 36.0 * DEG,
        pitch: 0.0,
    },
    Placed {
        file: "horses.jpg",
        yaw: -36.0 * DEG,
        pitch: 0.0,
    },
    Placed {
        file: "kite.jpg",
        yaw: 0.0,
        pitch: -45.0 * DEG,
    },
    Placed {
        file: "giraffe.jpg",
        yaw: 45.0 * DEG,
        pitch: -45.0 * DEG,
    },
];

impl Placed {
    /// The plane's centre, right and down axes (world NED).
    fn axes(&self) -> (DVec3, DVec3, DVec3) {
        let centre = direction(self.yaw, self.pitch);
        let right = direction(self.yaw + 90.0 * DEG, 0.0);
        (centre, right, centre.cross(right))
    }

    /// Tangent-plane units per photo pixel: the photograph is as tall in a scan view as in
    /// the model's input when the model ran on it directly (a view's height; a 3:2 photograph
    /// fills the view as it filled the model's input), so objects are seen at the scale they
    /// were found at.
    fn scale(&self, _w: u32, h: u32) -> f64 {
        let shape = model_views(416);
        let down = 2.0 * (shape.fov / 2.0).tan() * shape.height as f64 / shape.width as f64;
        down / h as f64
    }

    /// The direction of photo pixel `p` (pixel-edge coordinates) in a `w` × `h` photo.
    fn direction(&self, p: DVec2, w: u32, h: u32) -> DVec3 {
        let (centre, right, down) = self.axes();
        let q = (p - DVec2::new(w as f64, h as f64) / 2.0) * self.scale(w, h);
        (centre + right * q.x + down * q.y).normalize()
    }

    /// The photo point (pixel-edge coordinates) a ray falls on, if it does.
    fn point(&self, ray: DVec3, w: u32, h: u32) -> Option<DVec2> {
        let (centre, right, down) = self.axes();
        let along = ray.dot(centre);
        if along < 0.1 {
            return None;
        }
        let q = DVec2::new(ray.dot(right), ray.dot(down)) / along / self.scale(w, h);
        let p = q + DVec2::new(w as f64, h as f64) / 2.0;
        (p.x >= 0.0 && p.y >= 0.0 && p.x < w as f64 && p.y < h as f64).then_some(p)
    }
}

/// The panorama: grey, with the photograph laid on its plane (bilinear).
fn panorama(place: &Placed, width: u32) -> RgbImage {
    let photo = image::open(photos().join(place.file)).unwrap().to_rgb8();
    let pano = PanoramaWorld::new(RgbImage::new(width, width / 2));
    let mut out = RgbImage::from_pixel(width, width / 2, image::Rgb([118, 118, 118]));
    for (x, y, px) in out.enumerate_pixels_mut() {
        let ray = pano.ray(DVec2::new(x as f64, y as f64));
        if let Some(p) = place.point(ray, photo.width(), photo.height()) {
            let c = digiview::image_ops::bilinear(&photo, p - 0.5).round();
            *px = image::Rgb([c.x as u8, c.y as u8, c.z as u8]);
        }
    }
    out
}

/// An object the model found in a photograph: its class and where the panorama put it.
#[derive(Debug)]
struct Expected {
    file: &'static str,
    class: String,
    confidence: f64,
    ray: DVec3,
}

/// `digiview detect` on the photograph itself.
fn found_in_photo(place: &Placed, threshold: f64) -> Vec<Expected> {
    let mut all = vec![];
    {
        let path = photos().join(place.file);
        let (w, h) = image::image_dimensions(&path).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_digiview"))
            .args(["detect", "--json", "--threshold", &threshold.to_string()])
            .arg("--image")
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        for line in String::from_utf8_lossy(&out.stdout).lines() {
            let b: serde_json::Value = serde_json::from_str(line).unwrap();
            let n = |k: &str| b[k].as_f64().unwrap();
            let centre = DVec2::new(n("x0") + n("x1"), n("y0") + n("y1")) / 2.0;
            all.push(Expected {
                file: place.file,
                class: b["class"].as_str().unwrap().to_string(),
                confidence: n("confidence"),
                ray: place.direction(centre, w, h),
            });
        }
    }
    all
}

/// One photograph's panorama through the fisheye, scanned by `serve`: each object the model
/// finds in the photograph, and how far (degrees) the nearest object `serve` reports with its
/// class is from where the panorama put it (None: none of its class).
/// `place`'s panorama seen through CIL216 looking ahead, as `synth` draws it at 3840x2160,
/// written in `dir`.
fn fisheye(place: &Placed, dir: &Path) -> PathBuf {
    let pano = dir.join("pano.png");
    panorama(place, 4096).save(&pano).unwrap();
    let fish = dir.join("fish.png");
    let made = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "synth",
            "--lens",
            "CIL216",
            "--mount",
            "pitch=0",
            "--sensor",
            "3840x2160",
        ])
        .arg("--world")
        .arg(&pano)
        .arg("--out")
        .arg(&fish)
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .output()
        .unwrap();
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    fish
}

/// `serve --detector onnx` on `fish` (640x480 out), with `extra` flags.
fn serve_onnx(fish: &Path, extra: &[&str]) -> common::serve::Serve {
    let source = format!("image:{}", fish.display());
    let flags = [
        "--source",
        &source,
        "--lens",
        "CIL216",
        "--mount",
        "pitch=0",
        "--size",
        "640x480",
        "--detector",
        "onnx",
    ];
    common::serve::Serve::start_video(&[&flags[..], extra].concat())
}

fn scanned(place: &Placed, threshold: f64) -> Vec<(Expected, Option<f64>)> {
    let dir = tempfile::tempdir().unwrap();
    let fish = fisheye(place, dir.path());
    let expected = found_in_photo(place, threshold);

    let server = serve_onnx(&fish, &[]);
    let addr = server.addr.to_string();
    let http = server.http.clone().unwrap();
    let setting = format!("var_confidence_threshold={threshold}");
    assert!(ctl(&addr, &["set", "detection", &setting]).status.success());

    let offsets = |got: &[(String, DVec3, u64)]| -> Vec<Option<f64>> {
        expected
            .iter()
            .map(|e| {
                got.iter()
                    .filter(|(label, _, _)| *label == e.class)
                    .map(|(_, ray, _)| ray.angle_between(e.ray) / DEG)
                    .min_by(|a, b| a.total_cmp(b))
            })
            .collect()
    };
    let start = Instant::now();
    let (mut off, mut got) = (vec![], vec![]);
    while start.elapsed() < Duration::from_secs(30) {
        got = reported(&http);
        off = offsets(&got);
        if off.iter().all(|o| o.is_some_and(|o| o <= 2.0)) {
            break;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    println!("{}: after {:.1?}", place.file, start.elapsed());
    for (label, ray, score) in &got {
        let (yaw, pitch) = digiview::geometry::rotation::yaw_pitch(*ray);
        println!(
            "  reported: {label} (score {score}) at {:.1}°, {:.1}°",
            yaw / DEG,
            pitch / DEG
        );
    }
    expected.into_iter().zip(off).collect()
}

/// At var_confidence_threshold 0.45 (the issue's own figures: through a dewarped view
/// NanoDet-m finds the person at 0.53-0.73 and a horse at 0.49): 11 objects in the five
/// photographs. Through the lens and a scan view an object's score moves by up to about 0.13,
/// so one near the threshold may take a few scans to be reported.
#[test]
fn serve_finds_in_a_fisheye_panorama_every_object_the_model_finds_in_the_photographs() {
    let _alone = crate::one_at_a_time();
    const THRESHOLD: f64 = 0.45;
    let mut all = vec![];
    for place in &PLACES {
        for (e, off) in scanned(place, THRESHOLD) {
            println!("{} {} {:.2}: {off:.2?}", e.file, e.class, e.confidence);
            all.push((e, off));
        }
    }
    assert!(all.len() >= 5, "{all:#?}");
    let missed: Vec<_> = all
        .iter()
        .filter(|(_, off)| off.is_none_or(|o| o > 2.0))
        .collect();
    assert!(missed.is_empty(), "not reported within 2°: {missed:#?}");
}

/// The track step: with a scan's bonus and penalty at 0 (and a crop's penalty), scans only
/// create objects, so a score above the creation score (50) comes from the crops around the
/// object alone. With the default crop rate the person's score climbs; with `crop_hz = 0` it
/// stays at 50.
#[test]
fn the_track_step_finds_an_object_again_in_the_crop_around_it() {
    let _alone = crate::one_at_a_time();
    let dir = tempfile::tempdir().unwrap();
    let fish = fisheye(&PLACES[0], dir.path());
    for crop_hz in [10, 0] {
        let config = dir.path().join(format!("crops-{crop_hz}.toml"));
        std::fs::write(&config, format!("[detection]\ncrop_hz = {crop_hz}\n")).unwrap();
        let server = serve_onnx(&fish, &["--config", config.to_str().unwrap()]);
        let addr = server.addr.to_string();
        let http = server.http.clone().unwrap();
        let settings = [
            "var_confidence_threshold=0.45",
            "crop_confidence_threshold=0.3",
            "bonus_detection_scale=0",
            "missed_detection_penalty=0",
            "missed_redetection_penalty=0",
        ];
        let set = [&["set", "detection"][..], &settings[..]].concat();
        assert!(ctl(&addr, &set).status.success());
        let person = || {
            reported(&http)
                .into_iter()
                .filter(|(label, _, _)| label == "person")
                .map(|(_, _, score)| score)
                .max()
        };
        let start = Instant::now();
        while person().is_none() {
            assert!(start.elapsed() < Duration::from_secs(30), "no person found");
            std::thread::sleep(Duration::from_millis(200));
        }
        // Then 10 s of track steps, or none.
        let found = Instant::now();
        let mut score = 0;
        while found.elapsed() < Duration::from_secs(10) {
            score = person().expect("the person is still tracked");
            if crop_hz > 0 && score > 50 {
                break;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        println!(
            "crop_hz {crop_hz}: the person's score {score} after {:.1?}",
            found.elapsed()
        );
        match crop_hz {
            0 => assert_eq!(score, 50, "without crops only a scan changes a score"),
            _ => assert!(score > 50, "the crops never found the person again"),
        }
    }
}

/// A detector that cannot run says why and what to do, on every path: `detect`, and `serve`
/// at start-up (exit status non-zero, nothing served).
#[test]
fn a_missing_runtime_model_or_class_is_a_clear_error() {
    let _alone = crate::one_at_a_time();
    let photo = photos().join("dog.jpg");
    let detect = |env: &[(&str, &str)], args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_digiview"))
            .arg("detect")
            .arg("--image")
            .arg(&photo)
            .args(args)
            .envs(env.iter().copied())
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let err = detect(&[("ORT_DYLIB_PATH", "/no/such/libonnxruntime.so")], &[]);
    assert!(
        err.contains("/no/such/libonnxruntime.so") && err.contains("no such file"),
        "{err}"
    );
    // No runtime anywhere: where it was looked for, and what installs it.
    let empty = tempfile::tempdir().unwrap();
    let cache = empty.path().to_str().unwrap();
    let err = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args(["detect", "--image"])
        .arg(&photo)
        .env_remove("ORT_DYLIB_PATH")
        .env("XDG_CACHE_HOME", cache)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&err.stderr);
    assert!(
        !err.status.success() && text.contains("scripts/setup.sh"),
        "{text}"
    );
    // A model that is not one.
    let bogus = empty.path().join("model.onnx");
    std::fs::write(&bogus, "not a model").unwrap();
    let err = detect(&[], &["--model", bogus.to_str().unwrap()]);
    assert!(err.contains("model.onnx"), "{err}");
    let err = detect(&[], &["--classes", "person,unicorn"]);
    assert!(err.contains("unicorn: no such class"), "{err}");
    let err = detect(&[], &["--decoder", "yolov8"]);
    assert!(err.contains("YOLOv8"), "{err}");

    // serve refuses to start without its runtime, saying so.
    let out = Command::new(env!("CARGO_BIN_EXE_digiview"))
        .args([
            "serve",
            "--rtsp-port",
            "0",
            "--control",
            "127.0.0.1:0",
            "--http",
            "off",
        ])
        .args(["--mavlink", "off", "--detector", "onnx"])
        .env("DIGIVIEW_LENS_CAL", common::lens_cal_path())
        .env("ORT_DYLIB_PATH", "/no/such/libonnxruntime.so")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("ONNX Runtime") && err.contains("/no/such/libonnxruntime.so"),
        "{err}"
    );
}
