//! Invariants on arbitrary input for the fuzz targets (`fuzz/`) and the test that replays
//! their corpus, where the assembly's parts meet: the files an operator writes (the same text
//! as lens.cal, as a state file and as the serve configuration: each is read or refused with
//! an error in words, never a panic, and what is read holds), and the MAVLink link with the
//! cameras and gimbals on it.

use super::config::Config;
use crate::autopilot::checks::Bench;
use crate::cameras::{Cameras, CamerasConfig};
use crate::lens::{LensCal, Lenses};
use crate::state::State;
use std::path::Path;
use std::sync::Arc;

/// `data` as lens.cal, as a state file (lens names from `cal`) and as the serve configuration.
pub fn text_files(cal: &LensCal, data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match LensCal::parse(Path::new("lens.cal"), text) {
        Ok(read) => drop(Lenses::new(&read)),
        Err(e) => assert!(!e.to_string().is_empty(), "a refusal says why"),
    }
    match State::parse(text, "state.toml", cal) {
        // What the loaders do next: the whole state checked, refused with a reason.
        Ok(state) => {
            if let Err(e) = state.validate(&Lenses::new(cal)) {
                assert!(!e.to_string().is_empty(), "a refusal says why");
            }
        }
        Err(e) => assert!(!e.to_string().is_empty(), "a refusal says why"),
    }
    match Config::parse(text) {
        Ok(cfg) => cfg.check().expect("a configuration read is valid"),
        Err(e) => assert!(!e.to_string().is_empty(), "a refusal says why"),
    }
}

/// The MAVLink link's receiving side with the cameras and gimbals of the fuzzers' default
/// state on it (`control::checks::controller`).
pub fn mavlink_bench(cal: &LensCal) -> (Bench, Arc<crate::state::Gate>) {
    let gate = crate::control::checks::controller(cal).gate.clone();
    let cameras = Arc::new(Cameras::new(gate.clone(), CamerasConfig::default(), None));
    let sensing = (gate.sensed().clone(), Arc::default());
    (Bench::new(sensing, cameras), gate)
}

/// `data` as MAVLink messages (`autopilot::checks`) into `bench`: the settings stay valid.
pub fn mavlink_messages((bench, gate): &mut (Bench, Arc<crate::state::Gate>), data: &[u8]) {
    bench.feed(data);
    let settings = gate.settings();
    settings
        .snapshot()
        .validate(settings.lenses())
        .expect("the settings stay valid");
}
