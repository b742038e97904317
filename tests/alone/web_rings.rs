//! The tracked objects' rings on the tuning page, in headless Chromium against `digiview serve`
//! on the demo: on a phone the labels are legible and apart, the rings move with every frame
//! of the picture drawn, and with the vehicle flying in the fisheye layout each ring sits on
//! its mover in the very frame it is drawn over (the movers found by their colours in the
//! picture's canvas). One at a time: the rings come from the detection thread, which a test
//! beside them starves (in `tests/it` a run once had rings in 13 of 90 frames).

use crate::common;

use common::browser::Browser;
use common::serve::Serve;
use serde_json::Value;
use std::time::Duration;

/// A script's function: a signature of the picture the page shows (every 4th pixel each
/// way), which tells a new picture from the last one drawn again.
const PICTURE: &str = "
    const signature = () => {
      const g = document.getElementById('video').getContext('2d');
      const [w, h] = [g.canvas.width, g.canvas.height];
      const d = g.getImageData(0, 0, w, h).data;
      let s = 0;
      for (let y = 0; y < h; y += 4) {
        for (let x = 0; x < w; x += 4) {
          const k = 4 * (y * w + x);
          s = (Math.imul(s, 31) + d[k] + 7 * d[k + 1] + 13 * d[k + 2]) >>> 0;
        }
      }
      return s;
    };";

/// A script: the overlay's rings (`dataset.rings`), the frame's time and the picture's
/// signature at each frame of the picture the page draws, until `arguments[0]` pairs of
/// different pictures in a row start with a moving ring (or 90 frames).
fn frames_with_rings() -> String {
    PICTURE.to_string()
        + "
    const want = arguments[0];
    const c = document.getElementById('overlay');
    const preview = window.digiview.preview;
    const moving = (f) => JSON.parse(f || '[]').some(r => r.moving);
    return new Promise(done => {
      const seen = [];
      let pairs = 0;
      preview.addEventListener('frame', function step() {
        const last = seen[seen.length - 1];
        const now = { drawn: c.dataset.rings, pts: c.dataset.pts, picture: signature() };
        if (last && last.pts !== now.pts && last.picture !== now.picture && moving(last.drawn)) {
          pairs++;
        }
        seen.push(now);
        if (pairs < want && seen.length < 90) return;
        preview.removeEventListener('frame', step);
        done(seen);
      });
    })"
}

/// Of the frames drawn (each `{drawn, pts}`: the overlay's rings as JSON, the frame's time),
/// the pairs of different frames in a row whose first has a moving ring, and of those, the
/// pairs whose rings differ.
fn moving_pairs(frames: &Value) -> (usize, usize) {
    let frames = frames.as_array().unwrap();
    let drawn: Vec<&str> = frames
        .iter()
        .map(|f| f["drawn"].as_str().unwrap_or("[]"))
        .collect();
    // The same frame drawn again rightly keeps its rings: by the page (its presentation time
    // unchanged), or by the head (the same picture at a new time: a source slower than the
    // output, the last frame rendered again because the tracked objects changed, tiles with
    // it, while the rings' objects did not move).
    let new: Vec<bool> = frames
        .windows(2)
        .map(|w| w[0]["pts"] != w[1]["pts"] && w[0]["picture"] != w[1]["picture"])
        .collect();
    let again = frames
        .windows(2)
        .filter(|w| w[0]["pts"] != w[1]["pts"] && w[0]["picture"] == w[1]["picture"])
        .count();
    eprintln!("{again} frames the head drew again (a new time, the same picture)");
    let moving = |f: &str| {
        let rings: Value = serde_json::from_str(f).unwrap();
        rings
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r["moving"] == true)
    };
    let pairs: Vec<_> = drawn
        .windows(2)
        .zip(&new)
        .filter(|(w, new)| **new && moving(w[0]))
        .map(|(w, _)| w)
        .collect();
    let moved = pairs.iter().filter(|w| w[0] != w[1]).count();
    for w in pairs.iter().filter(|w| w[0] == w[1]) {
        let at = drawn
            .windows(2)
            .position(|d| std::ptr::eq(d, *w))
            .unwrap_or(0);
        eprintln!(
            "rings stood still from frame {at} (pts {}) to {} (pts {}): {}",
            frames[at]["pts"],
            at + 1,
            frames[at + 1]["pts"],
            w[0]
        );
    }
    (pairs.len(), moved)
}

