//! The tracker against the seed's rules, replaying scripted detections: every score change and
//! every drop, settings changed the way DETECTION's SET changes them (255 keeps a score
//! field, an out-of-range threshold keeps the old one), suppression, association in angles,
//! and the tiles' sorting modes.

use super::angular::{AngularBox, Detection, suppress};
use super::tracker::{Change, MAX_SCORE, Tracker, Why};
use crate::geometry::rotation::direction;
use crate::protocol::params::Detection as DetectionParams;
use crate::state::DetectionSettings;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// A detection at world yaw/pitch (degrees), `size` degrees square.
fn det(yaw: f64, pitch: f64, size: f64, confidence: f64) -> Detection {
    Detection {
        bbox: AngularBox::new(yaw * DEG, pitch * DEG, size * DEG, size * DEG),
        confidence,
        class: 0,
        velocity: None,
    }
}

fn everywhere(_: &AngularBox) -> bool {
    true
}

fn change(id: u32, why: Why, from: u8, to: u8) -> Change {
    Change { id, why, from, to }
}

/// DETECTION's SET applied to the default settings, as the protocol applies it.
fn settings(edit: impl FnOnce(&mut DetectionParams)) -> DetectionSettings {
    let mut settings = DetectionSettings::default();
    let mut p = settings.param();
    edit(&mut p);
    settings.set(&p);
    settings
}

#[test]
fn scores_follow_the_seeds_rules_from_creation_to_drop() {
    let s = DetectionSettings::default();
    let (create, scan_bonus, track_bonus) = (
        s.creation_score_scale,
        s.bonus_detection_scale,
        s.bonus_redetection_scale,
    );
    let (scan_miss, track_miss) = (s.missed_detection_penalty, s.missed_redetection_penalty);
    let mut t = Tracker::new();
    // Created by a scan, at the creation score.
    let c = t.scan(&s, 0.0, vec![det(10.0, -20.0, 4.0, 0.8)], everywhere);
    assert_eq!(c, vec![change(0, Why::Created, 0, create)]);
    // Found again by a scan (moved a little), then by its crop.
    let c = t.scan(&s, 0.5, vec![det(10.5, -20.0, 4.0, 0.8)], everywhere);
    let a = create + scan_bonus;
    assert_eq!(c, vec![change(0, Why::FoundByScan, create, a)]);
    let c = t.track(&s, 0.6, 0, vec![det(10.6, -20.0, 4.0, 0.9)]);
    assert_eq!(c, Some(change(0, Why::FoundByTrack, a, a + track_bonus)));
    let a = a + track_bonus;
    // Missed by its crop, then by a scan that covered it; a scan that did not cover it
    // changes nothing.
    let c = t.track(&s, 0.7, 0, vec![]);
    assert_eq!(c, Some(change(0, Why::MissedByTrack, a, a - track_miss)));
    let a = a - track_miss;
    let c = t.scan(&s, 1.0, vec![], everywhere);
    assert_eq!(c, vec![change(0, Why::MissedByScan, a, a - scan_miss)]);
    let mut a = a - scan_miss;
    assert!(t.scan(&s, 1.5, vec![], |_| false).is_empty());
    assert_eq!(t.get(0).unwrap().score, a);
    // Missed until it is dropped at 0: each step exactly the penalty, the last to 0.
    let mut now = 2.0;
    while a > 0 {
        let c = t.scan(&s, now, vec![], everywhere);
        let to = a.saturating_sub(scan_miss);
        assert_eq!(c, vec![change(0, Why::MissedByScan, a, to)]);
        a = to;
        now += 0.5;
    }
    assert!(t.objects().is_empty() && t.get(0).is_none());
    // A crop for an object that is gone answers nothing.
    assert_eq!(t.track(&s, now, 0, vec![det(10.0, -20.0, 4.0, 0.9)]), None);
    // The next object gets a new id.
    let c = t.scan(&s, now, vec![det(10.0, -20.0, 4.0, 0.8)], everywhere);
    assert_eq!(c, vec![change(1, Why::Created, 0, create)]);
}

