//! The thermal picture in camera 0's own stream as FFmpeg decodes it, chosen over MAVLink as a
//! pymavlink ground station chooses it (PARAM_EXT_SET THERMAL): the demo's thermal camera is
//! mounted to look at the car whose engine bay is the hottest thing it sees (the movers
//! standing, the vehicle hovering), and view 0 looks a little beside it. Blended, the
//! engine's hot patch lies within 1 px of where the view sees the engine (the two mounts
//! registered); as a picture-in-picture and as the view's whole picture, the decoded inset
//! lies within 1 px of the CPU reference's, drawn from the thermal frame the demo draws; and
//! the view's stream is flagged THERMAL (VIDEO_STREAM_INFORMATION), its field of view the
//! thermal camera's, while the view shows the thermal picture alone.

use crate::common;
use common::thermal::{
    SIZE, aimed, decoded, engine_ray, engine_serve, luma, mount_towards, reference_layer,
};

use common::peers::LinePeer;
use digiview::geometry::Euler;
use digiview::image_ops::psnr;
use digiview::layout::Rect;
use digiview::lens::Lenses;
use digiview::modes::ThermalShow;
use digiview::plan::FramePlan;
use digiview::state::{State, ThermalLook};
use glam::DVec2;
use image::RgbImage;
use std::time::Duration;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The centroid (pixel centres at +0.5) of the brightest patch of `value` in `rect` (x, y,
/// w, h): each pixel weighted by how far it rises past 25 levels under the brightest.
fn hot_patch(value: impl Fn(u32, u32) -> f64, (x0, y0, w, h): (u32, u32, u32, u32)) -> DVec2 {
    let pixels = || (y0..y0 + h).flat_map(move |y| (x0..x0 + w).map(move |x| (x, y)));
    let top = pixels().map(|(x, y)| value(x, y)).fold(f64::MIN, f64::max);
    let (mut sum, mut weight) = (DVec2::ZERO, 0.0);
    for (x, y) in pixels() {
        let w = (value(x, y) - (top - 25.0)).max(0.0);
        sum += DVec2::new(x as f64 + 0.5, y as f64 + 0.5) * w;
        weight += w;
    }
    sum / weight
}

/// Entry 0 of the layer over `plan`'s view 0 `show`'s way, as the CPU reference draws it
/// (white-hot under the automatic gain, the head's default), over black: the picture and the
/// entry's rect.
fn reference(plan: &FramePlan, state: &State, show: ThermalShow, mount: Euler) -> (RgbImage, Rect) {
    let layer = reference_layer(plan, state, show, mount, &ThermalLook::default());
    let mut picture = RgbImage::new(SIZE.0, SIZE.1);
    layer.draw_rgb(&mut picture);
    (picture, layer.entries[0].rect)
}

/// The mean squared difference of luma between `got` shifted by (dx, dy) and `want` over
/// `rect`.
fn mismatch(got: &RgbImage, want: &RgbImage, r: Rect, (dx, dy): (i32, i32)) -> f64 {
    let mut sum = 0.0;
    for y in r.y..r.y + r.h {
        for x in r.x..r.x + r.w {
            let (gx, gy) = ((x as i32 + dx) as u32, (y as i32 + dy) as u32);
            sum += (luma(got, gx, gy) - luma(want, x, y)).powi(2);
        }
    }
    sum / (r.w * r.h) as f64
}

/// How far `got` stands from `want` over `rect` (its edges 8 px in): the whole-pixel shift
/// within ±4 that matches best, refined on each axis by the parabola through its neighbours.
fn shift(got: &RgbImage, want: &RgbImage, rect: Rect) -> DVec2 {
    let r = Rect::new(rect.x + 8, rect.y + 8, rect.w - 16, rect.h - 16);
    let mut best = ((0, 0), f64::MAX);
    for dy in -4..=4 {
        for dx in -4..=4 {
            let m = mismatch(got, want, r, (dx, dy));
            if m < best.1 {
                best = ((dx, dy), m);
            }
        }
    }
    let ((dx, dy), m0) = best;
    let refine = |minus: f64, plus: f64| {
        let curve = minus + plus - 2.0 * m0;
        if curve > 0.0 {
            0.5 * (minus - plus) / curve
        } else {
            0.0
        }
    };
    let x = refine(
        mismatch(got, want, r, (dx - 1, dy)),
        mismatch(got, want, r, (dx + 1, dy)),
    );
    let y = refine(
        mismatch(got, want, r, (dx, dy - 1)),
        mismatch(got, want, r, (dx, dy + 1)),
    );
    DVec2::new(dx as f64 + x, dy as f64 + y)
}

/// Camera 0 set to show the thermal camera `show`'s way (PARAM_EXT_SET THERMAL, accepted),
/// and its stream as FFmpeg decodes it a moment later.
fn choose(station: &mut LinePeer, url: &str, show: ThermalShow) -> RgbImage {
    let heard = station.ask(&serde_json::json!({"camera": 100, "thermal": show.code()}));
    assert_eq!(heard["ack"], 0, "THERMAL = {}: {heard}", show.code());
    assert_eq!(heard["value"], show.code(), "{heard}");
    // Thermal frames come 9 times a second.
    std::thread::sleep(Duration::from_millis(1500));
    decoded(url)
}

#[test]
fn each_way_of_showing_the_thermal_camera_stands_where_the_mounts_put_it_in_the_stream() {
    let _alone = crate::one_at_a_time();
    let state = State::default();
    let ray = engine_ray(&state);
    let mount = mount_towards(&state, ray);
    // View 0 a little left of and above the engine, which stands off its middle.
    let (yaw, pitch) = (ray.y.atan2(ray.x) - 8.0 * DEG, -ray.z.asin() + 5.0 * DEG);
    let (serve, mut station, _) = engine_serve(mount, (yaw, pitch));
    let url = format!("{}/cam0", serve.rtsp.clone().unwrap());
    let s = aimed(&state, yaw, pitch);
    let fisheye = Lenses::new(&common::lens_cal())
        .for_frame(0, SIZE, None)
        .unwrap();
    let plan = FramePlan::single_view(&s, &fisheye, 0, SIZE.0, SIZE.1);
    let off = choose(&mut station, &url, ThermalShow::Off);
    let blend = choose(&mut station, &url, ThermalShow::Blend);
    let truth = plan.view_point(&plan.views[0], ray).unwrap();
    let warmer = |x, y| luma(&blend, x, y) - luma(&off, x, y);
    let at = hot_patch(warmer, (0, 0, SIZE.0, SIZE.1));
    let miss = (at - truth).length();
    eprintln!("blended: the engine at {at:.2}, the mounts put it at {truth:.2}: {miss:.2} px");
    assert!(
        miss <= 1.0,
        "blended: {miss:.2} px from where the mounts put it"
    );
    for show in [ThermalShow::Pip, ThermalShow::Thermal] {
        let frame = choose(&mut station, &url, show);
        // The view's own stream (1) is flagged thermal while it shows the thermal picture
        // alone; the composed one (2) never.
        let heard = station.ask(&serde_json::json!({"camera": 100, "streams": true}));
        // VIDEO_STREAM_STATUS_FLAGS_THERMAL.
        let thermal = |id: &str| heard["flags"][id].as_u64().map(|f| f & 2 != 0);
        let alone = show == ThermalShow::Thermal;
        assert_eq!(
            (thermal("1"), thermal("2")),
            (Some(alone), Some(false)),
            "{heard}"
        );
        // Its field of view is the thermal camera's (the Boson's, about 50°) while it is that
        // camera's picture, else the view's 90°.
        let boson = Lenses::new(&common::lens_cal())
            .named("BOSON320")
            .unwrap()
            .hfov();
        let hfov = if alone {
            boson.to_degrees().round()
        } else {
            90.0
        };
        assert_eq!(heard["hfov"]["1"], hfov, "{heard}");
        let (want, rect) = reference(&plan, &s, show, mount);
        // The measure sees a shift: the reference one pixel to the right reads as one.
        let moved = RgbImage::from_fn(SIZE.0, SIZE.1, |x, y| *want.get_pixel(x.max(1) - 1, y));
        let seen = shift(&moved, &want, rect);
        assert!((seen - DVec2::X).length() < 0.05, "{seen}");
        let db = psnr(&frame, &want, rect);
        let miss = shift(&frame, &want, rect).length();
        eprintln!(
            "{}: the decoded inset {miss:.2} px from where the thermal lens puts it, {db:.1} dB \
             against the CPU reference",
            show.name()
        );
        assert!(miss <= 1.0, "{}: {miss:.2} px", show.name());
        // The thermal picture itself, through the encoder (its palette and gain are held to
        // 45 dB before it, tests/it/thermal.rs).
        assert!(db >= 35.0, "{}: {db:.1} dB", show.name());
    }
    // MAV_CMD_SET_CAMERA_SOURCE picks the same: RGB alone, IR alone, RGB with IR in the
    // corner (the stream flagged thermal with IR alone only); what is not drawn is refused.
    for (sources, device, result, alone) in [
        ([2, 0], 0, "MAV_RESULT_ACCEPTED", true),
        ([1, 2], 100, "MAV_RESULT_ACCEPTED", false),
        ([1, 0], 0, "MAV_RESULT_ACCEPTED", false),
        // Refused, the view left as it was.
        ([2, 1], 0, "MAV_RESULT_DENIED", false),
        ([3, 0], 0, "MAV_RESULT_DENIED", false),
        ([2, 0], 101, "MAV_RESULT_DENIED", false),
    ] {
        let ask = serde_json::json!({"camera": 100, "source": sources, "device": device});
        let heard = station.ask(&ask);
        assert_eq!(heard["result"], result, "{ask}: {heard}");
        let heard = station.ask(&serde_json::json!({"camera": 100, "streams": true}));
        let thermal = heard["flags"]["1"].as_u64().map(|f| f & 2 != 0);
        assert_eq!(thermal, Some(alone), "{ask}: {heard}");
    }
}
