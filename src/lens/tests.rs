use super::models::{DoubleSphere, KannalaBrandt, Ocam};
use super::samples::sample_lenses;
use super::*;
use std::f64::consts::PI;

/// Pixels spread over the whole valid image circle: rings out to its rim, many angles.
fn circle_pixels(lens: &Lens) -> Vec<DVec2> {
    let mut out = vec![lens.centre()];
    for ring in 1..=60 {
        let theta = lens.half_fov * ring as f64 / 60.0;
        for k in 0..72 {
            let phi = 2.0 * PI * k as f64 / 72.0 + ring as f64 * 0.01;
            let ray = DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            out.push(lens.project(ray).expect("rays inside the fov project"));
        }
    }
    out
}

#[test]
fn every_model_round_trips_pixels_over_its_whole_image_circle_within_a_thousandth_of_a_pixel() {
    for lens in sample_lenses() {
        let mut worst: f64 = 0.0;
        for p in circle_pixels(&lens) {
            let ray = lens.unproject(p).unwrap_or_else(|| {
                let m = lens.affine.to_normalized(p).length();
                panic!(
                    "{}: {p} (r {m}, θ {:?}, half fov {}) unprojects",
                    lens.name,
                    lens.radial.theta_of_r(m),
                    lens.half_fov
                )
            });
            let back = lens.project(ray).unwrap();
            worst = worst.max((back - p).length());
        }
        assert!(worst < 1e-3, "{}: worst round trip {worst:e} px", lens.name);
    }
}

#[test]
fn every_model_round_trips_rays_beyond_ninety_degrees() {
    for lens in sample_lenses()
        .into_iter()
        .filter(|l| l.half_fov > PI / 2.0 + 0.01)
    {
        let theta = lens.half_fov - 0.005;
        let ray = DVec3::new(theta.sin() * 0.6, theta.sin() * -0.8, theta.cos());
        assert!(ray.z < 0.0, "the test ray points backwards");
        let back = lens.unproject(lens.project(ray).unwrap()).unwrap();
        assert!(
            (back - ray).length() < 1e-9,
            "{}: {back} vs {ray}",
            lens.name
        );
    }
}

#[test]
fn rays_outside_the_valid_fov_do_not_project_and_pixels_outside_the_circle_do_not_unproject() {
    for lens in sample_lenses() {
        let theta = lens.half_fov + 0.01;
        let ray = DVec3::new(theta.sin(), 0.0, theta.cos());
        assert_eq!(lens.project(ray), None, "{}", lens.name);
        let rim = lens.centre() + DVec2::new(lens.circle_radius() * 1.02, 0.0);
        assert_eq!(lens.unproject(rim), None, "{}", lens.name);
    }
}

#[test]
fn the_optical_axis_lands_on_the_principal_point() {
    for lens in sample_lenses() {
        let p = lens.project(DVec3::Z).unwrap();
        assert!((p - lens.centre()).length() < 1e-9, "{}", lens.name);
    }
}

#[test]
fn double_sphere_radial_form_matches_the_papers_three_dimensional_projection() {
    let (xi, alpha, f, c) = (-0.22, 0.58, 180.0, 640.0);
    let lens = Lens::new(
        "ds",
        0,
        Model::DoubleSphere(DoubleSphere { xi, alpha }),
        PixelAffine::pinhole(f, f, c, c),
        (1280, 1280),
        6.0,
    );
    for &(x, y, z) in &[(0.3, -0.2, 1.0), (1.0, 0.5, 0.1), (0.2, 0.9, -0.3)] {
        let p = DVec3::new(x, y, z);
        let d1 = p.length();
        let d2 = (x * x + y * y + (xi * d1 + z).powi(2)).sqrt();
        let den = alpha * d2 + (1.0 - alpha) * (xi * d1 + z);
        let expect = DVec2::new(f * x / den + c, f * y / den + c);
        let got = lens.project(p).unwrap();
        assert!((got - expect).length() < 1e-9, "{got} vs {expect}");
    }
}

#[test]
fn kannala_brandt_stops_at_the_fold_where_its_polynomial_turns_back() {
    // k1 < 0 strongly: r(θ) peaks well before 180°.
    let k = [-0.3, 0.0, 0.0, 0.0];
    let theta_max = KannalaBrandt { k }.limits().theta_max;
    let expect = (1.0_f64 / 0.9).sqrt(); // dr/dθ = 1 - 0.9 θ² = 0
    assert!((theta_max - expect).abs() < 1e-9, "{theta_max} vs {expect}");
    let lens = Lens::new(
        "fold",
        0,
        Model::KannalaBrandt(KannalaBrandt { k }),
        PixelAffine::pinhole(300.0, 300.0, 0.0, 0.0),
        (10, 10),
        3.0,
    );
    assert!(
        (lens.half_fov - theta_max).abs() < 1e-12,
        "the valid fov is cut at the fold"
    );
    // Past the fold the same radius has two preimages; the inverse returns the one on the branch.
    let r = lens.radial.r_of_theta(0.8).unwrap();
    let theta = lens.radial.theta_of_r(r).unwrap();
    assert!((theta - 0.8).abs() < 1e-10);
}

