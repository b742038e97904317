//! The GPU renderer on lavapipe (or whatever adapter the machine has; none is a failure)
//! against the CPU reference of the same math and against ground truth from the synthetic
//! world: every layout, crop mode and lens model; camera-native NV12 and I420 input;
//! encoder-ready I420 and NV12 output; filtering of minified views (mip and bilinear); tiny
//! frames; mip levels made by passes reading uploads in place or copied, or on the host; the
//! frame ring; 4:2:0 colours passed through; how far the draw's parabolas between projected
//! pixels stray from the projection.
//!
//! Tolerances: GPU vs CPU reference PSNR ≥ 45 dB per frame; GPU vs truth within 0.5 dB of
//! what the CPU reference scores; 4:2:0 input vs RGBA input ≥ 40 dB.

mod common;
use common::*;
use digiview::frame::{PixelFormat, PlaneLayout, yuv};
use digiview::image_ops::{pixel, psnr};
use digiview::layout::Rect;
use digiview::lens::Lens;
use digiview::lens::samples::sample_lenses;
use digiview::render::gpu::renderer::render_image;
use digiview::render::gpu::{Gpu, Renderer};
use digiview::render::{Filter, FramePlan, cpu};
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::State;
use glam::DVec2;
use image::RgbImage;
use std::sync::OnceLock;

/// One device for the whole file: opening lavapipe is not free.
fn gpu() -> Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| Gpu::new().expect("a GPU adapter (lavapipe in CI)"))
        .clone()
}

fn renderer(format: PixelFormat, filter: Filter) -> Renderer {
    Renderer::new(&gpu(), format, filter).unwrap()
}

fn whole(img: &RgbImage) -> Rect {
    Rect::new(0, 0, img.width(), img.height())
}

/// Four views and three detection tiles at 480x272, the vehicle rolled.
fn base_state() -> State {
    let mut s = four_view_state(7);
    (s.output.width, s.output.height) = (480, 272);
    s.output.overlay = 2;
    s.vehicle.attitude.roll = 10.0 * DEG;
    s.tracked = three_tracked();
    s
}

struct Scores {
    vs_cpu: f64,
    gpu_vs_truth: f64,
    cpu_vs_truth: f64,
}

/// Renders `state` through `lens` on both renderers and scores them.
fn scores(renderer: &mut Renderer, lens: &Lens, state: &State, fish: &RgbImage) -> Scores {
    let world = GridWorld::default();
    let plan = FramePlan::new(state, lens).unwrap();
    let want = cpu::render(&plan, fish, Filter::Mip);
    let got = render_image(renderer, fish, &plan).unwrap().to_rgb();
    let exact = truth(&world, &plan, state);
    Scores {
        vs_cpu: psnr(&got, &want, whole(&got)),
        gpu_vs_truth: psnr(&got, &exact, whole(&got)),
        cpu_vs_truth: psnr(&want, &exact, whole(&got)),
    }
}

fn assert_parity(label: &str, s: &Scores) {
    eprintln!(
        "{label}: GPU vs CPU {:.1} dB; vs truth GPU {:.2} dB, CPU {:.2} dB",
        s.vs_cpu, s.gpu_vs_truth, s.cpu_vs_truth
    );
    assert!(s.vs_cpu >= 45.0, "{label}: GPU vs CPU {:.2} dB", s.vs_cpu);
    assert!(
        s.gpu_vs_truth >= s.cpu_vs_truth - 0.5,
        "{label}: GPU {:.2} dB vs truth, CPU {:.2} dB",
        s.gpu_vs_truth,
        s.cpu_vs_truth
    );
}

#[test]
fn every_layout_and_crop_mode_matches_the_cpu_reference_and_ground_truth() {
    let (world, lens) = (GridWorld::default(), small_lens("CIL018"));
    let mut r = renderer(PixelFormat::Rgba, Filter::Mip);
    let state = base_state();
    let fish = fisheye(&world, &lens, &state);
    for layout in 0..7u8 {
        // Each camera takes each crop mode once over the four rotations (0, 1, 2, 3, 4 and an
        // unknown one, which is black); layout 6 shows no camera, so once is enough.
        for rotate in 0..if layout == 6 { 1 } else { 4 } {
            let mut s = state.clone();
            s.output.layout = layout;
            for (i, cam) in s.cameras.iter_mut().enumerate() {
                cam.crop = [0, 1, 2, 4, 3, 9][(i + rotate) % 6];
                cam.fov = if cam.crop == 2 { 200.0 } else { 80.0 } * DEG;
            }
            let label = format!("layout {layout} rotation {rotate}");
            assert_parity(&label, &scores(&mut r, &lens, &s, &fish));
        }
    }
}

