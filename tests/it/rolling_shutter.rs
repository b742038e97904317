//! Rolling-shutter correction against ground truth (issue 43's first acceptance). A grid-world
//! fisheye is captured row by row, each row with the vehicle's attitude when it was read (25 ms
//! readout, turning 90°/s in yaw, or separately in roll), and dewarped into four views aimed
//! at landmarks. Corrected (the frame's shutter table), the views match the global-shutter
//! truth (≥ 35 dB) and put every landmark within 0.5 px of it; uncorrected, each landmark is
//! off by the shear the geometry predicts (so the test can fail). The GPU draws the corrected
//! views as the CPU reference does.

use crate::common;
use common::gpu::*;
use common::*;
use digiview::geometry::shutter::{Readout, ShutterTable};
use digiview::geometry::{Euler, lens_from_world};
use digiview::image_ops::{centroid, pixel, psnr};
use digiview::layout::Rect;
use digiview::lens::Lens;
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::render::gpu::renderer::render_image;
use digiview::scene::GridWorld;
use digiview::scene::synth::{eye, fisheye, rolling_fisheye, truth};
use digiview::state::State;
use digiview::state::view::Field;
use glam::{DVec2, DVec3};
use image::RgbImage;

on_each_backend!(
    a_rolling_shutter_fisheye_turning_in_yaw_is_dewarped_as_a_global_shutter_one,
    a_rolling_shutter_fisheye_turning_in_roll_is_dewarped_as_a_global_shutter_one,
);

const RATE: f64 = 90.0 * DEG;
pub(crate) const READOUT_MS: f64 = 25.0;

#[derive(Clone, Copy, Debug)]
pub(crate) enum Turn {
    Yaw,
    Roll,
}

/// The attitude `dt_us` after the middle row, turning at [`RATE`] about `turn` from `base`.
pub(crate) fn turning(base: Euler, turn: Turn) -> impl Fn(f64) -> Euler + Sync {
    move |dt_us| {
        let a = RATE * dt_us * 1e-6;
        match turn {
            Turn::Yaw => Euler {
                yaw: base.yaw + a,
                ..base
            },
            Turn::Roll => Euler {
                roll: base.roll + a,
                ..base
            },
        }
    }
}

/// Layout 4, its views 50° across, locked to the world and aimed at landmarks `names`.
fn aimed_state(names: &[&str]) -> State {
    let mut s = four_view_state(7);
    s.vehicle.attitude.pitch = 10.0 * DEG;
    let world = GridWorld::default();
    for (i, name) in names.iter().enumerate() {
        let l = world.landmarks.iter().find(|l| l.name == *name).unwrap();
        let (yaw, pitch) = landmark_direction(&s, l.position);
        let aim = [
            (Field::Yaw, yaw),
            (Field::Pitch, pitch),
            (Field::Fov, 30.0 * DEG),
        ];
        s.settings.cameras[i] = s.settings.cameras[i].clone().with(&aim).unwrap();
    }
    s
}

/// Where the rolling fisheye shows world ray `ray`, the lens turning as `lens_at(dt_us)`
/// says: the point q with q = project(lens_at(dt(q)) · ray), by fixed-point steps.
fn rolling_point(
    lens: &Lens,
    readout: &Readout,
    lens_at: &dyn Fn(f64) -> glam::DMat3,
    ray: DVec3,
) -> Option<DVec2> {
    let size = (lens.width, lens.height);
    let mut q = lens.project(lens_at(0.0) * ray)?;
    for _ in 0..8 {
        q = lens.project(lens_at(readout.point_us(q, size)) * ray)?;
    }
    Some(q)
}

/// A landmark seen in a view: its centroid in the truth, the corrected and the uncorrected
/// render (frame pixels), and the shift the geometry predicts for the uncorrected one.
#[derive(Debug)]
struct Seen {
    name: &'static str,
    view: usize,
    truth: DVec2,
    fixed: DVec2,
    raw: DVec2,
    predicted: DVec2,
}

/// The landmarks each view shows well inside its edges, `shown(view, ray)` being where the
/// uncorrected render puts a ray (view pixels).
fn landmarks(
    plan: &FramePlan,
    state: &State,
    [want, fixed, raw]: [&RgbImage; 3],
    shown: impl Fn(usize, DVec3) -> Option<DVec2>,
) -> Vec<Seen> {
    let mut out = vec![];
    for (vi, view) in plan.views.iter().enumerate() {
        for l in &GridWorld::default().landmarks {
            let ray = (DVec3::new(l.position.x, l.position.y, 0.0) - eye(state)).normalize();
            let r = view.rect;
            let inside = |p: DVec2| {
                p.cmpge(DVec2::splat(60.0)).all()
                    && p.cmple(DVec2::new(r.w as f64, r.h as f64) - 60.0).all()
            };
            let (Some(p), Some(s)) = (plan.view_point(view, ray), shown(vi, ray)) else {
                continue;
            };
            if !inside(p) {
                continue;
            }
            let (cx, cy) = (r.x + p.x as u32, r.y + p.y as u32);
            let window = Rect::new(cx - 60, cy - 60, 120, 120);
            let colour = pixel(want, cx, cy);
            let at = |img: &RgbImage| centroid(img, window, colour, 70.0).map(|c| c.0);
            if let (Some(truth), Some(fixed), Some(raw)) = (at(want), at(fixed), at(raw)) {
                out.push(Seen {
                    name: l.name,
                    view: vi,
                    truth,
                    fixed,
                    raw,
                    predicted: s - p,
                });
            }
        }
    }
    out
}

