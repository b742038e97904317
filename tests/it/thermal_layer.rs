//! The thermal picture laid over the views on the GPU (lavapipe) against the CPU reference
//! (`ThermalLayer::draw_rgb`): blended onto a view, as a picture-in-picture and as a view's
//! whole picture, in RGBA and in I420 (the encoder's format), held to 45 dB; and placed where
//! the two mounts put it: a hot body's centre in the output within 1 px of where the ray of
//! its thermal pixel, carried through the thermal mount and the view, lands. A view showing
//! the thermal picture alone describes the thermal camera in its KLV.

use crate::common;

use common::gpu::{Gpu, as_format, on_each_backend, renderer, renderer_on, whole};
use common::{DEG, four_view_state, lens_cal};
use digiview::frame::{PixelFormat, yuv};
use digiview::geometry::Euler;
use digiview::image_ops::psnr;
use digiview::lens::{Lens, Lenses};
use digiview::modes::ThermalShow;
use digiview::plan::thermal::ThermalLayer;
use digiview::plan::{Filter, FramePlan};
use digiview::render::cpu;
use digiview::render::gpu::Renderer;
use digiview::scene::thermal::thermal_in_lens;
use digiview::state::State;
use digiview::stream::klv::ViewMetadata;
use digiview::thermal::synth::{Background, Body, frame};
use digiview::thermal::{Calibration, GainMode, GainTable, Palette};
use glam::{DMat3, DVec2, DVec3};
use image::{Rgb, RgbImage};
use std::sync::Arc;

on_each_backend!(the_thermal_layer_matches_the_cpu_reference_and_stands_where_the_mounts_put_it,);

/// The thermal camera turned a little from the fisheye's axis on all three axes.
fn mount() -> DMat3 {
    thermal_in_lens(Euler {
        yaw: 4.0 * DEG,
        pitch: -3.0 * DEG,
        roll: 2.0 * DEG,
    })
}

struct Setup {
    state: State,
    fisheye: Lens,
    thermal: Lens,
    fish: RgbImage,
}

/// Four views at 640x480 over a flat grey fisheye frame (the layer is what changes), the
/// shipped fisheye and Boson lenses.
fn setup() -> Setup {
    let lenses = Lenses::new(&lens_cal());
    let fisheye = lenses.for_frame(0, (1280, 960), None).unwrap();
    let thermal = lenses.named("BOSON320").unwrap().clone();
    let fish = RgbImage::from_pixel(1280, 960, Rgb([70, 90, 110]));
    Setup {
        state: four_view_state(7),
        fisheye,
        thermal,
        fish,
    }
}

/// A hot body (radius 6 thermal pixels, 340 K) at OpenCV point `at` of the thermal frame, on
/// a background of 290 to 300 K, or the background alone; white-hot from 285 to 345 K.
fn layer(s: &Setup, at: Option<DVec2>) -> ThermalLayer {
    let cal = Calibration::default();
    let bodies: Vec<Body> = at
        .map(|q| Body {
            x: q.x + 0.5,
            y: q.y + 0.5,
            radius: 6.0,
            kelvin: 340.0,
        })
        .into_iter()
        .collect();
    let sky = Background {
        top_k: 290.0,
        bottom_k: 300.0,
    };
    let f = frame(s.thermal.width, s.thermal.height, sky, &bodies, &cal);
    let span = GainMode::Span {
        low_k: 285.0,
        high_k: 345.0,
    };
    let gain = GainTable::new(&f, span, &cal).unwrap();
    ThermalLayer::new(
        Arc::new(f),
        Arc::new(gain),
        Palette::WhiteHot,
        s.thermal.clone(),
    )
}

/// The plan with view 2 (straight down, where the thermal camera looks) blended, view 0 with
/// a picture-in-picture and view 3 the thermal picture alone; the body at `at`.
fn plan(s: &Setup, at: Option<DVec2>) -> FramePlan {
    let plan = FramePlan::new(&s.state, &s.fisheye).unwrap();
    let mut l = layer(s, at);
    for (view, show) in [
        (2, ThermalShow::Blend),
        (0, ThermalShow::Pip),
        (3, ThermalShow::Thermal),
    ] {
        l.add(&plan, &plan.views[view], show, mount());
    }
    plan.with_thermal(Some(Arc::new(l)))
}