#[test]
fn scores_stop_at_254() {
    let s = settings(|p| {
        p.creation_score_scale = 250;
        p.bonus_detection_scale = 3;
        p.bonus_redetection_scale = 254;
    });
    let mut t = Tracker::new();
    t.scan(&s, 0.0, vec![det(0.0, 0.0, 5.0, 0.9)], everywhere);
    let c = t.scan(&s, 1.0, vec![det(0.0, 0.0, 5.0, 0.9)], everywhere);
    assert_eq!(c, vec![change(0, Why::FoundByScan, 250, 253)]);
    let c = t.scan(&s, 2.0, vec![det(0.0, 0.0, 5.0, 0.9)], everywhere);
    assert_eq!(c, vec![change(0, Why::FoundByScan, 253, MAX_SCORE)]);
    let c = t.track(&s, 3.0, 0, vec![det(0.0, 0.0, 5.0, 0.9)]);
    assert_eq!(c, Some(change(0, Why::FoundByTrack, MAX_SCORE, MAX_SCORE)));
}

#[test]
fn a_set_of_255_keeps_a_score_field_and_out_of_range_thresholds_keep_theirs() {
    let before = DetectionSettings::default();
    let s = settings(|p| {
        p.creation_score_scale = 255;
        p.bonus_detection_scale = 255;
        p.bonus_redetection_scale = 255;
        p.missed_detection_penalty = 255;
        p.missed_redetection_penalty = 255;
        p.var_confidence_threshold = 1.5;
        p.crop_confidence_threshold = -0.1;
        p.var_box_overlap = 0.99;
        p.crop_box_overlap = f64::NAN;
    });
    assert_eq!(s, before);
    // And the tracker runs on the kept values: a box at 0.35 is over the kept scan threshold
    // (0.3), not over the crop's (0.5).
    let mut t = Tracker::new();
    let c = t.scan(&s, 0.0, vec![det(30.0, 0.0, 5.0, 0.35)], everywhere);
    assert_eq!(
        c,
        vec![change(0, Why::Created, 0, before.creation_score_scale)]
    );
    let c = t.track(&s, 0.1, 0, vec![det(30.0, 0.0, 5.0, 0.35)]);
    let a = before.creation_score_scale;
    assert_eq!(
        c,
        Some(change(
            0,
            Why::MissedByTrack,
            a,
            a - before.missed_redetection_penalty
        ))
    );
    // Changed values take effect: a new penalty, and a creation score of 0 creates nothing.
    let s = settings(|p| {
        p.missed_redetection_penalty = 200;
        p.creation_score_scale = 0;
    });
    let c = t.track(&s, 0.2, 0, vec![]);
    let a = a - before.missed_redetection_penalty;
    assert_eq!(c, Some(change(0, Why::MissedByTrack, a, 0)));
    assert!(t.objects().is_empty());
    assert!(
        t.scan(&s, 0.3, vec![det(30.0, 0.0, 5.0, 0.9)], everywhere)
            .is_empty()
    );
}

#[test]
fn thresholds_overlap_limits_and_box_limits_decide_what_counts() {
    let s = DetectionSettings::default();
    // Below the scan threshold: nothing.
    let mut t = Tracker::new();
    assert!(
        t.scan(&s, 0.0, vec![det(0.0, 0.0, 5.0, 0.29)], everywhere)
            .is_empty()
    );
    // Two boxes overlapping by more than var_box_overlap are one object (the surer box);
    // by less, two.
    let a = det(0.0, 0.0, 10.0, 0.6);
    let (near, far) = (det(1.0, 0.0, 10.0, 0.9), det(5.0, 0.0, 10.0, 0.9));
    assert!(a.bbox.overlap(&near.bbox) > 0.5 && a.bbox.overlap(&far.bbox) < 0.5);
    let c = t.scan(&s, 0.0, vec![a, near], everywhere);
    assert_eq!(c.len(), 1);
    assert_eq!(t.objects()[0].confidence, 0.9);
    let mut t = Tracker::new();
    assert_eq!(t.scan(&s, 0.0, vec![a, far], everywhere).len(), 2);
    // var_box_limit (clamped by SET to 10..=500) keeps only the surest boxes.
    let s = settings(|p| p.var_box_limit = 3);
    assert_eq!(s.var_box_limit, 10);
    let many: Vec<Detection> = (0..15)
        .map(|i| det(i as f64 * 20.0, 0.0, 5.0, 0.4 + 0.01 * i as f64))
        .collect();
    let mut t = Tracker::new();
    assert_eq!(t.scan(&s, 0.0, many.clone(), everywhere).len(), 10);
    assert!(t.objects().iter().all(|o| o.confidence >= 0.45 - 1e-9));
    assert_eq!(suppress(many, 0.3, 0.5, 500).len(), 15);
}