#[test]
fn light_outside_the_lens_image_circle_never_reaches_the_output() {
    // CIL216's circle is narrower than the frame: a third of the columns are not imaged.
    let world = GridWorld::default();
    let lens = small_lens("CIL216").for_frame(1920, 1080, None);
    let (columns, rows) = lens.imaged_box();
    assert!(columns.len() < lens.width as usize * 2 / 3, "{columns:?}");
    let mut state = base_state();
    // The debug view: the whole fisheye minified 40 times, so the rim samples mip levels 5
    // and 6, whose texels reach past the imaged box's margin.
    (state.output.width, state.output.height) = (48, 28);
    (state.output.layout, state.output.overlay) = (6, 0);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let dark = fisheye(&world, &lens, &state);
    // Flare around the image circle: everything outside the imaged box white.
    let mut flare = dark.clone();
    for (x, y, p) in flare.enumerate_pixels_mut() {
        if !columns.contains(&x) || !rows.contains(&y) {
            *p = image::Rgb([255; 3]);
        }
    }
    let mut r = renderer(PixelFormat::Rgba, Filter::Mip);
    for format in [PixelFormat::Rgba, PixelFormat::Nv12, PixelFormat::I420] {
        let (dark, layout) = as_format(&dark, format);
        let (flare, _) = as_format(&flare, format);
        let got_dark = r.render(&dark, &layout, &plan).unwrap();
        let got_flare = r.render(&flare, &layout, &plan).unwrap();
        assert!(
            got_dark.data == got_flare.data,
            "{format}: the flare changed the output"
        );
        let want =
            cpu::render_frame(&plan, &flare, &layout, Filter::Mip, PixelFormat::Rgba).unwrap();
        let got = got_flare.to_rgb();
        let vs_cpu = psnr(&got, &want, whole(&got));
        assert!(
            vs_cpu >= 45.0,
            "{format}: GPU vs CPU with flare {vs_cpu:.2} dB"
        );
    }
}

#[test]
fn every_lens_model_matches_the_cpu_reference_and_ground_truth() {
    let world = GridWorld::default();
    let mut r = renderer(PixelFormat::Rgba, Filter::Mip);
    for lens in sample_lenses() {
        let lens = lens.for_frame(960, 720, None);
        let mut state = base_state();
        for (i, cam) in state.cameras.iter_mut().enumerate() {
            cam.crop = [1, 2, 0, 1][i];
            cam.fov = if cam.crop == 2 { 180.0 } else { 80.0 } * DEG;
        }
        let fish = fisheye(&world, &lens, &state);
        assert_parity(&lens.name, &scores(&mut r, &lens, &state, &fish));
    }
}

/// The fisheye frame as bytes of `format` (chroma from each 2x2 block's mean).
fn as_format(img: &RgbImage, format: PixelFormat) -> (Vec<u8>, PlaneLayout) {
    let layout = PlaneLayout::tight(format, img.width(), img.height()).unwrap();
    (yuv::encode(img, &layout), layout)
}