/// Where the body's centre shows in entry `e` of the layer, by the inverse path: its thermal
/// pixel unprojected, turned into the entry's view frame, projected by the entry.
fn truth(plan: &FramePlan, e: usize, at: DVec2) -> DVec2 {
    let l = plan.thermal.as_ref().unwrap();
    let entry = &l.entries[e];
    let ray = entry.thermal_from_view.transpose() * l.lens.unproject(at).unwrap();
    let p = entry.projection.point(ray).unwrap();
    p + DVec2::new(entry.rect.x as f64, entry.rect.y as f64)
}

/// The centroid (pixel centres at +0.5) of where `a` and `b` differ, inside entry `e`'s
/// rectangle.
fn centroid(a: &RgbImage, b: &RgbImage, plan: &FramePlan, e: usize) -> DVec2 {
    let r = plan.thermal.as_ref().unwrap().entries[e].rect;
    let (mut sum, mut weight) = (DVec2::ZERO, 0.0);
    for y in r.y..r.y + r.h {
        for x in r.x..r.x + r.w {
            let d: f64 = (0..3)
                .map(|c| (a.get_pixel(x, y)[c] as f64 - b.get_pixel(x, y)[c] as f64).abs())
                .sum();
            sum += DVec2::new(x as f64 + 0.5, y as f64 + 0.5) * d;
            weight += d;
        }
    }
    assert!(weight > 0.0, "the body shows nowhere in entry {e}");
    sum / weight
}

/// What the GPU draws, as RGB.
fn gpu(r: &mut Renderer, s: &Setup, plan: &FramePlan) -> RgbImage {
    let (data, layout) = as_format(&s.fish, PixelFormat::Rgba);
    r.render(&data, &layout, plan).unwrap().to_rgb()
}

/// The CPU reference: the views, then the layer over them.
fn reference(s: &Setup, plan: &FramePlan) -> RgbImage {
    let mut img = cpu::render(plan, &s.fish, Filter::Mip);
    if let Some(l) = &plan.thermal {
        l.draw_rgb(&mut img);
    }
    img
}

/// Where the thermal camera sees view 2's centre, and the body put 12 px right and 7 up.
fn body_place(s: &Setup) -> DVec2 {
    let plan = plan(s, None);
    let l = plan.thermal.as_ref().unwrap();
    let e = &l.entries[0];
    let centre = DVec2::new(e.rect.w as f64, e.rect.h as f64) / 2.0;
    let q = l
        .thermal_pixel(e, centre)
        .expect("the thermal camera sees the middle of view 2");
    q + DVec2::new(12.0, -7.0)
}

fn the_thermal_layer_matches_the_cpu_reference_and_stands_where_the_mounts_put_it(on: &Gpu) {
    let s = setup();
    let at = body_place(&s);
    let (with, without) = (plan(&s, Some(at)), plan(&s, None));
    let want = reference(&s, &with);
    let background = reference(&s, &without);
    for format in [PixelFormat::Rgba, PixelFormat::I420] {
        let mut r = renderer_on(on, format, Filter::Mip);
        let got = gpu(&mut r, &s, &with);
        let got_background = gpu(&mut r, &s, &without);
        // The reference through the same 4:2:0 the output takes.
        let through = |img: &RgbImage| match format {
            PixelFormat::Rgba => img.clone(),
            _ => {
                let (data, layout) = as_format(img, format);
                yuv::decode(&data, &layout).unwrap()
            }
        };
        let (want, background) = (through(&want), through(&background));
        let db = psnr(&got, &want, whole(&got));
        eprintln!("{format:?}: GPU vs CPU {db:.1} dB");
        assert!(db >= 45.0, "{format:?}: GPU vs CPU {db:.2} dB");
        for (e, name) in [(0, "blend"), (1, "picture-in-picture"), (2, "thermal view")] {
            let truth = truth(&with, e, at);
            let cpu_at = centroid(&want, &background, &with, e);
            let gpu_at = centroid(&got, &got_background, &with, e);
            let off = (gpu_at - truth).length();
            eprintln!(
                "{format:?} {name}: body at {gpu_at:.2} (CPU {cpu_at:.2}), truth {truth:.2}: \
                 {off:.2} px"
            );
            assert!(
                off <= 1.0,
                "{format:?} {name}: {off:.2} px from where the mounts put it"
            );
        }
    }
}