/// Matching is by angle on the sphere: near the nadir a small step can change yaw by half a
/// turn and still be the same object; a box far away of the same size is another.
#[test]
fn association_is_in_angles_not_yaw_and_pitch_numbers() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    t.scan(&s, 0.0, vec![det(10.0, -89.0, 3.0, 0.8)], everywhere);
    let c = t.scan(&s, 0.5, vec![det(185.0, -89.2, 3.0, 0.8)], everywhere);
    assert_eq!(c, vec![change(0, Why::FoundByScan, 50, 60)]);
    let c = t.scan(&s, 1.0, vec![det(185.0, -70.0, 3.0, 0.8)], everywhere);
    assert_eq!(
        c,
        vec![
            change(0, Why::MissedByScan, 60, 50),
            change(1, Why::Created, 0, 50)
        ]
    );
}

#[test]
fn sorting_mode_2_keeps_an_object_in_its_tile_and_modes_0_and_1_re_sort() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    // Object 0 (older), then object 1 found again twice: 1 outscores 0.
    t.scan(&s, 0.0, vec![det(0.0, 0.0, 5.0, 0.8)], everywhere);
    t.scan(
        &s,
        1.0,
        vec![det(0.0, 0.0, 5.0, 0.8), det(90.0, 0.0, 5.0, 0.8)],
        everywhere,
    );
    assert_eq!(t.tiles(2, 1), vec![Some(0)]);
    for now in [2.0, 3.0, 4.0] {
        t.track(&s, now, 1, vec![det(90.0, 0.0, 5.0, 0.9)]);
    }
    assert!(t.get(1).unwrap().score > t.get(0).unwrap().score);
    // Mode 2: the higher score does not take the tile.
    assert_eq!(t.tiles(2, 1), vec![Some(0)]);
    assert_eq!(t.tiles(2, 2), vec![Some(0), Some(1)]);
    // Mode 0 re-sorts by score; mode 1 by age, oldest first.
    assert_eq!(t.tiles(0, 2), vec![Some(1), Some(0)]);
    assert_eq!(t.tiles(1, 2), vec![Some(0), Some(1)]);
    assert_eq!(t.tiles(0, 1), vec![Some(1)]);
    // Mode 2 from here: object 1 holds tile 0 until it is dropped, then the best other.
    assert_eq!(t.tiles(2, 1), vec![Some(1)]);
    let s = settings(|p| p.missed_redetection_penalty = 254);
    t.track(&s, 5.0, 1, vec![]);
    assert!(t.get(1).is_none());
    assert_eq!(t.tiles(2, 1), vec![Some(0)]);
    assert_eq!(t.tiles(2, 3), vec![Some(0)]);
}

/// An object moving steadily, almost its size between scans, that one scan misses, is found
/// again two steps (more than its size) from where it was last seen: each scan looks for it
/// where its motion takes it.
#[test]
fn a_moving_object_is_looked_for_where_it_is_going() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    let at = |k: usize| det(10.0 + 3.5 * k as f64, -30.0, 4.0, 0.8);
    for k in 0..6 {
        let found = if k == 3 { vec![] } else { vec![at(k)] };
        let c = t.scan(&s, k as f64 * 0.5, found, everywhere);
        let why = match k {
            0 => Why::Created,
            3 => Why::MissedByScan,
            _ => Why::FoundByScan,
        };
        assert_eq!(c.len(), 1, "scan {k}: {c:?}");
        assert_eq!((c[0].id, c[0].why), (0, why), "scan {k}");
    }
    // Between scans it is expected further on.
    let o = t.get(0).unwrap();
    let (yaw, _) = o.at(o.seen + 0.5).yaw_pitch();
    assert!(
        (yaw / DEG - (10.0 + 3.5 * 6.0)).abs() < 0.5,
        "{}",
        yaw / DEG
    );
}

/// A detector that measures a thing's velocity gives a new object its motion at once: the
/// frames after its first scan look for it where it is going, not where it was.
#[test]
fn a_new_object_moves_on_at_the_velocity_its_detector_measured() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    let first = det(10.0, -30.0, 4.0, 0.8);
    let velocity = direction(12.0 * DEG, -30.0 * DEG) - first.bbox.centre;
    let moving = Detection {
        velocity: Some(velocity),
        ..first
    };
    t.scan(&s, 0.0, vec![moving], everywhere);
    let (yaw, _) = t.get(0).unwrap().at(0.5).yaw_pitch();
    assert!((yaw / DEG - 11.0).abs() < 0.1, "{}", yaw / DEG);
    // Without one it waits for a second sighting.
    let mut t = Tracker::new();
    t.scan(&s, 0.0, vec![first], everywhere);
    let (yaw, _) = t.get(0).unwrap().at(0.5).yaw_pitch();
    assert!((yaw / DEG - 10.0).abs() < 1e-9, "{}", yaw / DEG);
}

