//! The one table of rules (`state::rules::RULES`) covers every field, and every entry path
//! keeps to it: a field of a parameter type or of the state that the table leaves out fails
//! the first test; the second sets random values of every field the table gives a state key
//! through the control protocol, a state file, a serve configuration naming one and the
//! flags, and checks that the files and flags take a value exactly when the protocol takes it
//! unchanged (wrapped angles one turn either way), and that the protocol does with the rest
//! what the table says. The third does the same for the serve configuration's own numbers
//! (`app::config_rules`).

use crate::common;
use crate::entry_paths::{Outcome, by_config, by_flags, by_protocol, by_state_file};

use digiview::control::Controller;
use digiview::protocol::{Param, ParamType};
use digiview::state::rules::{Of, Outside, RULES, Rule};
use digiview::state::view::Op;
use digiview::state::{State, Tracked};
use proptest::prelude::*;
use serde_json::Value;
use std::collections::BTreeSet;

/// State keys no rule has: an object's label (text from the detector, any text).
const TEXT: &[&str] = &["tracked.label"];

/// The state with every optional part present: a camera target, a sensor crop, an object.
fn full_state() -> State {
    let mut s = State::default();
    let place = digiview::geometry::GeoPoint {
        lat: 47.0,
        lon: 8.0,
        alt: 400.0,
    };
    let seen = State::default();
    let camera = &mut s.settings.cameras[0];
    digiview::state::view::apply(camera, &Op::Target(place), &seen.seen()).unwrap();
    s.settings.sensor.roi = Some([0, 0, 100, 100]);
    s.tracked = vec![Tracked::default()];
    s
}

/// Every leaf of `v` as a dotted key, list indices left out (`camera.target.lat`).
fn leaves(v: &Value, at: &str, out: &mut BTreeSet<String>) {
    let join = |k: &str| match at {
        "" => k.to_string(),
        _ => format!("{at}.{k}"),
    };
    match v {
        Value::Object(m) => m.iter().for_each(|(k, v)| leaves(v, &join(k), out)),
        Value::Array(a) if a.iter().any(|e| e.is_object()) => {
            a.iter().for_each(|e| leaves(e, at, out))
        }
        // An optional part left out (the other cameras' targets).
        Value::Null => {}
        _ => {
            out.insert(at.to_string());
        }
    }
}

#[test]
fn every_field_of_every_parameter_type_and_of_the_state_has_one_rule() {
    let mut missing = vec![];
    let mut fields = 0;
    for &kind in ParamType::ALL.iter().filter(|k| k.settable()) {
        for f in kind.fields() {
            fields += 1;
            let n = RULES
                .iter()
                .filter(|r| r.param == Some((kind, f.name)))
                .count();
            if n != 1 {
                missing.push(format!("{kind} {}: {n} rules", f.name));
            }
        }
    }
    // No rule names a field that is not there.
    for r in RULES {
        if let Some((kind, name)) = r.param
            && !kind.fields().iter().any(|f| f.name == name)
        {
            missing.push(format!("a rule names {kind} {name}, which does not exist"));
        }
    }
    // Every key of the state as a file writes it has a rule, and the one check reads each.
    let state = full_state();
    let mut keys = BTreeSet::new();
    leaves(&serde_json::to_value(&state).unwrap(), "", &mut keys);
    let keys: BTreeSet<_> = keys
        .into_iter()
        .map(|k| k.replacen("cameras.", "camera.", 1))
        .filter(|k| !TEXT.contains(&k.as_str()))
        .collect();
    let ruled: BTreeSet<String> = RULES
        .iter()
        .filter_map(|r| r.key)
        .map(String::from)
        .collect();
    // The one check reads every field a rule says where the state holds.
    let checked: BTreeSet<String> = RULES
        .iter()
        .filter(|r| !matches!(r.of, Of::Nowhere))
        .filter_map(|r| r.key)
        .map(String::from)
        .collect();
    for k in &keys {
        if !ruled.contains(k) {
            missing.push(format!("state key {k} has no rule"));
        }
        if !checked.contains(k) {
            missing.push(format!(
                "state key {k}: its rule does not say where the state holds it (never checked)"
            ));
        }
    }
    let types = ParamType::ALL.iter().filter(|k| k.settable()).count();
    println!(
        "{} rules: {fields} fields of {types} settable parameter types, {} state keys \
         ({} set by no parameter type)",
        RULES.len(),
        keys.len(),
        RULES.iter().filter(|r| r.param.is_none()).count()
    );
    assert!(
        missing.is_empty(),
        "left out of the table:\n{}",
        missing.join("\n")
    );
}

