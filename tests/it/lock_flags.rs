//! Lock flags as a user sees them: with every axis locked a view holds still on the world
//! while the vehicle yaws, pitches and rolls; with none locked it turns with the vehicle.
//!
//! "Turns with the vehicle" is conventions.md's per-axis formula (θ = θc + θv, ...), which is
//! a rigid mount exactly when the camera's own angles are zero, or when the vehicle only yaws;
//! those cases are checked to be rigid to 1e-9 px, and every case against ground truth.

use crate::common;
use common::*;
use digiview::image_ops::psnr;
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::State;
use glam::DVec2;

const ATTITUDES: [(f64, f64, f64); 5] = [
    (0.0, 0.0, 0.0),
    (30.0, 0.0, 0.0),
    (0.0, 15.0, 0.0),
    (0.0, 0.0, -25.0),
    (-40.0, 10.0, 20.0),
];

fn at_attitude(lock: u8, (yaw, pitch, roll): (f64, f64, f64)) -> State {
    let mut s = four_view_state(lock);
    s.vehicle.attitude.yaw = yaw * DEG;
    s.vehicle.attitude.pitch = pitch * DEG;
    s.vehicle.attitude.roll = roll * DEG;
    s
}

#[test]
fn locked_views_hold_their_landmarks_still_while_the_vehicle_yaws_pitches_and_rolls() {
    let (world, lens) = (GridWorld::default(), small_lens("CIL216"));
    let still = at_attitude(7, ATTITUDES[0]);
    let plan0 = FramePlan::new(&still, &lens).unwrap();
    let first = cpu::render(&plan0, &fisheye(&world, &lens, &still), Filter::Mip);
    for attitude in &ATTITUDES[1..] {
        let s = at_attitude(7, *attitude);
        let plan = FramePlan::new(&s, &lens).unwrap();
        let got = cpu::render(&plan, &fisheye(&world, &lens, &s), Filter::Mip);
        let matches = landmark_matches(&plan, &s, &first, &got);
        assert!(
            matches.len() >= 4,
            "{attitude:?}: only {} landmarks to follow",
            matches.len()
        );
        for m in &matches {
            assert!(
                m.error() <= 0.5,
                "attitude {attitude:?}: {} in view {} moved {:.3} px",
                m.name,
                m.view,
                m.error()
            );
        }
    }
}

#[test]
fn unlocked_views_turn_with_the_vehicle_exactly() {
    let (world, lens) = (GridWorld::default(), small_lens("CIL216"));
    let level = at_attitude(0, ATTITUDES[0]);
    let plan0 = FramePlan::new(&level, &lens).unwrap();
    let truth0 = truth(&world, &plan0, &level);
    for attitude in &ATTITUDES[1..] {
        let s = at_attitude(0, *attitude);
        let plan = FramePlan::new(&s, &lens).unwrap();
        // Fixed to the vehicle: every view pixel samples the same fisheye pixel as when level.
        let yaw_only = attitude.1 == 0.0 && attitude.2 == 0.0;
        let rigid = |i: usize| {
            yaw_only || s.settings.cameras[i].euler() == digiview::geometry::Euler::default()
        };
        assert!(rigid(0), "camera 0 looks straight ahead");
        for (i, (v0, v)) in plan0
            .views
            .iter()
            .zip(&plan.views)
            .enumerate()
            .filter(|(i, _)| rigid(*i))
        {
            for p in [
                DVec2::new(10.5, 20.5),
                DVec2::new(120.0, 120.0),
                DVec2::new(200.5, 37.5),
            ] {
                let (a, b) = (plan0.fisheye_pixel(v0, p), plan.fisheye_pixel(v, p));
                assert!(
                    a.zip(b).is_none_or(|(a, b)| (a - b).length() < 1e-9)
                        && a.is_some() == b.is_some(),
                    "{attitude:?}: view {i} pixel {p} moved on the fisheye: {a:?} -> {b:?}"
                );
            }
        }
        // ... so the world turns in the picture, exactly as the truth says.
        let want = truth(&world, &plan, &s);
        let got = cpu::render(&plan, &fisheye(&world, &lens, &s), Filter::Mip);
        let matches = landmark_matches(&plan, &s, &want, &got);
        assert!(!matches.is_empty(), "{attitude:?}: no landmark to follow");
        for m in &matches {
            // 1 px, not issue 2's 0.5: the mip filter's coarse levels shift a small
            // landmark's centroid in strongly minified corners (0.80 px at worst).
            assert!(
                m.error() <= 1.0,
                "{attitude:?}: {} off by {:.3} px",
                m.name,
                m.error()
            );
        }
        let changed = plan
            .views
            .iter()
            .map(|v| psnr(&truth0, &want, v.rect))
            .fold(f64::INFINITY, f64::min);
        assert!(
            changed < 25.0,
            "{attitude:?}: the world did not move in the views (PSNR to level {changed:.1} dB)"
        );
    }
}