#[test]
fn a_view_that_shows_no_thermal_picture_is_drawn_as_without_a_layer() {
    let s = setup();
    let with = plan(&s, Some(body_place(&s)));
    let plain = FramePlan::new(&s.state, &s.fisheye).unwrap();
    let mut r = renderer(PixelFormat::I420, Filter::Mip);
    let (a, b) = (gpu(&mut r, &s, &with), gpu(&mut r, &s, &plain));
    // View 1 shows none; view 0 only its inset.
    let l = with.thermal.as_ref().unwrap();
    let inset = l.entries[1].rect;
    for view in [0, 1] {
        let v = with.views[view].rect;
        for y in v.y..v.y + v.h {
            for x in v.x..v.x + v.w {
                // A 4:2:0 quad straddling the inset's edge shares its chroma.
                let near = x + 2 >= inset.x
                    && y + 2 >= inset.y
                    && x < inset.x + inset.w + 2
                    && y < inset.y + inset.h + 2;
                if view == 1 || !near {
                    assert_eq!(
                        a.get_pixel(x, y),
                        b.get_pixel(x, y),
                        "({x}, {y}) in view {view}"
                    );
                }
            }
        }
    }
}

/// A view showing the thermal picture alone describes the thermal camera in its KLV: its
/// fields of view the thermal picture's, its pointing the thermal camera's axis (not the
/// view's own aim), no tracked objects placed in it; a view with an inset keeps its own.
#[test]
fn a_view_showing_the_thermal_picture_alone_describes_the_thermal_camera_in_its_klv() {
    let s = setup();
    let plan = plan(&s, None);
    let meta = |v: usize| {
        ViewMetadata::of(
            &plan,
            &plan.views[v],
            &s.state,
            (0, None),
            format!("cam {v}"),
        )
        .unwrap()
    };
    let alone = meta(3);
    // The thermal picture: a pinhole with the lens's focal lengths over its frame.
    let m = s.thermal.affine.matrix;
    let across = |size: u32, focal: f64| (2.0 * (0.5 * size as f64 / focal).atan()).to_degrees();
    let want = (
        across(s.thermal.width, m.x_axis.x),
        across(s.thermal.height, m.y_axis.y),
    );
    let euler = |d: &digiview::stream::klv::view::Degrees| {
        Euler::new(d.yaw * DEG, d.pitch * DEG, d.roll * DEG)
    };
    let seen = euler(&alone.platform).matrix() * euler(&alone.relative).matrix() * DVec3::X;
    let axis = plan.lens_from_world.transpose() * mount() * DVec3::Z;
    let off = seen.angle_between(axis).to_degrees();
    eprintln!(
        "thermal view: fov {:.2}° x {:.2}° (the thermal picture's {:.2}° x {:.2}°), \
         pointing {off:.4}° off the thermal axis",
        alone.fov.0, alone.fov.1, want.0, want.1
    );
    assert!((alone.fov.0 - want.0).abs() < 0.05 && (alone.fov.1 - want.1).abs() < 0.05);
    assert!(off < 0.01, "{off}° off the thermal camera's axis");
    assert!(alone.objects.is_none() && alone.corners.is_some());
    let inset = meta(0);
    assert!((inset.fov.0 - 90.0).abs() < 0.05, "{:?}", inset.fov);
    assert!(inset.objects.is_some());
}