/// The rules a SET sets and a state file holds, compared across the paths (the sensor crop
/// is joined with the lens and the camera's frame: `entry_paths` covers it; flags are on or
/// off, a file's booleans).
fn compared() -> Vec<&'static Rule> {
    RULES
        .iter()
        .filter(|r| r.param.is_some_and(|(k, _)| k.settable()) && r.key.is_some())
        .filter(|r| !matches!(r.outside, Outside::Flag) && r.key != Some("sensor.roi"))
        .collect()
}

/// The SET of `kind` as the default state's GET gives it (camera 0), or zeros.
fn base(cal: &digiview::lens::LensCal, kind: ParamType) -> Param {
    let c = Controller::direct(State::default(), cal);
    let mut q = kind.zeroed();
    let _ = q.set_field("cam_id", 0.0);
    c.get(&q)
        .ok()
        .and_then(|v| v.into_iter().next())
        .unwrap_or(q)
}

/// A state file holding what `p` sets: every field of its type that has a state key.
fn state_file(p: &Param) -> String {
    let kind = p.param_type();
    let (mut top, mut camera, mut target) = (vec![], vec![], vec![]);
    let mut sections = std::collections::BTreeMap::<&str, Vec<String>>::new();
    for r in RULES
        .iter()
        .filter(|r| r.param.is_some_and(|(k, _)| k == kind))
    {
        let (Some(key), Some((_, field))) = (r.key, r.param) else {
            continue;
        };
        // 0x0 on the wire is no crop, as a file without `roi` (`base` gives 0x0).
        if key == "sensor.roi" {
            continue;
        }
        let Some(v) = p.field(field) else { continue };
        let v = match (r.outside, v.fract() == 0.0) {
            (Outside::Flag, _) => format!("{}", v != 0.0),
            (_, true) => format!("{v:.0}"),
            _ => format!("{v:?}"),
        };
        match key.split('.').collect::<Vec<_>>()[..] {
            [name] => top.push(format!("{name} = {v}")),
            ["camera", "target", name] => target.push(format!("{name} = {v}")),
            ["camera", name] => camera.push(format!("{name} = {v}")),
            [section, name] => sections
                .entry(section)
                .or_default()
                .push(format!("{name} = {v}")),
            _ => panic!("key {key}"),
        }
    }
    let mut text = top.join("\n") + "\n";
    for (section, lines) in sections {
        text += &format!("[{section}]\n{}\n", lines.join("\n"));
    }
    if !camera.is_empty() || !target.is_empty() {
        text += "[[camera]]\nid = 0\n";
        text += &camera.join("\n");
        if !target.is_empty() {
            text += &format!("\ntarget = {{ {} }}", target.join(", "));
        }
    }
    text
}

