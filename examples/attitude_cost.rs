//! What one attitude sample from the autopilot costs the thread that takes it: the samples
//! the MAVLink link writes (into the attitude history and what is sensed, as
//! `autopilot::apply` does with each), timed in batches, with a frame loop taking the state
//! 30 times a second beside them. Prints the median and range of the batches' cost per
//! sample.
//!
//!     cargo run --release --example attitude_cost -- [--objects 8]

use digiview::geometry::Euler;
use digiview::lens::LensCal;
use digiview::state::{LiveSettings, Sensed, State, Tracked};
use digiview::telemetry::Telemetry;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let objects: usize = args
        .iter()
        .position(|a| a == "--objects")
        .and_then(|i| args.get(i + 1)?.parse().ok())
        .unwrap_or(8);
    let cal = LensCal::load(std::path::Path::new("lens-cal/lens.cal")).expect("lens.cal");
    let mut state = State::default();
    state.settings.detection.run_ai = true;
    state.tracked = (0..objects as u32)
        .map(|id| Tracked {
            id,
            yaw: id as f64 * 0.3,
            ..Tracked::default()
        })
        .collect();
    let settings = Arc::new(LiveSettings::new(state.settings, &cal).expect("valid settings"));
    let sensed = Arc::new(Sensed::new(state.vehicle, state.tracked));
    let telemetry = Telemetry::default();
    let stop = Arc::new(AtomicBool::new(false));
    let frames = {
        let (settings, sensed, stop) = (settings.clone(), sensed.clone(), stop.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                std::hint::black_box(State::now(&settings, &sensed));
                std::thread::sleep(Duration::from_millis(33));
            }
        })
    };
    let (batches, per_batch) = (15, 20_000u32);
    let mut ns = vec![];
    for b in 0..batches {
        let t0 = Instant::now();
        for k in 0..per_batch {
            let t = (b * per_batch + k) as f64 * 1e-3;
            let a = Euler::new(t.sin(), 0.1 * t.cos(), 0.05 * t.sin());
            telemetry.external_attitude((t * 1e6) as u64, a);
            let _ = sensed.set_attitude(a);
        }
        ns.push(t0.elapsed().as_nanos() as f64 / per_batch as f64);
    }
    stop.store(true, Ordering::Relaxed);
    frames.join().expect("the frame loop's stand-in");
    ns.sort_by(f64::total_cmp);
    println!(
        "attitude sample: median {:.0} ns (range {:.0}..{:.0}) over {batches} batches of \
         {per_batch}, {objects} tracked objects",
        ns[ns.len() / 2],
        ns[0],
        ns[ns.len() - 1]
    );
}
