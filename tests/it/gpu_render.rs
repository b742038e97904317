//! The GPU renderer's pictures on lavapipe (or whatever adapter the machine has; none is a
//! failure) against the CPU reference of the same math and against ground truth from the
//! synthetic world: every layout, crop mode and lens model; camera-native NV12 and I420 input;
//! encoder-ready I420 and NV12 output; filtering of minified views (mip and bilinear); 4:2:0
//! colours passed through. tests/it/gpu_frames.rs has the renderer as a stream of frames.
//!
//! Tolerances: GPU vs CPU reference PSNR ≥ 45 dB per frame; GPU vs truth within 0.5 dB of
//! what the CPU reference scores; 4:2:0 input vs RGBA input ≥ 40 dB.

use crate::common;
use common::gpu::*;
use common::*;
use digiview::frame::{PixelFormat, PlaneLayout, yuv};
use digiview::image_ops::{pixel, psnr};
use digiview::layout::Rect;
use digiview::lens::Lens;
use digiview::lens::samples::sample_lenses;
use digiview::modes::{LayoutMode, LayoutMode::Whole, OverlayMode};
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::render::gpu::Renderer;
use digiview::render::gpu::renderer::render_image;
use digiview::scene::GridWorld;
use digiview::scene::synth::{fisheye, truth};
use digiview::state::State;
use digiview::state::view::Field;
use image::RgbImage;

on_each_backend!(
    every_layout_and_crop_mode_matches_the_cpu_reference_and_ground_truth,
    light_outside_the_lens_image_circle_never_reaches_the_output,
    every_lens_model_matches_the_cpu_reference_and_ground_truth,
    nv12_and_i420_input_give_the_picture_of_rgba_input_and_of_the_cpu_reference,
    bilinear_filtering_matches_the_cpu_reference_from_every_input_format,
    i420_and_nv12_output_are_the_rgba_output_in_bt709_limited_range,
    camera_colours_rgb_cannot_hold_go_from_4_2_0_input_to_4_2_0_output_unclipped,
    a_minified_debug_view_of_a_fine_checkerboard_does_not_alias,
);

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

fn every_layout_and_crop_mode_matches_the_cpu_reference_and_ground_truth(gpu: &Gpu) {
    let (world, lens) = (GridWorld::default(), small_lens("CIL018"));
    let mut r = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    let state = base_state();
    let fish = fisheye(&world, &lens, &state);
    for &layout in LayoutMode::ALL {
        // Each camera takes each crop mode once over the four rotations (0, 1, 2, 3, 4 and an
        // unknown one, which is black); layout 6 shows no camera, so once is enough.
        for rotate in 0..if layout == LayoutMode::Whole { 1 } else { 4 } {
            let mut s = state.clone();
            s.settings.output.layout = layout;
            for (i, cam) in s.settings.cameras.iter_mut().enumerate() {
                let crop = [0, 1, 2, 4, 3, 9][(i + rotate) % 6];
                let fov = if crop == 2 { 200.0 } else { 80.0 } * DEG;
                cam.put(Field::Crop, crop as f64).unwrap();
                cam.put(Field::Fov, fov).unwrap();
            }
            let label = format!("layout {layout} rotation {rotate}");
            assert_parity(&label, &scores(&mut r, &lens, &s, &fish));
        }
    }
}