fn check(gpu: &Gpu, turn: Turn, names: &[&str]) {
    let readout = Readout::top_to_bottom(READOUT_MS);
    let state = aimed_state(names);
    let lens = small_lens("CIL216");
    let world = GridWorld::default();
    let attitude = turning(state.vehicle.attitude.euler(), turn);
    let mount = state.settings.mount.euler();
    let lens_at = |dt: f64| lens_from_world(attitude(dt), mount);
    let fish = rolling_fisheye(&world, &lens, &state, &readout, &attitude);
    let global = FramePlan::new(&state, &lens).unwrap();
    let table = ShutterTable::new(&readout, (lens.width, lens.height), lens_at);
    let plan = global.clone().with_shutter(table);
    let want = truth(&world, &global, &state);
    let fixed = cpu::render(&plan, &fish, Filter::Mip);
    let raw = cpu::render(&global, &fish, Filter::Mip);
    // The same world captured by a global shutter at the middle row's attitude, rendered alike:
    // the corrected views should match it, and score against the truth as it does.
    let still = fisheye(&world, &lens, &state);
    let still = cpu::render(&global, &still, Filter::Mip);
    for (i, v) in plan.views.iter().enumerate() {
        let [fixed_still, raw_still, fixed_truth, still_truth] = [
            (&fixed, &still),
            (&raw, &still),
            (&fixed, &want),
            (&still, &want),
        ]
        .map(|(a, b)| psnr(a, b, v.rect));
        eprintln!(
            "{turn:?} view {i}: vs the global shutter's render, corrected {fixed_still:.2} dB, \
             uncorrected {raw_still:.2} dB; vs truth, corrected {fixed_truth:.2} dB, global \
             {still_truth:.2} dB"
        );
        assert!(
            fixed_still >= 35.0 && fixed_truth >= still_truth - 0.5,
            "{turn:?} view {i}: corrected {fixed_still:.2} dB vs the global shutter's \
             render; {fixed_truth:.2} dB vs truth where it scores {still_truth:.2} dB"
        );
        assert!(
            raw_still < fixed_still - 5.0,
            "{turn:?} view {i}: uncorrected, {raw_still:.2} dB: no shear to correct"
        );
    }
    // The uncorrected render shows a ray where the global plan puts the ray that the middle
    // row's attitude gives the fisheye point at which the rows, read one by one, saw it.
    let shown = |vi: usize, ray: DVec3| {
        let q = rolling_point(&lens, &readout, &lens_at, ray)?;
        let seen = global.lens_from_world.transpose() * lens.unproject(q)?;
        global.view_point(&global.views[vi], seen)
    };
    let seen = landmarks(&global, &state, [&want, &fixed, &raw], shown);
    assert!(
        seen.len() >= 4,
        "{turn:?}: {} landmarks seen: {seen:?}",
        seen.len()
    );
    let mut sheared = 0.0f64;
    for s in &seen {
        let (fixed, raw) = ((s.fixed - s.truth).length(), s.raw - s.truth);
        eprintln!(
            "{turn:?} {} in view {}: corrected off {fixed:.3} px; uncorrected off {:.2} px, \
             predicted {:.2} px",
            s.name,
            s.view,
            raw.length(),
            s.predicted.length()
        );
        assert!(
            fixed <= 0.5,
            "{turn:?} {}: corrected off by {fixed:.3} px",
            s.name
        );
        let miss = (raw - s.predicted).length();
        assert!(
            miss <= 0.5 + 0.1 * s.predicted.length(),
            "{turn:?} {}: uncorrected off by {raw:?}, predicted {:?}",
            s.name,
            s.predicted
        );
        sheared = sheared.max(raw.length());
    }
    assert!(
        sheared >= 3.0,
        "{turn:?}: the uncorrected views are barely sheared ({sheared:.2} px)"
    );
    let mut renderer = renderer_on(gpu, digiview::frame::PixelFormat::Rgba, Filter::Mip);
    let gpu = render_image(&mut renderer, &fish, &plan).unwrap().to_rgb();
    let (vs_cpu, vs_truth) = (
        psnr(&gpu, &fixed, whole(&gpu)),
        psnr(&gpu, &want, whole(&gpu)),
    );
    eprintln!("{turn:?}: GPU vs CPU {vs_cpu:.1} dB, GPU vs truth {vs_truth:.2} dB");
    assert!(vs_cpu >= 45.0, "{turn:?}: GPU vs CPU {vs_cpu:.2} dB");
}

