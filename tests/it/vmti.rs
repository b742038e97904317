//! The tracked objects in the KLV (ST 0903 VMTI nested in ST 0601's tag 74), read back by
//! stanag4609, a reader written by others and strict about every field it knows
//! (tests/peers/misb_read.py): each object the view shows with its id, its centre and box in
//! the view's pixels where DigiView's own plan puts it, its score, its class, and its ground
//! point where DETECTED_ROI puts it; an object the view does not show left out.

use crate::common;
use common::klv::{POSITION, metres, misb, pixel};
use common::*;
use digiview::control::detection::{KNOWN, detected_roi};
use digiview::geometry::rotation::direction;
use digiview::plan::FramePlan;
use digiview::state::Tracked;
use digiview::stream::klv::ViewMetadata;

#[test]
fn stanag4609_reads_the_tracked_objects_a_view_shows_where_digiview_puts_them() {
    let lens = small_lens("CIL216");
    let mut state = four_view_state(7);
    state.vehicle.position = POSITION;
    state.vehicle.attitude.yaw = 30.0 * DEG;
    // Camera 1 looks 45° down to the north; two objects in its view, one behind it.
    let object = |id, yaw: f64, pitch: f64, label: &str| Tracked {
        id,
        yaw: yaw * DEG,
        pitch: pitch * DEG,
        size: 4.0 * DEG,
        score: 60 + id as u8,
        label: label.into(),
        ..Tracked::default()
    };
    state.tracked = vec![
        object(3, 10.0, -40.0, "person"),
        object(5, 180.0, -30.0, "person"),
        object(8, -15.0, -55.0, "traffic light"),
    ];
    let (w, h) = (640, 360);
    let plan = FramePlan::single_view(&state, &lens, 1, w, h);
    let frame = (1_764_150_000_000_000, Some((w, h)));
    let m = ViewMetadata::of(
        &plan,
        &plan.views[0],
        &state,
        frame,
        "DigiView cam 1".into(),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("view.klv");
    std::fs::write(&path, m.packet()).unwrap();
    let read = misb(&path);
    assert_eq!(read.len(), 1);
    let p = &read[0];
    eprintln!("{p}");
    assert!(p.get("error").is_none(), "stanag4609 refused it: {p}");
    let vmti = &p["vmti"];
    let fields = &vmti["fields"];
    assert_eq!(fields["frameWidth"], w, "{fields}");
    assert_eq!(fields["frameHeight"], h, "{fields}");
    assert_eq!(fields["totalNumTargetsDetected"], 3, "{fields}");
    assert_eq!(fields["numTargetsReported"], 2, "{fields}");
    let hfov = fields["vmtiHorizontalFov"].as_f64().unwrap();
    assert!((hfov - m.fov.0).abs() < 0.01, "hfov {hfov} for {}", m.fov.0);
    let targets = vmti["targets"].as_array().unwrap();
    let ids: Vec<u64> = targets.iter().map(|t| t["id"].as_u64().unwrap()).collect();
    assert_eq!(ids, [3, 8], "object 5 is behind the view");
    let rois = detected_roi(&state, KNOWN).unwrap();
    let classes = vmti["ontologies"].as_array().unwrap();
    for t in targets {
        let id = t["id"].as_u64().unwrap() as u32;
        let k = state.tracked.iter().position(|o| o.id == id).unwrap();
        let o = &state.tracked[k];
        let (centre, radius) = plan
            .view_circle(&plan.views[0], direction(o.yaw, o.pitch), o.size)
            .unwrap();
        let got = pixel(&t["targetCentroid"], w as u64);
        assert!(
            got.distance(centre) < 1.5,
            "object {id}: centroid {got} for {centre}"
        );
        let (tl, br) = (
            pixel(&t["boundingBoxTopLeft"], w as u64),
            pixel(&t["boundingBoxBottomRight"], w as u64),
        );
        let size = br - tl;
        assert!(
            (size.x - 2.0 * radius).abs() < 2.0 && (size.y - 2.0 * radius).abs() < 2.0,
            "object {id}: box {tl}..{br}, radius {radius:.1}"
        );
        assert_eq!(t["targetConfidenceLevel"], o.score);
        let location = &t["targetLocation"];
        let got = (
            location["lat"].as_f64().unwrap(),
            location["lon"].as_f64().unwrap(),
        );
        let roi = &rois[k];
        let miss = metres(got, (roi.latitude, roi.longitude));
        assert!(miss < 0.1, "object {id}: {miss:.3} m from DETECTED_ROI's");
        assert!((location["hae"].as_f64().unwrap() - roi.altitude).abs() <= 1.0);
        // Its class: the ontology entry its VObject names.
        let class = &t["vObjectSeries"][0]["ontology_id"];
        let entry = classes
            .iter()
            .find(|c| c["id"] == *class)
            .unwrap_or_else(|| panic!("object {id}: no class {class} among {classes:?}"));
        assert_eq!(entry["label"], o.label, "{entry}");
    }
    assert_eq!(
        classes.len(),
        2,
        "one entry per distinct label: {classes:?}"
    );
}
