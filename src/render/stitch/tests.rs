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
        stitch.apply(&mut data);
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
