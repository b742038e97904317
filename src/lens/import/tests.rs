use super::*;
use crate::lens::Model;
use crate::lens::models::{DoubleSphere, KannalaBrandt, Ocam};
use std::path::PathBuf;

fn sample(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/import")
        .join(name)
}

fn opts(name: &str) -> ImportOptions<'_> {
    ImportOptions {
        name,
        lens_id: 9,
        fov: None,
        camera: None,
    }
}

/// A malformed copy of a sample: `edit` applied to its text, written to a temp file.
fn broken(name: &str, edit: impl Fn(&str) -> String) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, edit(&std::fs::read_to_string(sample(name)).unwrap())).unwrap();
    (dir, path)
}

fn fails(name: &str, edit: impl Fn(&str) -> String, expect: &str) {
    let (_dir, path) = broken(name, edit);
    let e = import(&path, None, &opts("X")).unwrap_err().to_string();
    assert!(
        e.contains(expect) && e.contains(name),
        "{name}: `{e}` lacks `{expect}`"
    );
}

#[test]
#[allow(clippy::excessive_precision)] // the literals are the sample file's own digits
fn opencv_yaml_and_xml_give_the_same_kannala_brandt_lens() {
    let a = import(&sample("opencv_fisheye.yaml"), None, &opts("A")).unwrap();
    let b = import(&sample("opencv_fisheye.xml"), None, &opts("B")).unwrap();
    assert_eq!(
        a.model,
        Model::KannalaBrandt(KannalaBrandt {
            k: [
                4.1522378546091014e-02,
                -1.2836627398121017e-02,
                2.7391288216843418e-03,
                -4.8121633009153925e-04
            ]
        })
    );
    assert_eq!(a.model, b.model);
    assert_eq!(a.affine, b.affine);
    assert_eq!((a.width, a.height), (1920, 1080));
    assert!((a.affine.offset.x - 962.14504395283496).abs() < 1e-9);
    assert_eq!(a.provenance.rms_px, Some(3.2154879212364563e-01));
    assert!(
        a.fov > 3.0,
        "a 520 px focal length over 1920 px sees past 180°: {}",
        a.fov
    );
}

#[test]
fn ocamcalib_results_keep_both_polynomials_and_the_row_column_centre() {
    let e = import(&sample("calib_results.txt"), None, &opts("O")).unwrap();
    let Model::Ocam(Ocam { pol, invpol }) = &e.model else {
        panic!("{:?}", e.model)
    };
    assert_eq!(pol.len(), 5);
    assert_eq!(invpol.len(), 13);
    // OCam's centre is (row, column): the column is our x.
    assert!(
        (e.affine.offset.x - 961.081376).abs() < 1e-9
            && (e.affine.offset.y - 539.412843).abs() < 1e-9
    );
    assert_eq!((e.width, e.height), (1920, 1080));
    let lens = e.lens();
    let p = lens
        .project(glam::DVec3::new(0.3, -0.2, 0.5).normalize())
        .unwrap();
    let back = lens.project(lens.unproject(p).unwrap()).unwrap();
    assert!((p - back).length() < 1e-6);
}

#[test]
fn gyroflow_profiles_honour_the_asymmetrical_flag() {
    let asym = import(&sample("gyroflow_profile.json"), None, &opts("G")).unwrap();
    assert!(
        (asym.affine.offset.x - 1926.44).abs() < 1e-9,
        "asymmetrical: the stored principal point"
    );
    assert_eq!(asym.provenance.by, "A. Tester");
    let (_d, path) = broken("gyroflow_profile.json", |t| {
        t.replace("\"asymmetrical\": true", "\"asymmetrical\": false")
    });
    let sym = import(&path, None, &opts("G")).unwrap();
    assert_eq!(
        sym.affine.offset,
        glam::DVec2::new(1920.0, 1080.0),
        "symmetrical: the frame centre, as Gyroflow does"
    );
}

#[test]
fn kalibr_camchains_give_kannala_brandt_or_double_sphere_per_camera() {
    let c0 = import(&sample("kalibr_camchain.yaml"), None, &opts("K0")).unwrap();
    assert!(matches!(c0.model, Model::KannalaBrandt(_)));
    let o = ImportOptions {
        camera: Some("cam1"),
        ..opts("K1")
    };
    let c1 = import(&sample("kalibr_camchain.yaml"), None, &o).unwrap();
    assert_eq!(
        c1.model,
        Model::DoubleSphere(DoubleSphere {
            xi: -0.2317,
            alpha: 0.5713
        })
    );
    assert_eq!((c1.width, c1.height), (1280, 960));
}

#[test]
fn malformed_calibrations_are_refused_with_the_file_and_the_reason() {
    fails(
        "opencv_fisheye.yaml",
        |t| t.replace("   data: [ 4.15", "   data: [ 0.0, 4.15"),
        "5 coefficients",
    );
    fails(
        "opencv_fisheye.yaml",
        |t| t.replace("camera_matrix", "camera_matrx"),
        "no camera matrix",
    );
    // A matrix that is there but not numbers is said as such, not as missing.
    fails(
        "opencv_fisheye.yaml",
        |t| t.replace("9.6214504395283496e+02", ".nan"),
        "camera_matrix: `.nan` is not a number",
    );
    fails(
        "opencv_fisheye.xml",
        |t| t.replace("<data>", "<data>nan "),
        "not a finite number",
    );
    fails(
        "opencv_fisheye.yaml",
        |t| t.replace("image_height: 1080", "image_height: [1080"),
        "not valid YAML",
    );
    fails(
        "opencv_fisheye.xml",
        |t| t.replace("</D>", ""),
        "not valid XML",
    );
    fails(
        "opencv_fisheye.xml",
        |t| t.replace("<image_width>1920</image_width>", ""),
        "no image size",
    );
    fails(
        "calib_results.txt",
        |t| t.replace("5 -2.562381e+02", "6 -2.562381e+02"),
        "says 6 coefficients but has 5",
    );
    fails(
        "calib_results.txt",
        |t| t.replace("1.000412 0.000287 -0.000193", "1.000412 x -0.000193"),
        "`x` is not a number",
    );
    fails(
        "gyroflow_profile.json",
        |t| t.replace("\"opencv_fisheye\"", "\"poly5\""),
        "poly5",
    );
    fails(
        "gyroflow_profile.json",
        |t| t.replace("\"calib_dimension\"", "\"calib_dim\""),
        "not a Gyroflow lens profile",
    );
    fails(
        "kalibr_camchain.yaml",
        |t| t.replace("camera_model: pinhole", "camera_model: omni"),
        "omni-equidistant has no DigiView equivalent",
    );
    fails(
        "kalibr_camchain.yaml",
        |t| {
            t.replace(
                "intrinsics: [381.22, 380.97, 639.71, 481.36]",
                "intrinsics: [381.22]",
            )
        },
        "need [fu, fv, pu, pv]",
    );
}