/// The flags (as `render`, `synth` and `serve` take them) that set what `p` sets for `key`,
/// where flags set it (none set DETECTION, the camera's frame and rate, or a target).
fn flags(key: &str, p: &Param) -> Option<Vec<String>> {
    let (_, field) = RULES.iter().find(|r| r.key == Some(key))?.param?;
    let v = p.field(field)?;
    let n = |name: &str| p.field(name).unwrap_or_default();
    let (flag, value) = match key.split('.').collect::<Vec<_>>()[..] {
        ["output", "width" | "height"] => ("--size", format!("{}x{}", n("width"), n("height"))),
        ["output", "fps"] => ("--fps", format!("{v}")),
        ["output", "layout"] => ("--layout", format!("{v}")),
        ["output", "overlay"] => ("--overlay", format!("{v}")),
        ["lens"] => ("--lens", format!("{v}")),
        ["camera", "target", _] => return None,
        ["camera", name] => ("--cam", format!("0:{name}={v}")),
        ["mount", name] => ("--mount", format!("{name}={v}")),
        ["sensor", "target_brightness" | "exposure_us" | "gain"] => {
            let name = key.strip_prefix("sensor.").unwrap();
            ("--cam-sensor", format!("{name}={v}"))
        }
        _ => return None,
    };
    Some(vec![flag.to_string(), value])
}

/// `StateArgs` as the command line parses `args`.
fn parsed(args: &[String]) -> Result<digiview::cli::StateArgs, String> {
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        state: digiview::cli::StateArgs,
    }
    use clap::Parser;
    Cli::try_parse_from(std::iter::once("x".to_string()).chain(args.iter().cloned()))
        .map(|c| c.state)
        .map_err(|e| e.to_string())
}

/// The state's value under `key` (camera 0's, the first object's).
fn value(s: &State, key: &str) -> f64 {
    s.values()
        .into_iter()
        .find(|v| v.0.key == Some(key))
        .map_or(f64::NAN, |v| v.2)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

    #[test]
    fn every_field_in_the_table_is_taken_alike_by_the_protocol_and_the_files(
        which in any::<prop::sample::Index>(), kind in 0u8..6, t in 0.0f64..1.0
    ) {
        let cal = common::lens_cal();
        let rules = compared();
        let rule = rules[which.index(rules.len())];
        let (param, field) = rule.param.unwrap();
        let key = rule.key.unwrap();
        let span = (rule.hi - rule.lo).max(1.0);
        let step = if rule.unit == "rad" { 0.01 } else { 1.0 };
        let v = match kind {
            0 => rule.lo,
            1 => rule.hi,
            2 => rule.lo - step,
            3 => rule.hi + step,
            _ => rule.lo - span + t * 3.0 * span,
        };
        let mut p = base(&cal, param);
        let whole = !matches!(rule.unit, "rad" | "°" | "m" | "");
        let v = if whole || p.field(field).is_some_and(|f| f.fract() == 0.0) && step == 1.0 {
            v.round()
        } else {
            v
        };
        // The value the wire carries (an integer field takes only what its type holds).
        if p.set_field(field, v).is_err() {
            return Ok(());
        }
        let p = Param::decode(param, &p.encode());
        let sent = p.field(field).unwrap();
        let before = value(&State::default(), key);
        let protocol: Outcome = by_protocol(&cal, p);
        let toml = state_file(&p);
        let mut files = vec![
            ("state file", by_state_file(&cal, &toml)),
            ("config", by_config(&cal, &toml, None)),
        ];
        if let Some(args) = flags(key, &p) {
            files.push(("flags", parsed(&args).and_then(|a| by_flags(&cal, a))));
        }
        for (name, got) in &files[1..] {
            prop_assert_eq!(got.is_ok(), files[0].1.is_ok(), "{} {:?} {:?}", name, got, files[0].1);
        }
        // What the protocol made of it, against the table.
        let slack = if rule.unit == "rad" { 1.5e-3 } else { 1e-6 };
        let same = |a: f64, b: f64| match rule.outside {
            Outside::Wrap => (digiview::geometry::wrap_pi(a - b)).abs() <= slack,
            _ => (a - b).abs() <= slack,
        };
        let even = |v: f64| if matches!(key, "output.width" | "output.height") { v - v % 2.0 } else { v };
        let taken = protocol.as_ref().ok().map(|s| value(s, key));
        // A wrapped angle is the same one turn either way; more, a file refuses. Any other
        // is taken unchanged only within the table's range, and a milliradian past its ends
        // on an angle (the wire's unit: -1.571 for -π/2): the slack for the wire's rounding
        // must not hide a clamp (a pitch of 1.572 held at π/2 is 1.2e-3 off).
        let mrad = if rule.unit == "rad" { 1e-3 } else { 0.0 };
        let within = match rule.outside {
            Outside::Wrap => sent.abs() <= std::f64::consts::TAU + slack,
            _ => (rule.lo - mrad..=rule.hi + mrad).contains(&even(sent)),
        };
        let unchanged = taken.is_some_and(|got| same(got, even(sent))) && within;
        prop_assert_eq!(
            files[0].1.is_ok(), unchanged,
            "{} {} = {}: {}: {:?}; protocol {:?} (was {})\n{}",
            param, field, sent, key, files[0].1.as_ref().err(), taken, before, toml
        );
        if let Some(got) = taken.filter(|_| !unchanged && rule.also.is_empty()) {
            let want = rule.apply(sent, before);
            prop_assert!(
                want.is_some_and(|w| same(got, even(w))),
                "{} {} = {}: the protocol set {}, the table says {:?}", param, field, sent, got, want
            );
        }
    }
}

