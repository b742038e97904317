//! The GPU renderer as a stream of frames, on lavapipe (or whatever adapter the machine has;
//! none is a failure): frames pushed through the ring come back in order, a frame of the wrong
//! size is refused and the stream goes on, tiny and odd-sized frames, mip levels made by
//! passes (reading uploads in place or a copy) or on the host render alike, new view kinds and
//! lens models are drawn at once by generic pipelines, and how far the draw's parabolas
//! between projected pixels stray from the projection.
//!
//! Tolerances as in tests/it/gpu_render.rs: GPU vs CPU reference PSNR ≥ 45 dB per frame.

use crate::common;
use common::gpu::*;
use common::*;
use digiview::frame::{PixelFormat, PlaneLayout};
use digiview::image_ops::psnr;
use digiview::lens::Lens;
use digiview::lens::samples::sample_lenses;
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::render::gpu::renderer::render_image;
use digiview::render::gpu::{Gpu, Renderer};
use digiview::scene::GridWorld;
use digiview::scene::synth::fisheye;
use digiview::state::State;
use digiview::state::view::Field;
use glam::DVec2;
use image::RgbImage;

on_each_backend!(tiny_and_odd_sized_frames_render_as_the_cpu_does_and_too_small_ones_are_refused,);

/// Where pixel `k` of an 8-pixel run lies on the parabola through the run's columns 0, 4 and
/// 7 (`a`, `b`, `c`): shaders/render.wgsl's `through`.
fn on_parabola(a: DVec2, b: DVec2, c: DVec2, k: f64) -> DVec2 {
    a * ((k - 4.0) * (k - 7.0) / 28.0) + b * (k * (k - 7.0) / -12.0) + c * (k * (k - 4.0) / 21.0)
}

/// Of the 8-pixel runs of `plan`'s views that the draw pass gives to one view, those it puts
/// on parabolas (shaders/render.wgsl, `run_of`: columns 0, 2, 4 and 7 imaged, column 2 within
/// RUN_TOLERANCE of the parabola through the others), and the farthest that one of their
/// pixels lands from where it projects (f64).
fn parabola_runs(plan: &FramePlan) -> (usize, usize, f64) {
    const RUN_TOLERANCE: f64 = 0.005;
    let (mut all, mut fitted, mut worst) = (0, 0, 0.0f64);
    for view in &plan.views {
        let r = view.rect;
        for y in r.y..r.bottom() {
            // Blocks are 8 columns from a multiple of 8.
            for bx in (r.x.next_multiple_of(8)..r.right().saturating_sub(7)).step_by(8) {
                all += 1;
                let p = DVec2::new((bx - r.x) as f64 + 0.5, (y - r.y) as f64 + 0.5);
                let at = |k: f64| plan.fisheye_pixel(view, p + DVec2::new(k, 0.0));
                let (Some(a), Some(d), Some(b), Some(c)) = (at(0.0), at(2.0), at(4.0), at(7.0))
                else {
                    continue;
                };
                if (on_parabola(a, b, c, 2.0) - d).length() > RUN_TOLERANCE {
                    continue;
                }
                fitted += 1;
                for k in [1.0, 3.0, 5.0, 6.0] {
                    // The draw counts such a pixel imaged: it must be.
                    let exact = at(k).unwrap_or(DVec2::INFINITY);
                    worst = worst.max((on_parabola(a, b, c, k) - exact).length());
                }
            }
        }
    }
    (all, fitted, worst)
}

