use super::*;
use crate::lens::calfile::LensCal;
use std::path::Path;

fn shipped() -> LensCal {
    LensCal::load(Path::new("lens-cal/lens.cal")).unwrap()
}

fn dual() -> Lens {
    shipped().find("DUAL").unwrap().lens()
}

/// Directions spread evenly over the whole sphere (a Fibonacci lattice).
fn sphere(n: usize) -> impl Iterator<Item = DVec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n).map(move |i| {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let a = golden * i as f64;
        DVec3::new(r * a.cos(), r * a.sin(), z)
    })
}

#[test]
fn every_direction_lands_in_the_frame_and_comes_back_the_same_ray() {
    let lens = dual();
    assert_eq!(lens.fov(), 2.0 * PI);
    for ray in sphere(20_000) {
        let p = lens
            .project(ray)
            .unwrap_or_else(|| panic!("{ray} not seen"));
        assert!(lens.in_frame(p), "{ray} → {p}");
        let back = lens.unproject(p).unwrap();
        assert!(back.distance(ray) < 1e-9, "{ray} → {p} → {back}");
    }
}

#[test]
fn the_back_lens_takes_what_lies_behind_and_the_seam_is_halfway() {
    let lens = dual();
    let pair = lens.pair.as_ref().unwrap();
    // Straight back lands on the back lens's centre, right half of the frame.
    let back = lens.project(DVec3::NEG_Z).unwrap();
    assert!(back.distance(DVec2::new(2879.5, 959.5)) < 1e-9, "{back}");
    assert_eq!(pair.side_at(back), Side::Second);
    // Up (-y) is up in both images: a ray a little above the horizon, either side of the seam.
    let front_up = lens.project(DVec3::new(0.0, -0.5, 1.0)).unwrap();
    let back_up = lens.project(DVec3::new(0.0, -0.5, -1.0)).unwrap();
    assert!(front_up.y < 959.5 && back_up.y < 959.5);
    // On the plane between the lenses both see equally: half each.
    let seam = DVec3::new(0.3, 0.7, 0.0).normalize();
    assert!((pair.first_weight(seam) - 0.5).abs() < 1e-12);
    let front = DVec3::new(0.3, 0.7, 0.2).normalize();
    assert_eq!(
        pair.first_weight(front),
        1.0,
        "11.5deg in front of the seam"
    );
    assert_eq!(pair.first_weight(-front), 0.0);
}

#[test]
fn a_twist_of_the_back_lens_turns_its_image_about_its_centre() {
    let lens = dual();
    let pose = PairPose {
        correction: correction(2f64.to_radians(), 0.0, 0.0),
        baseline: DVec3::ZERO,
        feather: 0.0,
        masks: vec![],
    };
    let cal = shipped();
    let first = cal.find("DUALF").unwrap().lens();
    let second = cal.find("DUALB").unwrap().lens();
    let twisted = Lens::paired(&first, &second, "T", 9, pose);
    // A ray behind and to the side: its pixel turns 2° about the back lens's centre.
    let ray = DVec3::new(0.6, 0.0, -1.0).normalize();
    let centre = DVec2::new(2879.5, 959.5);
    let (a, b) = (lens.project(ray).unwrap(), twisted.project(ray).unwrap());
    let turn = (b - centre).angle_to(a - centre).abs().to_degrees();
    assert!((turn - 2.0).abs() < 1e-9, "{turn}°");
    // The front lens is where it was.
    let ahead = DVec3::new(0.2, 0.1, 1.0);
    assert_eq!(lens.project(ahead), twisted.project(ahead));
}

#[test]
fn a_pair_at_half_size_maps_each_lens_to_its_half() {
    let lens = dual().for_frame(1920, 960, None);
    let back = lens.project(DVec3::NEG_Z).unwrap();
    assert!(back.distance(DVec2::new(1439.5, 479.5)) < 1e-9, "{back}");
    for ray in sphere(2000) {
        let p = lens.project(ray).unwrap();
        assert!(lens.unproject(p).unwrap().distance(ray) < 1e-9);
    }
}

fn parse(extra: &str) -> Result<LensCal, crate::lens::LensError> {
    let text = std::fs::read_to_string("lens-cal/lens.cal").unwrap();
    let (lenses, _) = text.split_once("[[pair]]").unwrap();
    LensCal::parse(Path::new("t.cal"), &format!("{lenses}[[pair]]\n{extra}"))
}