#[test]
fn nv12_and_i420_input_give_the_picture_of_rgba_input_and_of_the_cpu_reference() {
    let state = base_state();
    // RGBA output takes 4:2:0 chroma per pixel, I420 output once per 2x2 quad.
    for output in [PixelFormat::Rgba, PixelFormat::I420] {
        let mut r = renderer(output, Filter::Mip);
        // 1002x566: rows that do not start on a word (luma 1002 bytes, I420 chroma 501) and a
        // height that is not a multiple of the ingest's 4-row blocks.
        for (w, h) in [(1280, 720), (1002, 566)] {
            let lens = small_lens("CIL216").for_frame(w, h, None);
            let fish = fisheye(&GridWorld::default(), &lens, &state);
            let plan = FramePlan::new(&state, &lens).unwrap();
            let (rgba, layout) = as_format(&fish, PixelFormat::Rgba);
            let want = r.render(&rgba, &layout, &plan).unwrap().to_rgb();
            let mut nv12 = None;
            for format in [PixelFormat::Nv12, PixelFormat::I420] {
                let (data, layout) = as_format(&fish, format);
                let got = r.render(&data, &layout, &plan).unwrap().to_rgb();
                // I420 holds NV12's samples in other places (its chroma is woven into NV12's
                // pairs on the way in): the very same picture.
                match &nv12 {
                    None => nv12 = Some(got.clone()),
                    Some(nv12) => assert!(got == *nv12, "{w}x{h}: I420 in differs from NV12 in"),
                }
                let db = psnr(&got, &want, whole(&got));
                // The CPU reference filtering the same bytes the same way.
                let cpu = cpu::render_frame(&plan, &data, &layout, Filter::Mip, output).unwrap();
                let vs_cpu = psnr(&got, &cpu, whole(&got));
                let label = format!("{w}x{h} {format} in, {output} out");
                eprintln!("{label}: {db:.1} dB vs RGBA input, {vs_cpu:.1} dB vs the CPU");
                assert!(db >= 40.0, "{label}: {db:.2} dB vs RGBA input");
                assert!(vs_cpu >= 45.0, "{label}: {vs_cpu:.2} dB vs the CPU");
            }
        }
    }
}

#[test]
fn bilinear_filtering_matches_the_cpu_reference_from_every_input_format() {
    // Bilinear filtering samples level 0 alone, so the GPU makes no mip chain for it: what it
    // does make must still be the right picture.
    let state = base_state();
    let lens = small_lens("CIL216").for_frame(1002, 566, None);
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let plan = FramePlan::new(&state, &lens).unwrap();
    for output in [PixelFormat::Rgba, PixelFormat::I420] {
        let mut r = renderer(output, Filter::Bilinear);
        for format in [PixelFormat::Rgba, PixelFormat::Nv12, PixelFormat::I420] {
            let (data, layout) = as_format(&fish, format);
            let frame = r.render(&data, &layout, &plan).unwrap();
            let cpu = cpu::render_frame(&plan, &data, &layout, Filter::Bilinear, output).unwrap();
            // The CPU's picture through the same output format (4:2:0 keeps a quad's mean
            // chroma).
            let want = yuv::decode(&yuv::encode(&cpu, &frame.layout), &frame.layout).unwrap();
            let got = frame.to_rgb();
            let db = psnr(&got, &want, whole(&got));
            eprintln!("bilinear, {format} in, {output} out: {db:.1} dB vs the CPU");
            assert!(
                db >= 45.0,
                "bilinear, {format} in, {output} out: {db:.2} dB"
            );
        }
    }
}

#[test]
fn i420_and_nv12_output_are_the_rgba_output_in_bt709_limited_range() {
    let lens = small_lens("CIL216");
    let mut state = base_state();
    // 472 is not a multiple of 8: the GPU pads its rows; the decoded picture must not care.
    state.output.width = 472;
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let rgba = render_image(&mut renderer(PixelFormat::Rgba, Filter::Mip), &fish, &plan)
        .unwrap()
        .to_rgb();
    for format in [PixelFormat::I420, PixelFormat::Nv12] {
        let frame = render_image(&mut renderer(format, Filter::Mip), &fish, &plan).unwrap();
        assert_eq!((frame.layout.width, frame.layout.height), (472, 272));
        // The same picture encoded on the CPU: every code value within 1.
        let want = yuv::encode(&rgba, &frame.layout);
        let worst = frame
            .data
            .iter()
            .zip(&want)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap();
        assert!(worst <= 1, "{format}: a code value differs by {worst}");
        // And black is Y 16, chroma 128 (the frame's left edge is outside every view).
        assert_eq!(frame.data[0], 16, "{format}: black luma");
        assert_eq!(frame.data[frame.layout.chroma[0] as usize], 128);
    }
}

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
                (state.output.width, state.output.height) = (640, 360);
                for cam in &mut state.cameras {
                    (cam.crop, cam.fov) = (crop, fov * DEG);
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
    (state.output.width, state.output.height) = (1920, 1080);
    let lens = lens_cal().find("CIL216").unwrap().lens();
    let (n, f, w) = parabola_runs(&FramePlan::new(&state, &lens).unwrap());
    eprintln!("a 1080p frame of four views: {f} of {n} runs on parabolas, worst {w:.5} px");
    assert!(f * 2 > n && w < 0.01, "{f} of {n} runs, worst {w:.4} px");
}