/// Every lens model, crop mode and a spread of fields of view, at a small output (more bend
/// per run than at 1080p): no pixel the draw pass puts on a parabola lands as much as a
/// hundredth of a fisheye pixel from where it projects; and in a frame like the benchmark's
/// most runs are put on parabolas.
#[test]
fn pixels_put_on_parabolas_land_within_a_hundredth_of_a_pixel_of_their_projection() {
    let mut lenses = sample_lenses();
    lenses.extend(["CIL216", "CIL018", "LN007"].map(|n| lens_cal().find(n).unwrap().lens()));
    let mut worst = (0.0f64, String::new());
    let (mut runs, mut fitted) = (0, 0);
    for lens in &lenses {
        for crop in [1, 2, 4] {
            for fov in [30.0, 90.0, 120.0, 170.0, 300.0] {
                let mut state = base_state();
                (state.settings.output.width, state.settings.output.height) = (640, 360);
                for cam in &mut state.settings.cameras {
                    cam.put(Field::Crop, crop as f64).unwrap();
                    cam.put(Field::Fov, fov * DEG).unwrap();
                }
                let (n, f, w) = parabola_runs(&FramePlan::new(&state, lens).unwrap());
                (runs, fitted) = (runs + n, fitted + f);
                if w > worst.0 {
                    worst = (w, format!("{}, crop {crop}, fov {fov}", lens.name));
                }
            }
        }
    }
    eprintln!(
        "{fitted} of {runs} runs on parabolas: worst {:.5} px ({})",
        worst.0, worst.1
    );
    assert!(fitted > 1_000_000, "only {fitted} runs on parabolas");
    assert!(worst.0 < 0.01, "{:.4} px off ({})", worst.0, worst.1);
    // A frame like the benchmark's: 1920x1080, four 540x540 views of 90° and tiles, CIL216
    // at 4K.
    let mut state = base_state();
    (state.settings.output.width, state.settings.output.height) = (1920, 1080);
    let lens = lens_cal().find("CIL216").unwrap().lens();
    let (n, f, w) = parabola_runs(&FramePlan::new(&state, &lens).unwrap());
    eprintln!("a 1080p frame of four views: {f} of {n} runs on parabolas, worst {w:.5} px");
    assert!(f * 2 > n && w < 0.01, "{f} of {n} runs, worst {w:.4} px");
}

#[test]
fn pushed_frames_come_back_in_order_each_as_rendered_alone() {
    let lens = small_lens("LN007");
    let world = GridWorld::default();
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    let mut alone = renderer(PixelFormat::I420, Filter::Mip);
    let mut returned = vec![];
    let mut expected = vec![];
    for i in 0..5 {
        let mut state = base_state();
        state.vehicle.attitude.yaw = (20.0 * i as f64) * DEG;
        // The output size changes mid-stream; the renderer follows it.
        if i >= 3 {
            (state.settings.output.width, state.settings.output.height) = (400, 240);
        }
        let fish = fisheye(&world, &lens, &state);
        let (data, layout) = as_format(&fish, PixelFormat::Nv12);
        let plan = FramePlan::new(&state, &lens).unwrap();
        expected.push(alone.render(&data, &layout, &plan).unwrap());
        returned.extend(r.push(&data, &layout, &plan).unwrap());
    }
    returned.extend(r.flush().unwrap());
    assert!(r.flush().unwrap().is_none());
    assert_eq!(returned.len(), 5);
    for (i, (got, want)) in returned.iter().zip(&expected).enumerate() {
        assert_eq!(got.id, i as u64);
        assert_eq!(got.layout, want.layout, "frame {i}");
        assert!(
            got.data == want.data,
            "frame {i} differs from rendering it alone"
        );
    }
    assert_eq!(returned[4].layout.width, 400);
}

#[test]
fn a_frame_of_the_wrong_size_is_refused_and_the_renderer_goes_on() {
    let lens = small_lens("CIL216");
    let state = base_state();
    let plan = FramePlan::new(&state, &lens).unwrap();
    let mut r = renderer(PixelFormat::Rgba, Filter::Mip);
    let layout = PlaneLayout::tight(PixelFormat::Nv12, 1280, 720).unwrap();
    let err = r.render(&[0; 100], &layout, &plan).unwrap_err();
    assert!(err.to_string().contains("bytes"), "{err}");
    let other = PlaneLayout::tight(PixelFormat::Nv12, 640, 360).unwrap();
    let err = r
        .render(&vec![0; other.size as usize], &other, &plan)
        .unwrap_err();
    assert!(err.to_string().contains("1280x720"), "{err}");
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let ok = render_image(&mut r, &fish, &plan).unwrap();
    assert_eq!(ok.layout.width, 480);
}

