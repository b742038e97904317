use super::view::{Follow, Op, Shape};
use super::*;
use crate::lens::LensCal;
use std::sync::Arc;

fn gate() -> Gate {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("lens-cal/lens.cal");
    let cal = LensCal::load(&path).unwrap();
    let settings = LiveSettings::new(Settings::default(), &cal).unwrap();
    Gate::new(Arc::new(settings), Arc::default(), Arc::default())
}

fn detection(gate: &Gate, on: bool) {
    gate.change(|s| {
        s.detection.run_ai = on;
        Ok::<_, Invalid>(())
    })
    .unwrap();
}

/// Detection turned off takes its objects with it at once: no reader sees them, and the
/// views that followed one stop; turned on again, only what the detector finds next shows.
#[test]
fn turning_detection_off_takes_the_objects_and_their_followers_with_it_at_once() {
    let gate = gate();
    let (settings, sensed) = (gate.settings(), gate.sensed());
    sensed.set_tracked(vec![Tracked::default(); 2]);
    let click = Follow {
        shape: Shape::Point,
        yaw: 0.0,
        pitch: -0.5,
        size: 0.1,
        ground: None,
        since_us: 5,
        object: None,
    };
    settings
        .update(|s| {
            let seen = State::default();
            view::apply(&mut s.cameras[1], &Op::Follow(click), &seen.seen()).unwrap();
            view::follow::adopt(&mut s.cameras, 1, 5, 0);
            Ok::<_, Invalid>(())
        })
        .unwrap();
    assert_eq!(State::now(settings, sensed).tracked.len(), 2);
    detection(&gate, false);
    let now = State::now(settings, sensed);
    assert!(now.tracked.is_empty());
    assert_eq!(now.settings.cameras[1].follow(), None);
    // Set while off (a detector slow to hear it), shown once it is on again; the old list
    // is gone.
    sensed.set_tracked(vec![Tracked::default()]);
    assert!(State::now(settings, sensed).tracked.is_empty());
    detection(&gate, true);
    assert_eq!(State::now(settings, sensed).tracked.len(), 1);
}

/// An attitude or a position outside the vehicle's rules is refused and the last kept.
#[test]
fn a_vehicle_sample_outside_its_rules_is_refused_and_the_last_one_kept() {
    let sensed = Sensed::default();
    sensed
        .set_attitude(crate::geometry::Euler::new(0.5, 0.1, 0.0))
        .unwrap();
    let e = sensed
        .set_attitude(crate::geometry::Euler::new(0.5, 2.0, 0.0))
        .unwrap_err();
    assert!(
        e.0.contains("vehicle attitude pitch 2 rad (114.592°) is outside ±π/2"),
        "{e}"
    );
    assert_eq!(sensed.vehicle().attitude.pitch, 0.1);
    let mut far = DEFAULT_POSITION;
    far.lat = f64::NAN;
    assert!(sensed.set_position(far).is_err());
    assert_eq!(sensed.vehicle().position, DEFAULT_POSITION);
}