#[test]
fn ocam_projection_is_exact_even_when_the_inverse_polynomial_is_only_a_rough_fit() {
    let pol = vec![-190.0, 0.0, 1.1e-3, 2.0e-7, 1.0e-9];
    let rough = Radial::new(Model::Ocam(Ocam {
        pol: pol.clone(),
        invpol: vec![250.0, 150.0],
    }));
    let none = Radial::new(Model::Ocam(Ocam {
        pol,
        invpol: vec![],
    }));
    for i in 1..50 {
        let theta = rough.limits.theta_max * i as f64 / 50.0;
        let (a, b) = (
            rough.r_of_theta(theta).unwrap(),
            none.r_of_theta(theta).unwrap(),
        );
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        let back = rough.theta_of_r(a).unwrap();
        assert!((back - theta).abs() < 1e-11, "θ {theta} → r {a} → θ {back}");
    }
}

#[test]
fn rescaling_to_another_frame_size_moves_pixels_with_the_frame() {
    for lens in sample_lenses() {
        let half = lens.for_frame(lens.width / 2, lens.height / 2, None);
        let ray = DVec3::new(0.4, -0.3, 0.8).normalize();
        let (p, q) = (lens.project(ray).unwrap(), half.project(ray).unwrap());
        // Pixel centres: full-res pixel centres 0 and 1 map to half-res 0.25 - 0.5 = -0.25 and 0.25.
        let expect = (p + 0.5) * 0.5 - 0.5;
        assert!(
            (q - expect).length() < 1e-9,
            "{}: {q} vs {expect}",
            lens.name
        );
        assert!((half.circle_radius() - lens.circle_radius() * 0.5).abs() < 1e-6);
    }
}

#[test]
fn a_sensor_crop_shifts_the_principal_point_by_the_crop_origin() {
    let lens = &sample_lenses()[0];
    let roi = Roi {
        x: 100.0,
        y: 60.0,
        width: 1080.0,
        height: 840.0,
    };
    let cropped = lens.for_frame(1080, 840, Some(roi));
    let d = lens.centre() - cropped.centre();
    assert!((d - DVec2::new(100.0, 60.0)).length() < 1e-9);
}

#[test]
fn the_imaged_box_holds_the_whole_image_circle_with_its_margin_and_no_more() {
    for lens in sample_lenses() {
        let (columns, rows) = lens.imaged_box();
        for range in [&columns, &rows] {
            assert_eq!(range.start % IMAGED_ALIGN, 0, "{}", lens.name);
        }
        assert!(columns.end % IMAGED_ALIGN == 0 || columns.end == lens.width);
        assert!(rows.end % IMAGED_ALIGN == 0 || rows.end == lens.height);
        let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
        for p in circle_pixels(&lens) {
            let inside = |v: f64, r: &Range<u32>, size: u32| {
                (v - IMAGED_MARGIN < 0.0 || v - IMAGED_MARGIN >= r.start as f64)
                    && (v + IMAGED_MARGIN >= size as f64 || v + IMAGED_MARGIN < r.end as f64)
            };
            assert!(
                inside(p.x, &columns, lens.width) && inside(p.y, &rows, lens.height),
                "{}: {p} and its margin are not all in {columns:?} x {rows:?}",
                lens.name
            );
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        // Tight: no more than the margin and the rounding beyond the circle's extent.
        let slack = IMAGED_MARGIN + IMAGED_ALIGN as f64 + 1.0;
        assert!(columns.start as f64 >= lo.x - slack && columns.end as f64 <= hi.x + slack);
        assert!(rows.start as f64 >= lo.y - slack && rows.end as f64 <= hi.y + slack);
    }
}

#[test]
fn the_cil216_circle_leaves_over_a_third_of_a_4k_frame_unimaged() {
    let cal = super::calfile::LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
    let lens = cal.by_id(0).unwrap().lens().for_frame(3840, 2160, None);
    let (columns, rows) = lens.imaged_box();
    // Circle radius 1175 px about x = 1919.5: 744.5 .. 3094.5, plus 16, rounded out to 32.
    assert_eq!((columns, rows), (704..3136, 0..2160));
}

#[test]
fn the_boson_lens_sees_its_published_50_degrees_across_and_a_fisheye_its_whole_field() {
    let cal = super::calfile::LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
    let boson = cal.by_id(3).unwrap().lens().for_frame(320, 256, None);
    let hfov = boson.hfov().to_degrees();
    assert!((hfov - 50.0).abs() < 1.0, "{hfov:.2}°");
    let fisheye = cal.by_id(0).unwrap().lens().for_frame(3840, 2160, None);
    assert_eq!(fisheye.hfov(), 2.0 * fisheye.half_fov);
}

#[test]
fn a_lens_pair_takes_frames_of_its_shape_only_and_one_lens_any() {
    let cal = super::calfile::LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
    let lenses = Lenses::new(&cal);
    let dual = cal.find("DUAL").unwrap().lens_id;
    // Within a pixel of the shape across.
    for fits in [(3840, 1920), (1920, 960), (1440, 720), (1441, 720)] {
        assert!(lenses.for_frame(dual, fits, None).is_ok(), "{fits:?}");
    }
    assert!(lenses.for_frame(dual, (1442, 720), None).is_err());
    let e = lenses.for_frame(dual, (3840, 2160), None).unwrap_err();
    assert_eq!(
        e.to_string(),
        "lens DUAL sees two images side by side in a 3840x1920 frame; a 3840x2160 frame is \
         another shape, which would squeeze them (a frame of the pair's shape is needed)"
    );
    // A sensor crop says which part of the frame the pair's frame is.
    let crop = Roi {
        x: 0.0,
        y: 0.0,
        width: 3840.0,
        height: 1920.0,
    };
    assert!(lenses.for_frame(dual, (3840, 2160), Some(crop)).is_ok());
    // One lens takes any frame (scaled to it).
    assert!(lenses.for_frame(0, (640, 480), None).is_ok());
}
