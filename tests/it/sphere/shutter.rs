//! The rolling-shutter correction on the pair: a pair frame read row by row across both
//! images while the vehicle turns (25 ms, 90°/s in yaw) is dewarped as the same frame taken
//! by a global shutter, on the seam, straight up and straight down; uncorrected, it is not.

use super::*;
use crate::rolling_shutter::{READOUT_MS, Turn, turning};
use digiview::geometry::lens_from_world;
use digiview::geometry::shutter::{Readout, ShutterTable};
use digiview::scene::synth::rolling_fisheye;

fn a_rolling_shutter_pair_turning_in_yaw_is_dewarped_as_a_global_shutter_one(gpu: &Gpu) {
    let lens = pair(2.0 * DEG);
    let s = state([(0.0, 0.0), (95.0, 12.0), (0.0, 80.0), (180.0, -80.0)]);
    let readout = Readout::top_to_bottom(READOUT_MS);
    let attitude = turning(s.vehicle.attitude.euler(), Turn::Yaw);
    let mount = s.settings.mount.euler();
    let rolling = rolling_fisheye(world(), &lens, &s, &readout, &attitude);
    let still = fisheye(world(), &lens, &s);
    let global = FramePlan::new(&s, &lens).unwrap();
    let size = (lens.width, lens.height);
    let table = ShutterTable::new(&readout, size, |dt| lens_from_world(attitude(dt), mount));
    let plan = global.clone().with_shutter(table);
    let fixed = cpu::render(&plan, &rolling, Filter::Mip);
    let raw = cpu::render(&global, &rolling, Filter::Mip);
    let want = cpu::render(&global, &still, Filter::Mip);
    let mut renderer = renderer_on(gpu, PixelFormat::Rgba, Filter::Mip);
    let on_gpu = render_image(&mut renderer, &rolling, &plan)
        .unwrap()
        .to_rgb();
    let vs_cpu = psnr(&on_gpu, &fixed, whole(&on_gpu));
    eprintln!("GPU vs CPU reference, corrected: {vs_cpu:.1} dB");
    assert!(vs_cpu >= 45.0, "GPU vs CPU reference {vs_cpu:.1} dB");
    for (i, v) in plan.views.iter().enumerate() {
        let (corrected, uncorrected) = (psnr(&fixed, &want, v.rect), psnr(&raw, &want, v.rect));
        eprintln!(
            "view {i}: against the global shutter's frame, corrected {corrected:.2} dB, \
             uncorrected {uncorrected:.2} dB"
        );
        assert!(corrected >= 35.0, "view {i}: corrected {corrected:.2} dB");
        assert!(
            uncorrected < corrected - 5.0,
            "view {i}: uncorrected {uncorrected:.2} dB: no shear to correct"
        );
    }
}

on_each_backend!(a_rolling_shutter_pair_turning_in_yaw_is_dewarped_as_a_global_shutter_one);