/// Of the values that are not `black`, the most frequent and the share of them it has.
fn dominant<T: Copy + Ord>(values: impl Iterator<Item = T>, black: T) -> (T, f64) {
    let mut counts = std::collections::BTreeMap::new();
    for v in values.filter(|&v| v != black) {
        *counts.entry(v).or_insert(0usize) += 1;
    }
    let total: usize = counts.values().sum();
    let (&value, &n) = counts
        .iter()
        .max_by_key(|(_, n)| **n)
        .expect("something is drawn");
    (value, n as f64 / total as f64)
}

#[test]
fn camera_colours_rgb_cannot_hold_go_from_4_2_0_input_to_4_2_0_output_unclipped() {
    // Y 60, Cb 60, Cr 220: a dark, saturated red whose blue is below RGB's 0. Through RGB and
    // back it would come out clipped (Y 66); 4:2:0 in and out, the camera's values go out as
    // they came, wherever a view sees the image.
    let lens = small_lens("CIL216");
    let plan = FramePlan::new(&base_state(), &lens).unwrap();
    for input in [PixelFormat::I420, PixelFormat::Nv12] {
        let layout = PlaneLayout::tight(input, lens.width, lens.height).unwrap();
        let mut data = vec![60u8; layout.size as usize];
        for by in 0..lens.height / 2 {
            for bx in 0..lens.width / 2 {
                let (u, v) = layout.chroma_at(bx, by);
                (data[u], data[v]) = (60, 220);
            }
        }
        for output in [PixelFormat::I420, PixelFormat::Nv12] {
            for filter in [Filter::Mip, Filter::Bilinear] {
                let label = format!("{input} in, {output} out, {filter:?}");
                let frame = renderer(output, filter)
                    .render(&data, &layout, &plan)
                    .unwrap();
                let (out, bytes) = (&frame.layout, &frame.data);
                let luma = (0..out.height).flat_map(|y| {
                    (0..out.width).map(move |x| bytes[(y * out.stride + x) as usize])
                });
                // Pixels on the image circle's rim blend with the black outside it.
                let (y, share) = dominant(luma, 16);
                assert!(y == 60 && share > 0.9, "{label}: luma {y} ({share:.3})");
                let chroma = (0..out.height / 2).flat_map(|by| {
                    (0..out.width / 2).map(move |bx| {
                        let (u, v) = out.chroma_at(bx, by);
                        (bytes[u], bytes[v])
                    })
                });
                let (c, share) = dominant(chroma, (128, 128));
                assert!(
                    c == (60, 220) && share > 0.9,
                    "{label}: chroma {c:?} ({share:.3})"
                );
            }
        }
    }
}

/// Mean squared deviation from the mean (AC energy) over a rectangle, per channel.
fn ac_energy(img: &RgbImage, r: Rect) -> f64 {
    let n = r.area() as f64;
    let mut mean = glam::DVec3::ZERO;
    for y in r.y..r.bottom() {
        for x in r.x..r.right() {
            mean += pixel(img, x, y);
        }
    }
    mean /= n;
    let mut e = 0.0;
    for y in r.y..r.bottom() {
        for x in r.x..r.right() {
            e += (pixel(img, x, y) - mean).length_squared() / 3.0;
        }
    }
    e / n
}

