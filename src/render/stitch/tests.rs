use super::*;
use crate::lens::calfile::LensCal;
use glam::DVec3;
use std::path::Path;

fn dual(width: u32, height: u32) -> Lens {
    let cal = LensCal::load(Path::new("lens-cal/lens.cal")).unwrap();
    cal.find("DUAL")
        .unwrap()
        .lens()
        .for_frame(width, height, None)
}

/// A frame whose left (first lens's) half is `a` and right half `b`, every channel.
fn halves(layout: &PlaneLayout, a: u8, b: u8) -> Vec<u8> {
    let mut data = vec![0u8; layout.size as usize];
    for rows in layout.planes() {
        for y in 0..rows.rows {
            let start = (rows.offset + y * rows.stride) as usize;
            let row = &mut data[start..start + rows.bytes as usize];
            let half = row.len() / 2;
            row[..half].fill(a);
            row[half..].fill(b);
        }
    }
    data
}

/// Blends the seam of `data` in place, neither lens corrected.
fn apply(stitch: &Stitch, data: &mut [u8]) {
    let tables = Matching::default().tables(&stitch.components);
    let from = data.to_vec();
    stitch.stitch_into(&from, data, &tables);
}

/// Luma (or red) at a frame position, nearest pixel.
fn at(layout: &PlaneLayout, data: &[u8], p: DVec2) -> u8 {
    let c = if layout.format == PixelFormat::Rgba {
        4
    } else {
        1
    };
    let (x, y) = (p.x.round() as u32, p.y.round() as u32);
    data[(y * layout.stride + x * c) as usize]
}

#[test]
fn across_the_seam_each_image_holds_the_blend_its_ray_should_have() {
    for format in [PixelFormat::Rgba, PixelFormat::Nv12, PixelFormat::I420] {
        let layout = PlaneLayout::aligned(format, 960, 480, 64).unwrap();
        let lens = dual(960, 480);
        let pair = lens.pair.as_ref().unwrap();
        let stitch = Stitch::new(&lens, &layout).unwrap();
        let mut data = halves(&layout, 200, 40);
        apply(&stitch, &mut data);
        // A ray on the seam: both images hold the half-and-half blend.
        let seam = DVec3::new(0.6, 0.3, 0.0).normalize();
        for side in [Side::First, Side::Second] {
            let p = pair.project_in(side, seam).unwrap().round();
            let ray = pair.unproject(p).unwrap();
            let first = weight_of(pair.best(ray).1, pair.feather);
            let want = 40.0 + 160.0 * first;
            let v = at(&layout, &data, p) as f64;
            assert!(
                (v - want).abs() <= 2.0,
                "{format:?} {side:?}: {v} against {want:.1}"
            );
            assert!((want - 120.0).abs() < 30.0);
        }
        // Past the feather's edge each image keeps its own.
        let deep = DVec3::new(0.6, 0.3, 0.06).normalize(); // 3.1deg towards the first lens
        assert_eq!(
            at(&layout, &data, pair.project_in(Side::First, deep).unwrap()),
            200
        );
        let p = pair.project_in(Side::Second, -deep).unwrap();
        assert_eq!(at(&layout, &data, p), 40, "{format:?}");
        // Halfway into the feather, a quarter-step of the smooth step: 200 - 160 * 0.156.
        let quarter = DVec3::new(0.6, 0.3, (0.5f64).to_radians().tan() * 0.6708).normalize();
        let p = pair.project_in(Side::First, quarter).unwrap().round();
        let share = 1.0 - weight_of(pair.best(pair.unproject(p).unwrap()).1, pair.feather);
        assert!((0.05..0.4).contains(&share), "{share}");
        let want = 200.0 - 160.0 * share;
        let v = at(&layout, &data, p) as f64;
        assert!((v - want).abs() <= 3.0, "{format:?}: {v} against {want:.1}");
    }
}

#[test]
fn a_frame_of_one_lens_has_no_seam_and_a_pair_touches_only_a_band() {
    let cal = LensCal::load(Path::new("lens-cal/lens.cal")).unwrap();
    let single = cal.find("CIL216").unwrap().lens();
    let layout = PlaneLayout::tight(PixelFormat::Nv12, 3840, 2160).unwrap();
    assert!(Stitch::new(&single, &layout).is_none());
    let layout = PlaneLayout::tight(PixelFormat::Nv12, 3840, 1920).unwrap();
    let stitch = Stitch::new(&dual(3840, 1920), &layout).unwrap();
    let share = stitch.taps() as f64 / (3840.0 * 1920.0 * 1.5);
    // The feather (4deg) and the reach (2deg) of two circles of 950 px: about 6%.
    assert!((0.03..0.10).contains(&share), "{share:.3}");
}