fn light_outside_the_lens_image_circle_never_reaches_the_output(gpu: &Gpu) {
    // CIL216's circle is narrower than the frame: a third of the columns are not imaged.
    let world = GridWorld::default();
    let lens = small_lens("CIL216").for_frame(1920, 1080, None);
    let (columns, rows) = lens.imaged_box();
    assert!(columns.len() < lens.width as usize * 2 / 3, "{columns:?}");
    let mut state = base_state();
    // The debug view: the whole fisheye minified 40 times, so the rim samples mip levels 5
    // and 6, whose texels reach past the imaged box's margin.
    (state.settings.output.width, state.settings.output.height) = (48, 28);
    (state.settings.output.layout, state.settings.output.overlay) = (Whole, OverlayMode::None);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let dark = fisheye(&world, &lens, &state);
    // Flare around the image circle: everything outside the imaged box white.
    let mut flare = dark.clone();
    for (x, y, p) in flare.enumerate_pixels_mut() {
        if !columns.contains(&x) || !rows.contains(&y) {
            *p = image::Rgb([255; 3]);
        }
    }
    let mut r = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
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

fn every_lens_model_matches_the_cpu_reference_and_ground_truth(gpu: &Gpu) {
    let world = GridWorld::default();
    let mut r = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    for lens in sample_lenses() {
        let lens = lens.for_frame(960, 720, None);
        let mut state = base_state();
        for (i, cam) in state.settings.cameras.iter_mut().enumerate() {
            let crop = [1, 2, 0, 1][i];
            let fov = if crop == 2 { 180.0 } else { 80.0 } * DEG;
            cam.put(Field::Crop, crop as f64).unwrap();
            cam.put(Field::Fov, fov).unwrap();
        }
        let fish = fisheye(&world, &lens, &state);
        assert_parity(&lens.name, &scores(&mut r, &lens, &state, &fish));
    }
}

fn nv12_and_i420_input_give_the_picture_of_rgba_input_and_of_the_cpu_reference(gpu: &Gpu) {
    let state = base_state();
    // RGBA output takes 4:2:0 chroma per pixel, I420 output once per 2x2 quad.
    for output in [PixelFormat::Rgba, PixelFormat::I420] {
        let mut r = renderer_on(gpu, output, Filter::Mip);
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

fn bilinear_filtering_matches_the_cpu_reference_from_every_input_format(gpu: &Gpu) {
    // Bilinear filtering samples level 0 alone, so the GPU makes no mip chain for it: what it
    // does make must still be the right picture.
    let state = base_state();
    let lens = small_lens("CIL216").for_frame(1002, 566, None);
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let plan = FramePlan::new(&state, &lens).unwrap();
    for output in [PixelFormat::Rgba, PixelFormat::I420] {
        let mut r = renderer_on(gpu, output, Filter::Bilinear);
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

fn i420_and_nv12_output_are_the_rgba_output_in_bt709_limited_range(gpu: &Gpu) {
    let lens = small_lens("CIL216");
    let mut state = base_state();
    // 472 is not a multiple of 8: the GPU pads its rows; the decoded picture must not care.
    state.settings.output.width = 472;
    let fish = fisheye(&GridWorld::default(), &lens, &state);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let rgba = render_image(
        &mut renderer_on(gpu, PixelFormat::Rgba, Filter::Mip),
        &fish,
        &plan,
    )
    .unwrap()
    .to_rgb();
    for format in [PixelFormat::I420, PixelFormat::Nv12] {
        let frame = render_image(&mut renderer_on(gpu, format, Filter::Mip), &fish, &plan).unwrap();
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

fn camera_colours_rgb_cannot_hold_go_from_4_2_0_input_to_4_2_0_output_unclipped(gpu: &Gpu) {
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
                let frame = renderer_on(gpu, output, filter)
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

fn a_minified_debug_view_of_a_fine_checkerboard_does_not_alias(gpu: &Gpu) {
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
    (state.settings.output.width, state.settings.output.height) = (240, 136);
    (state.settings.output.layout, state.settings.output.overlay) = (Whole, OverlayMode::None);
    let plan = FramePlan::new(&state, &lens).unwrap();
    let view = plan.views[0].rect;
    let digiview::plan::ViewMap::Fisheye { origin, scale } = plan.views[0].map else {
        panic!("layout 6 is a fisheye view");
    };
    // Box reference: the mean of the checks over each output pixel's square footprint, inside
    // the image circle only (as the renderer masks it).
    let reference = RgbImage::from_fn(
        state.settings.output.width,
        state.settings.output.height,
        |x, y| {
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
        },
    );
    // Measured on a square well inside the image circle.
    let c = (view.x + view.w / 2, view.y + view.h / 2);
    let window = Rect::new(c.0 - 40, c.1 - 40, 80, 80);
    let input_energy = 127.5f64 * 127.5;
    let aliasing = |img: &RgbImage| ac_energy(img, window) / input_energy;
    let reference_aliasing = aliasing(&reference);
    let mip = render_image(
        &mut renderer_on(gpu, PixelFormat::Rgba, Filter::Mip),
        &checks,
        &plan,
    )
    .unwrap()
    .to_rgb();
    let bilinear = render_image(
        &mut renderer_on(gpu, PixelFormat::Rgba, Filter::Bilinear),
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