fn tiny_and_odd_sized_frames_render_as_the_cpu_does_and_too_small_ones_are_refused(gpu: &Gpu) {
    // Frames smaller than one ingest block (16x4) and RGBA with odd sizes: every plane and
    // level still lands where the CPU reference puts it.
    let state = base_state();
    let world = GridWorld::default();
    let mut r = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    for (format, w, h) in [
        (PixelFormat::Rgba, 5, 5),
        (PixelFormat::Rgba, 37, 21),
        (PixelFormat::Nv12, 4, 4),
        (PixelFormat::I420, 6, 4),
        (PixelFormat::I420, 34, 18),
    ] {
        let lens = small_lens("CIL216").for_frame(w, h, None);
        let plan = FramePlan::new(&state, &lens).unwrap();
        let (data, layout) = as_format(&fisheye(&world, &lens, &state), format);
        let got = r.render(&data, &layout, &plan).unwrap().to_rgb();
        let want =
            cpu::render_frame(&plan, &data, &layout, Filter::Mip, PixelFormat::Rgba).unwrap();
        let db = psnr(&got, &want, whole(&got));
        assert!(db >= 45.0, "{w}x{h} {format}: {db:.2} dB vs the CPU");
    }
    let lens = small_lens("CIL216").for_frame(2, 2, None);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let layout = PlaneLayout::tight(PixelFormat::I420, 2, 2).unwrap();
    let err = r.render(&[16; 6], &layout, &plan).unwrap_err();
    assert!(err.to_string().contains("at least 4x4"), "{err}");
}

#[test]
fn mip_levels_made_in_place_from_a_copy_or_on_the_host_render_alike() {
    // The mip filter's levels: made by the ingest and mip passes, which read the upload
    // buffer itself where the device shares host memory (lavapipe, integrated GPUs) and a
    // copy of it on a discrete GPU; or made on the host as the frame is uploaded (the
    // default on software rasterizers). All three paths, here on one device, at a size
    // whose imaged box ends off the ingest's 16x4 blocks.
    let shared = gpu();
    assert!(
        shared.shared_memory || !shared.is_software(),
        "lavapipe reads uploads in place"
    );
    let mut copied = shared.clone();
    copied.shared_memory = false;
    let state = base_state();
    let lens = small_lens("CIL216").for_frame(1002, 566, None);
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let on_gpu = |gpu: &Gpu| {
        let mut r = Renderer::new(gpu, PixelFormat::I420, Filter::Mip).unwrap();
        r.make_levels_on_host(false);
        r
    };
    for format in [PixelFormat::Rgba, PixelFormat::Nv12, PixelFormat::I420] {
        let (data, layout) = as_format(&fish, format);
        let mut host = Renderer::new(&shared, PixelFormat::I420, Filter::Mip).unwrap();
        host.make_levels_on_host(true);
        let [in_place, copy, host] = [on_gpu(&shared), on_gpu(&copied), host]
            .map(|mut r| r.render(&data, &layout, &plan).unwrap());
        assert!(
            in_place.data == copy.data,
            "{format}: in place and copied differ"
        );
        assert!(
            in_place.data == host.data,
            "{format}: GPU and host levels differ"
        );
        // And the picture is there, not black.
        let rgb = copy.to_rgb();
        let black = RgbImage::new(rgb.width(), rgb.height());
        assert!(
            psnr(&rgb, &black, whole(&rgb)) < 20.0,
            "{format}: a black frame"
        );
    }
}

/// A lens of lens.cal (at 1280x720) and what it sees of the grid world from `state`.
fn seen(name: &str, state: &State) -> (Lens, RgbImage) {
    let lens = small_lens(name);
    let fish = fisheye(&GridWorld::default(), &lens, state);
    (lens, fish)
}

/// `state` drawn by `r` from what a lens sees.
fn draw(r: &mut Renderer, (lens, fish): &(Lens, RgbImage), state: &State) -> RgbImage {
    let plan = FramePlan::new(state, lens).unwrap();
    render_image(r, fish, &plan).unwrap().to_rgb()
}