/// On a phone (390x844), with the demo's movers tracked: the status panel gives the
/// detection's scans a second and the objects tracked, and every label over the picture
/// ("cam N", "#n") is at least 11 CSS pixels tall and clear of every other (read from where
/// the page drew them). A screenshot goes to web-phone-390x844.png in cargo's directory for
/// the tests' files (target/tmp).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
// The guard is held for the whole test, awaits included: that is what runs it alone.
#[allow(clippy::await_holding_lock)]
async fn on_a_phone_the_labels_are_legible_and_apart_and_the_panel_says_what_detection_does() {
    let _alone = crate::one_at_a_time();
    let serve = Serve::start_video(&["--size", "1280x720", "--demo-hover", "--detector", "motion"]);
    let b = Browser::start(390, 844).await;
    b.client.goto(serve.http.as_ref().unwrap()).await.unwrap();
    let figures = b
        .until(
            "the panel's detection figures, with objects tracked",
            Duration::from_secs(30),
            "const f = document.getElementById('figures').textContent;
             const n = /tracked\\s*(\\d+)/.exec(f);
             return /\\d+\\.\\d scans\\/s/.test(f) && n && +n[1] > 0 ? f : null",
        )
        .await;
    eprintln!("{figures}");
    // The labels' boxes and text heights as the page drew them, in canvas pixels, and the
    // canvas's CSS pixels per canvas pixel as the browser lays it out.
    let labels = b
        .until(
            "rings labelled over the picture",
            Duration::from_secs(20),
            "const c = document.getElementById('overlay');
             const l = JSON.parse(c.dataset.labels || '[]');
             return l.length > 4 ? [c.getBoundingClientRect().width / c.width, l] : null",
        )
        .await;
    let css = labels[0].as_f64().unwrap();
    let boxes: Vec<[f64; 5]> = labels[1]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| ["x", "y", "w", "h", "font"].map(|k| l[k].as_f64().unwrap() * css))
        .collect();
    eprintln!("{} labels, CSS px: {boxes:.1?}", boxes.len());
    for (i, a) in boxes.iter().enumerate() {
        assert!(a[4] >= 11.0, "label {i}'s text is {:.1} CSS px tall", a[4]);
        for b in &boxes[..i] {
            let apart = a[0] >= b[0] + b[2]
                || b[0] >= a[0] + a[2]
                || a[1] >= b[1] + b[3]
                || b[1] >= a[1] + a[3];
            assert!(apart, "labels overlap: {a:.1?} and {b:.1?}");
        }
    }
    // The rings move on every frame of the picture the page draws, at the tracker's velocity,
    // not only when an update comes (about every 100 ms): 9 pairs of frames drawn with a
    // moving ring (a ring is still where the tracker has no velocity for it).
    let frames = b.js(&frames_with_rings(), vec![9.into()]).await;
    let (pairs, moved) = moving_pairs(&frames);
    eprintln!("rings moved in {moved} of {pairs} pairs of drawn frames with a moving ring");
    assert!(pairs >= 5, "too few frames with moving rings: {frames}");
    assert_eq!(
        moved, pairs,
        "the rings stood still between frames: {frames}"
    );
    let shot = b.client.screenshot().await.unwrap();
    // Kept for a look, where cargo keeps the tests' files (the target directory, wherever
    // CARGO_TARGET_DIR puts it).
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("web-phone-390x844.png");
    std::fs::write(&path, shot).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    b.close().await;
}

