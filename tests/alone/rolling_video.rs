//! Rolling-shutter correction on the live head (issue 43): the demo camera reads its rows out
//! over 25 ms, top to bottom, while it spins (yaw 90°/s, roll ±20° at 1 Hz) and a simulated
//! autopilot reports that attitude over MAVLink. With all axes locked the views are fixed in
//! the world, so in every decoded frame the ground's landmarks must be where the ground truth
//! puts them: with `[readout] time_ms = 25` they are; told the camera has a global shutter,
//! the head draws them sheared and wobbling at the spin's rate.

use super::autopilot_video::{Readouts, landmark_errors_with, spread, summary};

#[test]
fn a_rolling_shutter_spinning_with_the_vehicle_is_corrected_in_the_decoded_views() {
    let _alone = crate::one_at_a_time();
    let rolling = |corrected_ms| Readouts {
        camera_ms: 25.0,
        corrected_ms,
    };
    let (errors, small, fps) = landmark_errors_with("interpolated", rolling(25.0), 31, |_| {});
    let (median, worst) = summary("corrected", &errors, &small, fps);
    let (raw, r_small, r_fps) = landmark_errors_with("interpolated", rolling(0.0), 31, |_| {});
    let (r_median, r_worst) = summary("uncorrected", &raw, &r_small, r_fps);
    assert!(
        errors.len() >= 250,
        "only {} landmarks seen in 30 frames",
        errors.len()
    );
    assert!(
        median <= 0.5,
        "corrected: median {median:.2} px from the truth"
    );
    assert!(
        worst <= 1.0,
        "corrected: a landmark {worst:.2} px from the truth"
    );
    let (_, s_worst) = spread(&small);
    assert!(
        s_worst <= 2.0,
        "a small landmark {s_worst:.2} px from the truth"
    );
    assert!(
        r_median > 2.0 * median && r_worst > 3.0 * worst,
        "uncorrected, the landmarks should visibly move: median {r_median:.2} px, worst \
         {r_worst:.2} px"
    );
}