/// What pipelines made for the state's kinds and the lens draw: a fresh renderer's first
/// frame.
fn alone(seen: &(Lens, RgbImage), state: &State) -> RgbImage {
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    let img = draw(&mut r, seen, state);
    assert!(r.drew_specialised());
    img
}

#[test]
fn new_view_kinds_and_lens_models_are_drawn_at_once_by_generic_pipelines_alike() {
    // Switching a view to a panorama or the debug view mid-stream must not wait for a
    // pipeline build (lavapipe compiles one in 1.2 s, cold): the generic draw pipelines draw
    // those kinds at once. Specialised ones, built on another thread on a GPU (forced on here
    // so that path runs too), take over once ready, and the picture does not change.
    let rectilinear = base_state();
    let mut mixed = rectilinear.clone();
    mixed.settings.cameras[1].put(Field::Crop, 2.0).unwrap();
    mixed.settings.cameras[2].put(Field::Crop, 4.0).unwrap();
    let mut panorama = rectilinear.clone();
    panorama.settings.cameras[3].put(Field::Crop, 2.0).unwrap();
    let cil = seen("CIL216", &rectilinear);
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    draw(&mut r, &cil, &rectilinear);
    assert!(
        r.drew_specialised(),
        "the first frame's kinds are built for"
    );
    let generic = draw(&mut r, &cil, &mixed);
    assert!(
        !r.drew_specialised(),
        "new kinds are drawn generically first"
    );
    let db = psnr(&generic, &alone(&cil, &mixed), whole(&generic));
    eprintln!("generic vs specialised pipelines: {db:.1} dB");
    assert!(db >= 60.0, "generic vs specialised pipelines: {db:.1} dB");
    // Back to kinds already built for: specialised again.
    draw(&mut r, &cil, &rectilinear);
    assert!(r.drew_specialised());

    // The GPU's path: built on another thread, then used.
    r.build_in_background(true);
    let first = draw(&mut r, &cil, &panorama);
    assert!(!r.drew_specialised());
    r.wait_for_builds();
    let later = draw(&mut r, &cil, &panorama);
    assert!(r.drew_specialised(), "the built pipelines take over");
    let db = psnr(&later, &first, whole(&later));
    assert!(
        db >= 60.0,
        "the picture changed as the pipelines did: {db:.1} dB"
    );
    let db = psnr(&later, &alone(&cil, &panorama), whole(&later));
    assert!(db >= 60.0, "background-built vs built first: {db:.1} dB");

    // A lens of another model mid-stream: drawn by the generic pipelines for that model (one
    // pair to build instead of two), then by specialised ones.
    let kb = seen("LN007", &rectilinear);
    let first = draw(&mut r, &kb, &rectilinear);
    assert!(
        !r.drew_specialised(),
        "a new lens model is drawn generically first"
    );
    r.wait_for_builds();
    let later = draw(&mut r, &kb, &rectilinear);
    assert!(r.drew_specialised());
    let want = alone(&kb, &rectilinear);
    for (label, got) in [("generic", &first), ("specialised", &later)] {
        let db = psnr(got, &want, whole(got));
        assert!(db >= 60.0, "new lens model, {label}: {db:.1} dB");
    }
}

#[test]
fn lens_models_named_ahead_are_drawn_from_the_first_frame_without_a_build() {
    // The live stream names lens.cal's models: its first frame makes their generic draw
    // pipelines, so a LENS SET to a lens of another model builds (and, on lavapipe, compiles)
    // nothing on the stream's path.
    let state = base_state();
    let lenses: Vec<_> = ["CIL216", "CIL018", "LN007"]
        .into_iter()
        .map(|name| (name, seen(name, &state)))
        .collect();
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    r.expect_lenses(lenses.iter().map(|(_, (lens, _))| lens));
    draw(&mut r, &lenses[0].1, &state);
    let built = r.pipelines();
    for (name, other) in &lenses[1..] {
        let got = draw(&mut r, other, &state);
        assert_eq!(r.pipelines(), built, "{name}: pipelines built mid-stream");
        let db = psnr(&got, &alone(other, &state), whole(&got));
        assert!(
            db >= 60.0,
            "{name}, drawn by pipelines warmed up: {db:.1} dB"
        );
    }
    // Unnamed, a lens of another model does need a build.
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    draw(&mut r, &lenses[0].1, &state);
    let built = r.pipelines();
    draw(&mut r, &lenses[2].1, &state);
    assert!(r.pipelines() > built);
}