/// An object lost for two scans (two things crossing) and found again 9° on, further than
/// its size and its motion's prediction would reach, keeps its identity and score rather
/// than leaving a stale object beside a new one; a box beyond what 5°/s could reach in that
/// time is a new object, and one of another class is too.
#[test]
fn an_object_found_late_and_far_keeps_its_identity_and_a_box_beyond_reach_is_new() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    t.scan(&s, 0.0, vec![det(10.0, 0.0, 3.0, 0.8)], everywhere);
    t.scan(&s, 0.5, vec![det(10.0, 0.0, 3.0, 0.8)], everywhere);
    t.scan(&s, 1.0, vec![], everywhere);
    t.scan(&s, 1.5, vec![], everywhere);
    // 1.5 s since it was seen: 3° + 5°/s × 1.5 s = 10.5° of reach.
    let c = t.scan(&s, 2.0, vec![det(19.0, 0.0, 3.0, 0.8)], everywhere);
    assert_eq!(c, vec![change(0, Why::FoundByScan, 40, 50)]);
    assert_eq!(t.objects().len(), 1);

    let mut far = Tracker::new();
    far.scan(&s, 0.0, vec![det(10.0, 0.0, 3.0, 0.8)], everywhere);
    let c = far.scan(&s, 0.5, vec![det(17.0, 0.0, 3.0, 0.8)], everywhere);
    assert_eq!(
        c,
        vec![
            change(0, Why::MissedByScan, 50, 40),
            change(1, Why::Created, 0, 50)
        ]
    );
    let mut other = Tracker::new();
    other.scan(&s, 0.0, vec![det(10.0, 0.0, 3.0, 0.8)], everywhere);
    let cat = Detection {
        class: 15,
        ..det(14.0, 0.0, 3.0, 0.8)
    };
    let c = other.scan(&s, 0.5, vec![cat], everywhere);
    assert_eq!(c[1], change(1, Why::Created, 0, 50));
}

/// Boxes on the sphere: the gap between two boxes side by side, and the box enclosing them.
#[test]
fn boxes_have_a_gap_and_a_union_in_angles() {
    let a = AngularBox::new(0.0, 0.0, 4.0 * DEG, 2.0 * DEG);
    let b = AngularBox::new(5.0 * DEG, 0.0, 4.0 * DEG, 2.0 * DEG);
    assert!((a.gap(&b) / DEG - 1.0).abs() < 0.01, "{}", a.gap(&b) / DEG);
    assert_eq!(a.gap(&a), 0.0);
    let u = a.union(&b);
    let (yaw, pitch) = u.yaw_pitch();
    assert!((yaw / DEG - 2.5).abs() < 0.01 && pitch.abs() < 1e-9);
    assert!((u.width / DEG - 9.0).abs() < 0.02 && (u.height / DEG - 2.0).abs() < 0.01);
}

/// A published object, as each frame aims its tile: moved on by its velocity to the frame's
/// capture time, 2 s from its last sighting at most, back for a frame captured before it.
#[test]
fn a_frame_shows_an_object_where_it_has_got_to() {
    let o = crate::state::Tracked {
        yaw: 10.0 * DEG,
        pitch: 0.0,
        // 4°/s along the horizon, seen at 5 s.
        velocity: [
            -4.0 * DEG * (10.0 * DEG).sin(),
            4.0 * DEG * (10.0 * DEG).cos(),
            0.0,
        ],
        seen_us: 5_000_000,
        ..Default::default()
    };
    let yaw_at = |t: f64| o.at((t * 1e6) as u64).yaw / DEG;
    assert!((yaw_at(5.5) - 12.0).abs() < 0.05, "{}", yaw_at(5.5));
    assert!((yaw_at(9.0) - 18.0).abs() < 0.2, "{}", yaw_at(9.0));
    assert!((yaw_at(4.5) - 8.0).abs() < 0.05, "{}", yaw_at(4.5));
    assert!((yaw_at(1.0) - 2.0).abs() < 0.2, "{}", yaw_at(1.0));
    assert_eq!(yaw_at(5.0), 10.0);
}

