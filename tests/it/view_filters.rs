//! The views alone drawn the cheaper way (`FramePlan::cheapest_filter`: the bilinear filter
//! from one mip level where every pixel's footprint allows, as the per-view streams are
//! drawn), judged against ground truth from the grid world beside the mip filter, on the GPU
//! (lavapipe) at the footprints a 4K fisheye gives 1280x720 views: the fisheye and the views
//! both at a third of that size.

use crate::common;
use common::gpu::*;
use common::*;
use digiview::frame::PixelFormat;
use digiview::image_ops::psnr;
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::view::Field;

on_each_backend!(views_drawn_from_one_level_match_the_truth_as_well_as_the_mip_filter,);

fn views_drawn_from_one_level_match_the_truth_as_well_as_the_mip_filter(gpu: &Gpu) {
    let lens = small_lens("CIL216");
    let world = GridWorld::default();
    let mut r = renderer_on(gpu, PixelFormat::I420, Filter::Mip);
    let view = r.add_output(PixelFormat::I420, Filter::Mip).unwrap();
    let mut chosen = vec![];
    for (fov, pitch, (w, h)) in [
        (90.0, -30.0, (426, 240)),
        (90.0, -80.0, (426, 240)),
        (60.0, -45.0, (426, 240)),
        (120.0, -45.0, (426, 240)),
        (90.0, -45.0, (240, 136)),
        (150.0, -45.0, (426, 240)),
        (40.0, -60.0, (640, 360)),
    ] {
        let mut state = four_view_state(7);
        let aim = [(Field::Fov, fov * DEG), (Field::Pitch, pitch * DEG)];
        state.settings.cameras[0] = state.settings.cameras[0].clone().with(&aim).unwrap();
        state.vehicle.attitude.roll = 8.0 * DEG;
        let fish = fisheye(&world, &lens, &state);
        let (data, layout) = as_format(&fish, PixelFormat::I420);
        r.render(&data, &layout, &FramePlan::new(&state, &lens).unwrap())
            .unwrap();
        let plan = FramePlan::single_view(&state, &lens, 0, w, h);
        let want = truth(&world, &plan, &state);
        let rect = plan.views[0].rect;
        let mut db = |how: (Filter, u32)| {
            r.set_filter(view, how).unwrap();
            let got = r.redraw(&[(view, &plan)]).unwrap().remove(0).to_rgb();
            psnr(&got, &want, rect)
        };
        let how = plan.cheapest_filter();
        let (mip, cheap) = (db((Filter::Mip, 0)), db(how));
        let cpu_mip = psnr(
            &cpu::render_frame(&plan, &data, &layout, Filter::Mip, PixelFormat::Rgba).unwrap(),
            &want,
            rect,
        );
        eprintln!(
            "fov {fov}° pitch {pitch}° {w}x{h}: footprints {:.2?}, {how:?}: {cheap:.2} dB \
             against the truth; mip {mip:.2} dB (CPU reference {cpu_mip:.2} dB)",
            plan.footprints(&plan.views[0])
        );
        assert!(cheap >= 30.0, "{cheap:.2} dB");
        assert!(
            cheap >= mip - 0.1,
            "{how:?}: {cheap:.2} dB, mip {mip:.2} dB"
        );
        chosen.push(how);
    }
    // A per-view stream's own view (1280x720 at 90°, a third here) from level 0; a smaller
    // one from level 1; the widest ones with the mip filter, as they span several levels.
    assert_eq!(chosen[0], (Filter::Bilinear, 0));
    assert_eq!(chosen[4], (Filter::Bilinear, 1));
    assert_eq!(chosen[5], (Filter::Mip, 0));
}