/// One upload, every output: after each frame is rendered, two more outputs drawn from its
/// upload (a view alone, I420 with the mip filter, as a per-view stream is; and an RGBA scan
/// with the bilinear filter, as a model's scan is) come back byte for byte as a renderer of
/// their own draws them from the same frame, frame after frame. Drawing before any upload,
/// with a lens that images the frame otherwise, or one output twice is refused, and drawing
/// goes on after.
#[test]
fn outputs_drawn_again_from_one_upload_match_each_rendered_alone() {
    let lens = small_lens("CIL216");
    let world = GridWorld::default();
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    let view = r.add_output(PixelFormat::I420, Filter::Mip).unwrap();
    let scan = r.add_output(PixelFormat::Rgba, Filter::Bilinear).unwrap();
    let err = r
        .redraw(&[(
            view,
            &FramePlan::single_view(&base_state(), &lens, 0, 320, 180),
        )])
        .unwrap_err();
    assert!(err.to_string().contains("no frame"), "{err}");
    let mut alone_view = renderer(PixelFormat::I420, Filter::Mip);
    let mut alone_scan = renderer(PixelFormat::Rgba, Filter::Bilinear);
    let mut last: Option<(Vec<u8>, PlaneLayout)> = None;
    for (i, yaw) in [0.0, 35.0, -70.0].into_iter().enumerate() {
        let mut state = base_state();
        state.vehicle.attitude.yaw = yaw * DEG;
        let (data, layout) = as_format(&fisheye(&world, &lens, &state), PixelFormat::I420);
        r.render(&data, &layout, &FramePlan::new(&state, &lens).unwrap())
            .unwrap();
        let view_plan = FramePlan::single_view(&state, &lens, i, 320, 180);
        let mut scanned = state.clone();
        (
            scanned.settings.output.width,
            scanned.settings.output.height,
        ) = (256, 128);
        let scan_plan = FramePlan::new(&scanned, &lens).unwrap();
        let got = r.redraw(&[(view, &view_plan), (scan, &scan_plan)]).unwrap();
        let want = [
            alone_view.render(&data, &layout, &view_plan).unwrap(),
            alone_scan.render(&data, &layout, &scan_plan).unwrap(),
        ];
        for (got, want) in got.iter().zip(&want) {
            assert_eq!(got.layout, want.layout, "frame {i}");
            assert!(got.data == want.data, "frame {i}: {:?}", got.layout.format);
        }
        // Drawn from the frame before, the view would differ: the comparison tells.
        if let Some((data, layout)) = last.replace((data, layout)) {
            let stale = alone_view.render(&data, &layout, &view_plan).unwrap();
            assert!(stale.data != got[0].data, "frame {i}");
        }
    }
    let other = small_lens("CIL216").for_frame(640, 360, None);
    let err = r
        .redraw(&[(
            view,
            &FramePlan::single_view(&base_state(), &other, 0, 320, 180),
        )])
        .unwrap_err();
    assert!(err.to_string().contains("otherwise"), "{err}");
    let plan = FramePlan::single_view(&base_state(), &lens, 0, 320, 180);
    let err = r.redraw(&[(view, &plan), (view, &plan)]).unwrap_err();
    assert!(err.to_string().contains("twice"), "{err}");
    assert_eq!(r.redraw(&[(view, &plan)]).unwrap().len(), 1);
    let mut bilinear = renderer(PixelFormat::I420, Filter::Bilinear);
    assert!(bilinear.add_output(PixelFormat::I420, Filter::Mip).is_err());
}