#[test]
fn a_crop_finds_only_its_own_object_not_another_thing_beside_it() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    t.scan(&s, 0.0, vec![det(10.0, -20.0, 4.0, 0.8)], everywhere);
    // A dog where the person is expected: the person's crop missed it.
    let dog = Detection {
        class: 16,
        ..det(10.2, -20.0, 4.0, 0.9)
    };
    let c = t.track(&s, 0.1, 0, vec![dog]);
    let (create, miss) = (s.creation_score_scale, s.missed_redetection_penalty);
    assert_eq!(
        c,
        Some(change(0, Why::MissedByTrack, create, create - miss))
    );
    assert_eq!(
        t.get(0).unwrap().class,
        0,
        "the object took the dog's class"
    );
    assert_eq!(
        t.get(0).unwrap().bbox.centre,
        det(10.0, -20.0, 4.0, 0.8).bbox.centre
    );
}

/// A click lands on an object anywhere on its way since its last sighting: an operator's
/// picture lags, and a scan starved of CPU time leaves the object's last box and its
/// prediction far apart.
#[test]
fn a_click_finds_an_object_where_it_was_on_its_way_since_it_was_seen() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    // 4°/s east, last seen at t = 1 s at yaw 14°.
    t.scan(&s, 0.0, vec![det(10.0, -30.0, 4.0, 0.8)], everywhere);
    t.scan(&s, 1.0, vec![det(14.0, -30.0, 4.0, 0.8)], everywhere);
    let o = t.get(0).unwrap();
    let click = |yaw: f64| AngularBox::new(yaw * DEG, -30.0 * DEG, 1.0 * DEG, 1.0 * DEG);
    // At t = 2.5 s it should be at 20°: a click at 17° (where it was at 1.75 s) is 0° from
    // its way, though 3° from where it should be now and from where it was seen.
    let on_the_way = o.nearest_since_seen(2.5, &click(17.0)) / DEG;
    assert!(on_the_way < 0.3, "{on_the_way}");
    assert!(o.at(2.5).angle_to(&click(17.0)) / DEG > 2.5);
    // Behind its last sighting or past where it should be now is as far as the nearer end.
    let behind = o.nearest_since_seen(2.5, &click(11.0)) / DEG;
    let ahead = o.nearest_since_seen(2.5, &click(23.0)) / DEG;
    assert!(
        (2.5..3.0).contains(&behind) && (2.5..3.0).contains(&ahead),
        "{behind} {ahead}"
    );
}

/// Two movers crossing, seen as one blob for two scans: the one the blob is taken as keeps
/// going where it went (not to the blob's middle, nor with the jump as its velocity), and
/// each is found again on its own way after.
#[test]
fn a_blob_of_two_crossing_objects_moves_neither() {
    let s = DetectionSettings::default();
    let mut t = Tracker::new();
    // One going east along pitch -30°, one going west along pitch -33°, 3° across, 6°/s.
    let east = |k: f64| det(10.0 + 2.0 * k, -30.0, 3.0, 0.8);
    let west = |k: f64| det(30.0 - 2.0 * k, -33.0, 3.0, 0.8);
    for k in 0..4 {
        t.scan(
            &s,
            k as f64 / 3.0,
            vec![east(k as f64), west(k as f64)],
            everywhere,
        );
    }
    // Scans 4 and 5: one box 8° wide over both, centred between them.
    for k in [4.0, 5.0] {
        let blob = det(20.0, -31.5, 8.0, 0.8);
        t.scan(&s, k / 3.0, vec![blob], everywhere);
    }
    for id in [0, 1] {
        let o = t.get(id).unwrap();
        let (yaw, _) = o.at(5.0 / 3.0).yaw_pitch();
        let (want, _) = if id == 0 { east(5.0) } else { west(5.0) }.bbox.yaw_pitch();
        assert!(
            (yaw - want).abs() / DEG < 0.5 && o.bbox.size() / DEG < 4.0,
            "object {id} at yaw {:.2}°, {:.2}° across; it is at {:.2}°",
            yaw / DEG,
            o.bbox.size() / DEG,
            want / DEG
        );
    }
    // Apart again, each is found on its own way.
    let c = t.scan(&s, 2.0, vec![east(6.0), west(6.0)], everywhere);
    assert!(
        c.iter().all(|c| c.why == Why::FoundByScan) && c.len() == 2,
        "{c:?}"
    );
    let yaw = |id| t.get(id).unwrap().bbox.yaw_pitch().0 / DEG;
    assert!((yaw(0) - 22.0).abs() < 0.1 && (yaw(1) - 18.0).abs() < 0.1);
}