#[test]
fn a_minified_debug_view_of_a_fine_checkerboard_does_not_alias() {
    // A 1280x720 fisheye of 3-pixel checks (period 6 px) drawn 5.3x smaller in layout 6: the
    // checks' period is 1.1 output pixels, all of their energy above the output's Nyquist
    // limit, so whatever AC energy the view has is aliasing. The box-filtered reference
    // averages each output pixel's exact footprint.
    let (fw, fh) = (1280u32, 720u32);
    let checks = RgbImage::from_fn(fw, fh, |x, y| {
        image::Rgb([if (x / 3 + y / 3) % 2 == 0 { 255 } else { 0 }; 3])
    });
    let lens = small_lens("CIL216");
    let mut state = State::default();
    (state.output.width, state.output.height) = (240, 136);
    (state.output.layout, state.output.overlay) = (6, 0);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let view = plan.views[0].rect;
    let digiview::render::ViewMap::Fisheye { origin, scale } = plan.views[0].map else {
        panic!("layout 6 is a fisheye view");
    };
    // Box reference: the mean of the checks over each output pixel's square footprint, inside
    // the image circle only (as the renderer masks it).
    let reference = RgbImage::from_fn(state.output.width, state.output.height, |x, y| {
        if !view.contains(x, y) {
            return image::Rgb([0; 3]);
        }
        let p = glam::DVec2::new((x - view.x) as f64 + 0.5, (y - view.y) as f64 + 0.5);
        if plan.fisheye_pixel(&plan.views[0], p).is_none() {
            return image::Rgb([0; 3]);
        }
        let (x0, y0) = (
            origin.x + (p.x - 0.5) * scale,
            origin.y + (p.y - 0.5) * scale,
        );
        let (mut sum, mut n) = (0.0f64, 0.0f64);
        let steps = 32;
        for j in 0..steps {
            for i in 0..steps {
                let fx = x0 + (i as f64 + 0.5) / steps as f64 * scale;
                let fy = y0 + (j as f64 + 0.5) / steps as f64 * scale;
                let (cx, cy) = (fx.floor() as i64, fy.floor() as i64);
                if cx >= 0 && cy >= 0 && (cx as u32) < fw && (cy as u32) < fh {
                    sum += pixel(&checks, cx as u32, cy as u32).x;
                    n += 1.0;
                }
            }
        }
        image::Rgb([(sum / n.max(1.0)).round() as u8; 3])
    });
    // Measured on a square well inside the image circle.
    let c = (view.x + view.w / 2, view.y + view.h / 2);
    let window = Rect::new(c.0 - 40, c.1 - 40, 80, 80);
    let input_energy = 127.5f64 * 127.5;
    let aliasing = |img: &RgbImage| ac_energy(img, window) / input_energy;
    let reference_aliasing = aliasing(&reference);
    let mip = render_image(
        &mut renderer(PixelFormat::Rgba, Filter::Mip),
        &checks,
        &plan,
    )
    .unwrap()
    .to_rgb();
    let bilinear = render_image(
        &mut renderer(PixelFormat::Rgba, Filter::Bilinear),
        &checks,
        &plan,
    )
    .unwrap()
    .to_rgb();
    let (got, unfiltered) = (aliasing(&mip), aliasing(&bilinear));
    eprintln!(
        "aliased energy / checkerboard energy: box reference {reference_aliasing:.4}, \
         mip {got:.4}, single bilinear {unfiltered:.4}"
    );
    assert!(
        got <= reference_aliasing + 0.10,
        "the filtered view aliases: {got:.4} vs box reference {reference_aliasing:.4}"
    );
    assert!(
        unfiltered > reference_aliasing + 0.10,
        "the measure must catch an unfiltered view ({unfiltered:.4})"
    );
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
            (state.output.width, state.output.height) = (400, 240);
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

#[test]
fn tiny_and_odd_sized_frames_render_as_the_cpu_does_and_too_small_ones_are_refused() {
    // Frames smaller than one ingest block (16x4) and RGBA with odd sizes: every plane and
    // level still lands where the CPU reference puts it.
    let state = base_state();
    let world = GridWorld::default();
    let mut r = renderer(PixelFormat::Rgba, Filter::Mip);
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
    mixed.cameras[1].crop = 2;
    mixed.cameras[2].crop = 4;
    let mut panorama = rectilinear.clone();
    panorama.cameras[3].crop = 2;
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
    r.expect_lens_models(lenses.iter().map(|(_, (lens, _))| &lens.radial.model));
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
