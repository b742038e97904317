//! pymavlink, the MAVLink implementation most Python tools and scripts use, against a running
//! `serve` (tests/peers/pymavlink_station.py): stream requests with NaN
//! or 0 in what they do not use, and every gimbal and camera command the same as COMMAND_LONG
//! and as COMMAND_INT.

use crate::common;

use common::autopilot::free_udp_port;
use common::peers::run_peer;
use common::serve::Serve;
use serde_json::Value;

#[test]
fn pymavlink_gets_the_streams_with_nan_or_zero_and_each_command_the_same_long_or_int() {
    let link = free_udp_port();
    // The vehicle 100 m above home; the view pointed at a spot on the ground near it.
    let serve = Serve::start(&[
        "--mavlink",
        &format!("udpin:127.0.0.1:{link}"),
        "--position",
        "lat=47.0,lon=8.0,alt=600,rel=100",
    ]);
    let spot = ["47.0004", "8.0002", "500"];
    let (out, err) = run_peer(
        "pymavlink_station.py",
        &[&link.to_string(), spot[0], spot[1], spot[2]],
    );
    let events: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}\n{err}")))
        .collect();

    let streams: Vec<&Value> = events.iter().filter(|e| e["event"] == "streams").collect();
    assert_eq!(streams.len(), 4, "{out}");
    for s in streams {
        assert_eq!(s["result"], "MAV_RESULT_ACCEPTED", "{s}");
        assert_eq!(s["ids"], serde_json::json!([1, 2]), "{s}");
    }

    let commands: Vec<&Value> = events.iter().filter(|e| e["event"] == "command").collect();
    assert_eq!(commands.len(), 4, "{out}");
    for c in commands {
        assert_eq!(c["long"][0], "MAV_RESULT_ACCEPTED", "{c}");
        assert_eq!(c["long"][0], c["int"][0], "the same answer either way: {c}");
        assert!(
            alike(&c["long"][1], &c["int"][1]),
            "the same state either way: {c}"
        );
        assert_ne!(
            c["long"][1], c["before"],
            "the command changed something: {c}"
        );
    }
    drop(serve);
}

/// The same state: equal, but for numbers within 0.002 (COMMAND_LONG carries a latitude as a
/// float, good to about half a metre; COMMAND_INT to a centimetre).
fn alike(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Array(a), Value::Array(b)) => {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| alike(x, y))
        }
        (Value::Number(x), Value::Number(y)) => {
            (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() < 2e-3
        }
        _ => a == b,
    }
}