/// A 4:2:0 frame whose luma is `a` in the first lens's half and `b` in the second's, chroma
/// `cb`, `cr` and `cb2`, `cr2` likewise.
fn exposed(layout: &PlaneLayout, luma: (u8, u8), cb: (u8, u8), cr: (u8, u8)) -> Vec<u8> {
    let mut data = halves(layout, luma.0, luma.1);
    let chroma = layout.planes()[1];
    for y in 0..chroma.rows {
        let start = (chroma.offset + y * chroma.stride) as usize;
        let row = &mut data[start..start + chroma.bytes as usize];
        let half = row.len() / 2;
        for (i, px) in row.chunks_exact_mut(2).enumerate() {
            let second = i * 2 >= half;
            px[0] = if second { cb.1 } else { cb.0 };
            px[1] = if second { cr.1 } else { cr.0 };
        }
    }
    data
}

/// Luma at a frame position (nearest pixel) and the NV12 chroma there.
fn yuv_at(layout: &PlaneLayout, data: &[u8], p: DVec2) -> [u8; 3] {
    let (x, y) = (p.x.round() as u32, p.y.round() as u32);
    let (u, v) = layout.chroma_at(x / 2, y / 2);
    [data[(y * layout.stride + x) as usize], data[u], data[v]]
}

/// A 960x480 NV12 frame's layout, the pair for it, and a pixel deep in each lens's own part
/// (the first's, the second's), where no blend reaches.
fn deep_in_each() -> (PlaneLayout, Lens, DVec2, DVec2) {
    let layout = PlaneLayout::aligned(PixelFormat::Nv12, 960, 480, 64).unwrap();
    let lens = dual(960, 480);
    let pair = lens.pair.as_ref().unwrap();
    let deep = DVec3::new(0.6, 0.3, 0.3).normalize();
    let front = pair.project_in(Side::First, deep).unwrap();
    let back = pair.project_in(Side::Second, -deep).unwrap();
    (layout, lens, front, back)
}

#[test]
fn a_second_lens_half_again_as_bright_and_warmer_is_matched_halfway_and_slowly() {
    let (layout, lens, front, back) = deep_in_each();
    let mut stitches = Stitches::default();
    let even = exposed(&layout, (100, 100), (128, 128), (128, 128));
    let out = stitches.stitched(&lens, &layout, &even);
    assert_eq!(yuv_at(&layout, out, front), [100, 128, 128]);
    // Luma 16 + 84 against 16 + 126 (1.5 times above black); the back lens 6 codes bluer.
    let uneven = exposed(&layout, (100, 142), (128, 134), (128, 122));
    let out = stitches.stitched(&lens, &layout, &uneven).to_vec();
    let (f, b) = (yuv_at(&layout, &out, front), yuv_at(&layout, &out, back));
    assert!(
        b[0] - f[0] > 35,
        "one frame on, the match has barely moved: {f:?} {b:?}"
    );
    for _ in 0..120 {
        stitches.stitched(&lens, &layout, &uneven);
    }
    let out = stitches.stitched(&lens, &layout, &uneven).to_vec();
    let (f, b) = (yuv_at(&layout, &out, front), yuv_at(&layout, &out, back));
    // Halfway: the geometric mean of 84 and 126 above black, and chroma 131 and 125.
    let want = 16.0 + (84.0f64 * 126.0).sqrt();
    for (v, w) in [
        (f[0], want),
        (b[0], want),
        (f[1], 131.0),
        (b[1], 131.0),
        (f[2], 125.0),
        (b[2], 125.0),
    ] {
        assert!((v as f64 - w).abs() <= 1.0, "{f:?} {b:?} against {want:.1}");
    }
    let apart = stitches.apart();
    assert!(
        (apart[0] - 1.5).abs() < 0.01 && (apart[1] - 6.0).abs() < 0.1,
        "{apart:?}"
    );
}

#[test]
fn a_lens_far_darker_than_the_other_is_matched_no_further_than_twice_and_said_so() {
    let (layout, lens, front, back) = deep_in_each();
    // The back lens all but covered: 10 codes above black against the front's 150.
    let covered = exposed(&layout, (166, 26), (128, 128), (128, 128));
    let mut stitches = Stitches::default();
    let out = stitches.stitched(&lens, &layout, &covered).to_vec();
    let (f, b) = (yuv_at(&layout, &out, front), yuv_at(&layout, &out, back));
    // Halved and doubled about black, no further: the front lens stays at 16 + 75, not
    // dragged to the geometric mean of 150 and 10 (16 + 39).
    assert_eq!((f[0], b[0]), (16 + 75, 16 + 20), "{f:?} {b:?}");
    let said = stitches.said();
    assert!(
        said.starts_with("second lens: luma x0.07") && said.contains("is one covered?"),
        "{said}"
    );
    // Lenses 1.5 times apart are still matched halfway, and said to be.
    let mut stitches = Stitches::default();
    stitches.stitched(
        &lens,
        &layout,
        &exposed(&layout, (100, 142), (128, 128), (128, 128)),
    );
    assert!(
        stitches.said().ends_with("(each corrected halfway)"),
        "{}",
        stitches.said()
    );
}
