//! The pair through `serve` to a client: the lenses' exposure matched in the decoded stream,
//! and told to the operator (`/api/status`, and the page's status panel in Chromium).

use super::*;

/// Mean luma (BT.709) of rows `rows` of an image, over its middle half of columns.
fn row_luma(img: &RgbImage, rows: std::ops::Range<u32>) -> f64 {
    let (x0, x1) = (img.width() / 4, img.width() * 3 / 4);
    let n = (rows.len() as u32 * (x1 - x0)) as f64;
    rows.flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| pixel(img, x, y).dot(DVec3::new(0.2126, 0.7152, 0.0722)))
        .sum::<f64>()
        / n
}

#[test]
fn a_back_lens_half_again_as_bright_leaves_no_step_at_the_seam_in_the_decoded_stream() {
    let dir = tempfile::tempdir().unwrap();
    // A grey world (any step at the seam is the lenses' exposure), seen by the pair with the
    // back lens 1.5 times as bright as the front (about black).
    let grey = PanoramaWorld::new(RgbImage::from_pixel(64, 32, image::Rgb([90, 90, 90])));
    let s = state(ON_THE_SEAM);
    let mut frame = fisheye(&grey, &pair(0.0), &s);
    brighter_second(&mut frame, 1.5);
    let still = dir.path().join("pair.png");
    frame.save(&still).unwrap();
    let (serve, last) = served_through_dual(&format!("image:{}", still.display()));
    // The view looks level: the seam is its middle row. Rows 6 to 10 degrees above and below.
    let (above, below) = (row_luma(&last, 180..210), row_luma(&last, 270..300));
    let across = row_luma(&last, 236..244);
    eprintln!(
        "decoded luma: above the seam {above:.2}, on it {across:.2}, below {below:.2} \
         (the lenses alone: {:.1} and {:.1})",
        0.2126 * 90.0 + 0.7152 * 90.0 + 0.0722 * 90.0,
        90.0 * 1.5
    );
    assert!(
        (above - below).abs() <= 2.0,
        "a step of {:.2}",
        above - below
    );
    assert!((across - (above + below) / 2.0).abs() <= 2.0, "{across:.2}");
    // The operator is told how far apart the lenses are: the back lens's luma 1.5 times the
    // front's (about black).
    let http = serve.http.clone().unwrap();
    let (code, body) = common::gcs::http_get(&format!("{http}api/status"));
    assert_eq!(code, 200);
    let status: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let said = status["video"]["lenses"].as_str().unwrap_or_default();
    // "second lens: luma x1.51, Cb +0.0, ...": the luma gain about 1.5.
    let about_half_again = |said: &str| {
        let gain = said
            .strip_prefix("second lens: luma x")
            .and_then(|r| r.split(',').next()?.parse::<f64>().ok());
        gain.is_some_and(|g| (1.45..=1.55).contains(&g))
    };
    eprintln!("/api/status: {said}");
    assert!(about_half_again(said), "/api/status says {said:?}");
    // The page's status panel has the same row, in Chromium.
    let rt = tokio::runtime::Runtime::new().unwrap();
    let b = rt.block_on(common::browser::Browser::start(1024, 768));
    rt.block_on(b.client.goto(&http)).unwrap();
    let row = rt.block_on(b.until(
        "the page's lens pair row",
        std::time::Duration::from_secs(5),
        "const row = [...document.querySelectorAll('#figures dt')]
           .find((d) => d.textContent === 'lens pair');
         return row ? row.nextElementSibling.textContent : null;",
    ));
    let row = row.as_str().unwrap_or_default();
    eprintln!("the page: lens pair {row}");
    assert!(about_half_again(row), "the page says {row:?}");
    rt.block_on(b.close());
}