/// What the page shows while the demo flies in the fisheye layout (6), where a ring placed
/// without the vehicle's heading at that frame lands tens of pixels off: over 90 frames of
/// the picture as drawn, each ring (where the overlay drew it) has the colour of one of the
/// demo's movers (pink, lime, brown) within 20 px of its centre in the picture's canvas, in
/// at least 90% of the frames; and the rings move with every frame drawn.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
// The guard is held for the whole test, awaits included: that is what runs it alone.
#[allow(clippy::await_holding_lock)]
async fn flying_in_the_fisheye_layout_the_rings_sit_on_their_movers_in_each_frame_drawn() {
    let _alone = crate::one_at_a_time();
    let serve = Serve::start_video(&[
        "--size",
        "1280x720",
        "--layout",
        "6",
        "--detector",
        "motion",
    ]);
    let b = Browser::start(1280, 900).await;
    b.client.goto(serve.http.as_ref().unwrap()).await.unwrap();
    b.until(
        "two movers ringed over a picture timing them",
        Duration::from_secs(40),
        "const c = document.getElementById('overlay');
         return c.dataset.pts && JSON.parse(c.dataset.rings || '[]').length >= 2",
    )
    .await;
    // Each frame as drawn: the rings' centres, and for each whether the picture has at least
    // two pixels of a mover's colour within 20 px of it.
    let script = PICTURE.to_string()
        + "const [n, reach] = arguments;
             const mover = (r, g, b) =>
               (g - r > 60 && g - b > 100)                                // lime
               || (r > 200 && r - g > 60 && b - g > 5 && b - g < 60)     // pink
               || (r > 70 && r < 130 && r - g >= 12 && g - b >= 15);     // brown
             const picture = document.getElementById('video').getContext('2d');
             const overlay = document.getElementById('overlay');
             return new Promise(done => {
               const seen = [];
               const preview = window.digiview.preview;
               preview.addEventListener('frame', function step() {
                 const rings = JSON.parse(overlay.dataset.rings || '[]').map(r => {
                   const [x0, y0] = [Math.round(r.x) - reach, Math.round(r.y) - reach];
                   const d = picture.getImageData(x0, y0, 2 * reach + 1, 2 * reach + 1).data;
                   let hits = 0;
                   for (let j = 0; j <= 2 * reach; j++) {
                     for (let i = 0; i <= 2 * reach; i++) {
                       const k = 4 * (j * (2 * reach + 1) + i);
                       const inside = (i - reach) ** 2 + (j - reach) ** 2 <= reach * reach;
                       if (inside && mover(d[k], d[k + 1], d[k + 2])) hits++;
                     }
                   }
                   return [r.x, r.y, hits >= 2];
                 });
                 seen.push({ rings, drawn: overlay.dataset.rings, pts: overlay.dataset.pts,
                             picture: signature() });
                 if (seen.length < n) return;
                 preview.removeEventListener('frame', step);
                 done(seen);
               });
             })";
    let frames = b.js(&script, vec![90.into(), 20.into()]).await;
    let (pairs, moved) = moving_pairs(&frames);
    let frames = frames.as_array().unwrap();
    let rings = |f: &Value| f["rings"].as_array().unwrap().clone();
    let ringed: Vec<_> = frames.iter().filter(|f| !rings(f).is_empty()).collect();
    let on = ringed
        .iter()
        .filter(|f| rings(f).iter().all(|r| r[2].as_bool().unwrap()))
        .count();
    let all: usize = ringed.iter().map(|f| rings(f).len()).sum();
    let off = ringed
        .iter()
        .flat_map(|f| rings(f))
        .filter(|r| !r[2].as_bool().unwrap())
        .count();
    eprintln!(
        "{} frames, {} with rings: every ring on a mover in {on} ({:.1}%); {off} of {all} \
         rings off; rings moved in {moved} of {pairs} pairs of frames with a moving ring",
        frames.len(),
        ringed.len(),
        100.0 * on as f64 / ringed.len().max(1) as f64,
    );
    // A ring is drawn only within 1 s of a sighting, so a scan starved of the CPU leaves
    // frames without rings; most frames have them.
    assert!(ringed.len() * 3 >= frames.len(), "rings in too few frames");
    assert!(
        on * 10 >= ringed.len() * 9,
        "every ring on a mover in only {on} of {} frames: {frames:?}",
        ringed.len()
    );
    assert!(
        pairs * 3 >= frames.len(),
        "too few frames with moving rings"
    );
    assert_eq!(moved, pairs, "the rings stood still between frames");
    b.close().await;
}