#[test]
fn a_pair_that_cannot_be_one_source_is_refused_saying_why() {
    let base = "name = \"P\"\nlens_id = 9\n";
    for (fields, says) in [
        (
            "lenses = [\"DUALF\"]",
            "lenses: must name two lenses (got 1)",
        ),
        (
            "lenses = [\"DUALF\", \"NOPE\"]",
            "no `[[lens]]` named `NOPE` in the file",
        ),
        (
            "lenses = [\"DUALF\", \"CIL216\"]",
            "`DUALF` is 3840x1920 and `CIL216` 3840x2160",
        ),
        (
            "lenses = [\"DUALF\", \"DUALB\"]\nfeather = \"30deg\"",
            "feather: must be 0 to 20deg",
        ),
        (
            "lenses = [\"DUALF\", \"DUALB\"]\nrotation = [\"40deg\", 0, 0]",
            "rotation: each angle must be within 28deg",
        ),
        ("lenses = [\"DUALF\", \"DUALB\"]\nlens_id = 0", "lens_id"),
        (
            "lenses = [\"DUALF\", \"DUALB\"]\nmasks = [[[10, 10], [20, 10]]]",
            "masks: polygon 1: needs at least three points",
        ),
        (
            "lenses = [\"DUALF\", \"DUALB\"]\nmasks = [[[1, 1], [9, 1], [9, 9]], [[0, 0], [5000, 0], [0, 5]]]",
            "masks: polygon 2: every point must lie in the 3840x1920 frame",
        ),
        (
            "lenses = [\"DUALF\", \"DUALB\"]\nmasks = [[[1800, 900], [2000, 900], [1900, 1000]]]",
            "masks: polygon 1: must lie within one lens's image",
        ),
    ] {
        let e = parse(&format!("{base}{fields}\n")).unwrap_err().to_string();
        assert!(e.contains(says), "{fields}: {e}");
    }
}

#[test]
fn a_pair_written_out_reads_back_the_same() {
    let cal = parse(
        "name = \"P\"\nlens_id = 9\nlenses = [\"DUALF\", \"DUALB\"]\n\
         rotation = [\"2deg\", \"-0.5deg\", \"0.25deg\"]\nfeather = \"6deg\"\n\
         masks = [[[100, 900], [300, 880.5], [310, 1000]], [[3000, 10], [3100, 10], [3050, 90]]]\n",
    )
    .unwrap();
    let entry = cal.find("P").unwrap();
    let text = std::fs::read_to_string("lens-cal/lens.cal").unwrap();
    let (lenses, _) = text.split_once("[[pair]]").unwrap();
    let back = LensCal::parse(Path::new("b"), &format!("{lenses}{}", entry.to_toml())).unwrap();
    let again = back.find("P").unwrap();
    let (a, b) = (entry.pair.as_ref().unwrap(), again.pair.as_ref().unwrap());
    for (x, y) in a.rotation.iter().zip(b.rotation) {
        assert!((x - y).abs() < 1e-7, "{:?} {:?}", a.rotation, b.rotation);
    }
    assert!((a.feather - b.feather).abs() < 1e-6);
    assert_eq!(a.masks, b.masks);
    assert_eq!(a.masks[0].points[1], DVec2::new(300.0, 880.5));
    // The lens carries them, in its frame's pixels; at half size, halved.
    let half = again.lens().for_frame(1920, 960, None);
    let masks = &half.pair.as_ref().unwrap().masks;
    assert!(masks[1].contains(DVec2::new(1525.0, 20.0)));
    assert!(!masks[1].contains(DVec2::new(3050.0, 40.0)));
    assert_eq!((again.lens_id, &again.name), (9, &"P".to_string()));
}

#[test]
fn lens_check_says_how_much_of_what_a_mask_hides_the_other_lens_sees() {
    let cal = parse(
        "name = \"P\"\nlens_id = 9\nlenses = [\"DUALF\", \"DUALB\"]\n\
         masks = [[[1800, 900], [1915, 900], [1915, 1020], [1800, 1020]], \
         [[900, 900], [1000, 900], [950, 1000]]]\n",
    )
    .unwrap();
    let found = crate::lens::check::check(cal.find("P").unwrap());
    let said: Vec<_> = found
        .iter()
        .filter(|f| f.what.starts_with("mask"))
        .collect();
    assert_eq!(said.len(), 2, "{found:?}");
    assert!(
        said[0].ok && said[0].what.contains("sees 100%"),
        "{:?}",
        said[0]
    );
    assert!(
        !said[1].ok && said[1].what.contains("sees 0%"),
        "{:?}",
        said[1]
    );
}