/// The serve configuration's numbers (`app::config_rules`): each has a rule, and the file
/// takes each at either end of its range and refuses it a step past either end, naming it.
#[test]
fn every_number_of_the_serve_configuration_has_a_rule_and_is_refused_outside_it() {
    use digiview::app::Config;
    use digiview::app::config_rules::CONFIG_RULES;
    let mut full = Config::default();
    full.mavlink.system_id = Some(1);
    let json = serde_json::to_value(&full).unwrap();
    let mut keys = BTreeSet::new();
    leaves(&json, "", &mut keys);
    let numbers: Vec<String> = keys
        .into_iter()
        .filter(|k| {
            let at = format!("/{}", k.replace('.', "/"));
            json.pointer(&at).is_some_and(Value::is_number)
        })
        .collect();
    let checked: BTreeSet<&str> = full.values().into_iter().map(|v| v.0).collect();
    let mut missing = vec![];
    for k in &numbers {
        if !CONFIG_RULES.iter().any(|r| r.key == k) {
            missing.push(format!("{k} has no rule"));
        }
        if !checked.contains(k.as_str()) {
            missing.push(format!("{k} is not among Config::values (never checked)"));
        }
    }
    println!(
        "{} numbers of the serve configuration, {} rules",
        numbers.len(),
        CONFIG_RULES.len()
    );
    assert!(missing.is_empty(), "left out:\n{}", missing.join("\n"));
    // Each end taken, a step past each refused with the key said.
    for r in CONFIG_RULES {
        let toml = |v: f64| match r.key.split_once('.') {
            Some((section, name)) => format!("[{section}]\n{name} = {v:?}\n"),
            None => format!("{} = {v:?}\n", r.key),
        };
        let whole = |v: f64| v.fract() == 0.0;
        let step = if whole(r.lo) && whole(r.hi) {
            1.0
        } else {
            0.01
        };
        for (v, ok) in [
            (r.lo, true),
            (r.hi, true),
            (r.lo - step, false),
            (r.hi + step, false),
        ] {
            let text = if step == 1.0 {
                toml(v).replace(".0\n", "\n")
            } else {
                toml(v)
            };
            let got = Config::parse(&text);
            let said = r.key.replace('.', " ");
            match (&got, ok) {
                (Ok(_), true) => {}
                (Err(e), false) => assert!(
                    e.to_string().contains(&said)
                        || e.to_string().contains(r.key.rsplit('.').next().unwrap()),
                    "{text}: {e}"
                ),
                _ => panic!("{text}: {:?}", got.as_ref().err().map(|e| e.to_string())),
            }
        }
    }
}