fn a_rolling_shutter_fisheye_turning_in_yaw_is_dewarped_as_a_global_shutter_one(gpu: &Gpu) {
    check(gpu, Turn::Yaw, &["red", "blue", "yellow", "magenta"]);
}

fn a_rolling_shutter_fisheye_turning_in_roll_is_dewarped_as_a_global_shutter_one(gpu: &Gpu) {
    check(gpu, Turn::Roll, &["cyan", "purple", "red", "blue"]);
}

/// How many times a ray must be projected again with its row's rotation (SHUTTER_STEPS): at
/// 4K, turning 90°/s with a 25 ms readout, over a grid of the whole fisheye, the corrected
/// projection lands within 0.02 px of the exact rolling-shutter point; one step would not.
#[test]
fn two_steps_find_where_the_rolling_rows_saw_a_ray_at_4k() {
    let readout = Readout::top_to_bottom(READOUT_MS);
    let state = aimed_state(&[]);
    let lens = lens_cal()
        .find("CIL216")
        .unwrap()
        .lens()
        .for_frame(3840, 2160, None);
    for turn in [Turn::Yaw, Turn::Roll] {
        let attitude = turning(state.vehicle.attitude.euler(), turn);
        let mount = state.settings.mount.euler();
        let lens_at = |dt: f64| lens_from_world(attitude(dt), mount);
        let plan = FramePlan::new(&state, &lens).unwrap();
        let table = ShutterTable::new(&readout, (lens.width, lens.height), lens_at).unwrap();
        let plan = plan.with_shutter(Some(table.clone()));
        let (mut one, mut two) = (0.0f64, 0.0f64);
        for i in 0..=40 {
            for j in 0..=40 {
                let p = DVec2::new(i as f64 * 96.0, j as f64 * 54.0);
                let Some(ray) = lens.unproject(p) else {
                    continue;
                };
                let world = plan.lens_from_world.transpose() * ray;
                let Some(exact) =
                    rolling_point(&lens, &readout, &lens_at, world).filter(|&q| lens.in_frame(q))
                else {
                    continue;
                };
                let d = plan.lens_from_world * world;
                let first = lens.project(d).unwrap();
                let Some(step) = lens.project(table.at(first) * d) else {
                    continue;
                };
                one = one.max(step.distance(exact));
                two = two.max(plan.lens_pixel(d).unwrap().distance(exact));
            }
        }
        eprintln!("{turn:?} at 4K: one step off by up to {one:.3} px, SHUTTER_STEPS {two:.4} px");
        assert!(two <= 0.02, "{turn:?}: off by {two:.4} px");
    }
}

/// The readout estimate (docs/serve.md, "Measuring the readout") on 4 s of the demo camera
/// spinning (yaw 90°/s, roll ±20° at 1 Hz) with a `readout_ms` readout, as the head collects
/// them: luma at half size, attitudes by the clock the spin follows.
fn estimated(readout_ms: f64) -> digiview::render::shutter_fit::Fit {
    use digiview::frame::{Frame, PixelFormat, PlaneLayout};
    use digiview::render::shutter_fit::{FitFrame, estimate};
    use digiview::source::demo::{DemoCamera, spin};
    let state = State::default();
    let (w, h) = (640, 360);
    let lens = lens_cal()
        .find("CIL216")
        .unwrap()
        .lens()
        .for_frame(w, h, None);
    let layout = PlaneLayout::tight(PixelFormat::Nv12, w, h).unwrap();
    let camera =
        DemoCamera::new(&lens, layout, state.settings.mount.euler()).with_readout(readout_ms);
    let sensor = digiview::exposure::SensorModel::new(digiview::exposure::Setting {
        exposure_us: state.settings.sensor.exposure_us,
        gain: state.settings.sensor.gain,
    });
    let position = state.vehicle.position;
    let frames: Vec<FitFrame> = (0..120)
        .map(|i| {
            let stamp = 100.0 + i as f64 / 30.0;
            let at = |dt_us: f64| spin(Euler::default(), stamp + dt_us * 1e-6);
            let data = camera.frame(at, &position, stamp, (sensor, i), None);
            let frame = Frame {
                data,
                layout,
                captured_us: 0,
            };
            FitFrame::new(frame.luma().unwrap(), |t| Some(at(t as f64))).unwrap()
        })
        .collect();
    let fit = estimate(
        &frames,
        &lens,
        state.settings.mount.euler(),
        Readout::default(),
        |_, _| {},
    );
    let fit = fit.unwrap();
    eprintln!(
        "{readout_ms} ms: estimated {:.2} ms from {} pairs of {} points: disagreement {:.2} vs \
         {:.2} uncorrected",
        fit.readout_ms, fit.pairs, fit.points, fit.disagreement, fit.disagreement_global
    );
    fit
}

#[test]
fn the_readout_of_the_spinning_demo_is_estimated_within_2_ms() {
    for readout_ms in [READOUT_MS, 0.0, 45.0] {
        let fit = estimated(readout_ms);
        assert!(
            (fit.readout_ms - readout_ms).abs() <= 2.0,
            "{readout_ms} ms: {fit:?}"
        );
    }
}
