//! The thermal colouring on the GPU (lavapipe) against the CPU reference: every palette under
//! the automatic gain and under a fixed span, on a synthetic frame of warm and cold bodies,
//! held to the 45 dB; and the hottest and coldest point of such a frame against its
//! truth.

use crate::common;

use common::gpu::gpu;
use digiview::image_ops::psnr;
use digiview::layout::Rect;
use digiview::render::gpu::thermal::ThermalPass;
use digiview::thermal::synth::{Background, Body, frame};
use digiview::thermal::{Calibration, GainMode, GainTable, Palette, ThermalFrame, colourise};
use image::{DynamicImage, RgbImage, RgbaImage};

fn rgb(img: RgbaImage) -> RgbImage {
    DynamicImage::ImageRgba8(img).to_rgb8()
}

/// A 321x241 frame (an odd number of pixels: the GPU reads two counts a word): a sky at
/// 265 K warming to ground at 295 K, a person at 309.6 K, an engine at 355 K, a puddle at
/// 278 K.
fn scene(cal: &Calibration) -> ThermalFrame {
    let bodies = [
        Body {
            x: 80.5,
            y: 150.25,
            radius: 9.0,
            kelvin: 309.6,
        },
        Body {
            x: 230.0,
            y: 170.0,
            radius: 14.0,
            kelvin: 355.0,
        },
        Body {
            x: 150.0,
            y: 210.0,
            radius: 12.0,
            kelvin: 278.0,
        },
    ];
    let sky = Background {
        top_k: 265.0,
        bottom_k: 295.0,
    };
    frame(321, 241, sky, &bodies, cal)
}

#[test]
fn every_palette_under_both_gains_matches_the_cpu_reference() {
    let gpu = gpu();
    let pass = ThermalPass::new(&gpu).unwrap();
    let cal = Calibration::default();
    let f = scene(&cal);
    let whole = Rect::new(0, 0, f.width, f.height);
    let modes = [
        GainMode::default(),
        GainMode::Span {
            low_k: 270.0,
            high_k: 320.0,
        },
    ];
    for mode in modes {
        let gain = GainTable::new(&f, mode, &cal).unwrap();
        for palette in Palette::ALL {
            let cpu = rgb(colourise(&f, &gain, palette));
            let on_gpu = rgb(pass.colourise(&gpu, &f, &gain, palette).unwrap());
            let db = psnr(&cpu, &on_gpu, whole);
            assert!(db >= 45.0, "{} under {mode:?}: {db:.1} dB", palette.name());
        }
    }
    // The measure tells palettes apart: ironbow is not rainbow.
    let gain = GainTable::new(&f, GainMode::default(), &cal).unwrap();
    let iron = rgb(colourise(&f, &gain, Palette::Ironbow));
    let rainbow = rgb(pass.colourise(&gpu, &f, &gain, Palette::Rainbow).unwrap());
    assert!(psnr(&iron, &rainbow, whole) < 20.0);
}

#[test]
fn the_span_colours_one_temperature_alike_whatever_else_is_in_the_frame() {
    // With a fixed span the person is the same colour beside a warm roof that fills a fifth
    // of the picture or without it; under the automatic gain the roof takes levels from them
    // (no more than its plateau lets it).
    let cal = Calibration::default();
    let person = Body {
        x: 80.5,
        y: 150.25,
        radius: 9.0,
        kelvin: 309.6,
    };
    let roof = Body {
        x: 250.0,
        y: 60.0,
        radius: 70.0,
        kelvin: 320.0,
    };
    let sky = Background {
        top_k: 265.0,
        bottom_k: 295.0,
    };
    let with_roof = frame(321, 241, sky, &[person, roof], &cal);
    let without = frame(321, 241, sky, &[person], &cal);
    let level = |f: &ThermalFrame, mode| {
        let gain = GainTable::new(f, mode, &cal).unwrap();
        gain.level(f.at(80, 150)) as i32
    };
    let span = GainMode::Span {
        low_k: 270.0,
        high_k: 320.0,
    };
    assert_eq!(level(&with_roof, span), level(&without, span));
    let auto = GainMode::default();
    let (beside, alone) = (level(&with_roof, auto), level(&without, auto));
    assert!(
        beside + 10 < alone && beside > 200,
        "{beside} beside the roof, {alone} alone"
    );
}

#[test]
fn the_hottest_and_coldest_points_are_the_bodies() {
    let cal = Calibration::new(0.04, 0.0).unwrap();
    let f = scene(&cal);
    let e = f.extremes(&cal);
    // The engine, at its temperature (to the calibration's step) and its middle.
    assert!((e.hottest.kelvin - 355.0).abs() <= 0.02, "{e:?}");
    assert!(
        (e.hottest.x - 230.0).hypot(e.hottest.y - 170.0) <= 0.5,
        "{e:?}"
    );
    // The sky's top row is colder than the puddle: the coldest point is up there.
    assert!((e.coldest.kelvin - 265.0).abs() < 0.1, "{e:?}");
    assert!(e.coldest.y < 1.0, "{e:?}");
}
