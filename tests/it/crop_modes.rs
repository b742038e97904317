//! The CPU reference over every layout mode and crop mode, with detection tiles: each view
//! and tile matches ground truth, an unknown crop mode is black, and nothing is drawn outside
//! the layout's rectangles.

use crate::common;
use common::*;
use digiview::geometry::Projection;
use digiview::image_ops::{pixel, psnr};
use digiview::modes::{LayoutMode, OverlayMode};
use digiview::plan::{Filter, FramePlan, ViewMap};
use digiview::render::cpu;
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::State;
use digiview::state::view::Field;

#[test]
fn every_layout_and_crop_mode_matches_ground_truth() {
    let (world, lens) = (GridWorld::default(), small_lens("CIL018"));
    let mut state = four_view_state(7);
    state.settings.output.overlay = OverlayMode::Right;
    state.vehicle.attitude.roll = 10.0 * DEG;
    state.tracked = three_tracked();
    let fish = fisheye(&world, &lens, &state);
    for &layout in LayoutMode::ALL {
        for rotate in 0..4usize {
            let mut s = state.clone();
            s.settings.output.layout = layout;
            for (i, cam) in s.settings.cameras.iter_mut().enumerate() {
                let crop = [0, 1, 2, 4][(i + rotate) % 4];
                let fov = if crop == 2 { 200.0 } else { 80.0 } * DEG;
                cam.put(Field::Crop, crop as f64).unwrap();
                cam.put(Field::Fov, fov).unwrap();
            }
            let plan = FramePlan::new(&s, &lens).unwrap();
            let (got, want) = (
                cpu::render(&plan, &fish, Filter::Mip),
                truth(&world, &plan, &s),
            );
            for (i, v) in plan.views.iter().enumerate() {
                let db = psnr(&got, &want, v.rect);
                // 29 dB, not issue 2's 32: the isotropic mip filter blurs minified views more
                // than n x n supersampling did, most of all a 200° panorama squeezed into a
                // 173 px square (29.8 dB), whose footprint is far from square.
                assert!(
                    db >= 29.0,
                    "layout {layout} rotate {rotate} view/tile {i} ({:?}): {db:.1} dB",
                    v.map
                );
            }
            assert_eq!(
                plan.views.len(),
                plan.layout.views.len() + 3,
                "three tiles for three tracked objects"
            );
            // Outside every rectangle the frame is black.
            for y in (0..480).step_by(7) {
                for x in (0..640).step_by(7) {
                    if !plan.views.iter().any(|v| v.rect.contains(x, y)) {
                        assert_eq!(
                            pixel(&got, x, y),
                            glam::DVec3::ZERO,
                            "({x}, {y}) outside the views"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn an_unknown_crop_mode_renders_its_view_black() {
    let lens = small_lens("CIL216");
    let mut s: State = four_view_state(7);
    s.settings.cameras[1].put(Field::Crop, 9.0).unwrap();
    let fish = fisheye(&GridWorld::default(), &lens, &s);
    let plan = FramePlan::new(&s, &lens).unwrap();
    let got = cpu::render(&plan, &fish, Filter::Mip);
    let r = plan.views[1].rect;
    assert!(
        (r.y..r.bottom()).all(|y| (r.x..r.right()).all(|x| pixel(&got, x, y) == glam::DVec3::ZERO))
    );
    let r0 = plan.views[0].rect;
    assert!(
        (r0.y..r0.bottom()).any(|y| pixel(&got, r0.x + 5, y) != glam::DVec3::ZERO),
        "the other views are drawn"
    );
}

/// Where the page rings a tracked object: the point a world ray shows at in each view, for
/// every layout and crop mode, draws that ray (and is the point it came from, to a thousandth
/// of a pixel, but in a panorama, which draws some rays twice), and a ray a view does not show
/// is found in none.
#[test]
fn view_point_inverts_world_ray_in_every_crop_mode() {
    let lens = small_lens("CIL018");
    let mut state = four_view_state(7);
    state.vehicle.attitude.roll = 10.0 * DEG;
    for &layout in LayoutMode::ALL {
        let mut s = state.clone();
        s.settings.output.layout = layout;
        for (i, cam) in s.settings.cameras.iter_mut().enumerate() {
            let crop = [0, 1, 2, 4][(i + layout.code() as usize) % 4];
            let fov = if crop == 2 { 200.0 } else { 80.0 } * DEG;
            let aim = [
                (Field::Yaw, i as f64 * 90.0 * DEG),
                (Field::Pitch, -50.0 * DEG),
            ];
            *cam = cam.clone().with(&aim).unwrap();
            cam.put(Field::Crop, crop as f64).unwrap();
            cam.put(Field::Fov, fov).unwrap();
        }
        let plan = FramePlan::new(&s, &lens).unwrap();
        let mut checked = 0;
        for (i, view) in plan.views.iter().enumerate() {
            let (w, h) = (view.rect.w as f64, view.rect.h as f64);
            for (fx, fy) in [(0.5, 0.5), (0.1, 0.2), (0.85, 0.7), (0.3, 0.95)] {
                let p = glam::DVec2::new(w * fx, h * fy);
                let Some(ray) = plan.world_ray(view, p) else {
                    continue;
                };
                let back = plan.view_point(view, ray).unwrap_or_else(|| {
                    panic!(
                        "layout {layout} view {i} ({:?}): {p} not found back",
                        view.map
                    )
                });
                // The panorama draws the rays past the nadir twice and the nadir along a
                // whole row, so the point found is one drawing that ray, not always p.
                let again = plan
                    .world_ray(view, back)
                    .expect("the point found shows a ray");
                let panorama = matches!(view.map, ViewMap::Rays { projection, .. }
                    if matches!(projection, Projection::Panorama { .. }));
                assert!(
                    again.angle_between(ray) < 1e-6 && (panorama || back.distance(p) < 1e-3),
                    "layout {layout} view {i} ({:?}): {p} came back at {back}",
                    view.map
                );
                checked += 1;
            }
            // Straight up: above the lens's view from a camera looking down.
            assert_eq!(
                plan.view_point(view, glam::DVec3::new(0.0, 0.0, -1.0)),
                None
            );
        }
        assert!(
            checked >= plan.views.len() * 2,
            "layout {layout}: {checked} points"
        );
    }
}
