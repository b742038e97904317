//! The KLV of a view through the pair (ST 0601's pointing, fields of view, frame centre and
//! footprint): the view's own, worked out from its rays, as through one fisheye; a view above
//! the horizon, which only the pair shows, has no ground to give.

use super::*;
use digiview::stream::klv::ViewMetadata;

#[test]
fn a_views_klv_through_the_pair_is_the_same_views_through_one_fisheye() {
    let mut s = state([(0.0, -60.0), (95.0, -5.0), (200.0, 30.0), (290.0, 85.0)]);
    let a = &mut s.vehicle.attitude;
    (a.yaw, a.pitch, a.roll) = (30.0 * DEG, -5.0 * DEG, 8.0 * DEG);
    let one = small_lens("CIL216");
    for cam in 0..4 {
        let through = |lens: &Lens| {
            let plan = FramePlan::single_view(&s, lens, cam, 640, 360);
            let pose = (1_764_150_000_000_000, Some((640, 360)));
            ViewMetadata::of(&plan, &plan.views[0], &s, pose, "DigiView cam 0".into())
                .unwrap()
                .with_objects(false)
        };
        let (paired, single) = (through(&pair(0.0)), through(&one));
        assert_eq!(paired, single, "camera {cam}");
        // Down and just under the horizon: a footprint; above it, none.
        let below = s.settings.cameras[cam].pitch() < 0.0;
        assert_eq!(paired.centre.is_some(), below, "camera {cam}: {paired:?}");
        assert_eq!(
            paired.corners.is_some(),
            cam == 0,
            "camera {cam}: {paired:?}"
        );
    }
}
