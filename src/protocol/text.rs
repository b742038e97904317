//! Messages for people: each field with its unit, and a byte-by-byte annotation of a frame
//! (what `digiview ctl --hex` prints and docs/protocol.md shows).

use super::params::Field;
use super::{
    Body, CHECKSUM_AT, DATA_AT, FRAME_LEN, Message, MessageType, Param, ParamType, Unit, crc8,
};
use serde_json::Value;
use std::fmt::Write;

/// The fields of a parameter, in wire order, with their values.
pub fn fields(p: &Param) -> Vec<(Field, Value)> {
    let Ok(Value::Object(map)) = serde_json::to_value(p) else {
        unreachable!("parameter structs serialize to objects")
    };
    p.param_type()
        .fields()
        .iter()
        .map(|f| (*f, map.get(f.name).cloned().unwrap_or(Value::Null)))
        .collect()
}

/// A field's value with its unit: `0.785 rad (44.98°)`, `58.000000°`, `100.000 m`.
pub fn show(unit: Unit, v: &Value) -> String {
    let n = v.as_f64().unwrap_or(f64::NAN);
    let bbox = |b: &Value| {
        let g = |k| b.get(k).and_then(Value::as_u64).unwrap_or(0);
        format!("{},{} {}x{}", g("x"), g("y"), g("w"), g("h"))
    };
    match unit {
        Unit::Integer => v.to_string(),
        Unit::Radians => format!("{n:.3} rad ({:.2}°)", n.to_degrees()),
        Unit::Degrees => format!("{n:.6}°"),
        Unit::Metres => format!("{n:.3} m"),
        Unit::Ratio => format!("{n:.3}"),
        Unit::Offset => format!("{n:.4}"),
        Unit::Seconds => format!("{n:.3} s"),
        Unit::Kelvin => format!("{n:.1} K"),
        Unit::Text => v.as_str().unwrap_or_default().to_string(),
        Unit::Boxes => match v {
            Value::Array(boxes) => boxes
                .iter()
                .enumerate()
                .map(|(i, b)| format!("[{i}] {}", bbox(b)))
                .collect::<Vec<_>>()
                .join("  "),
            b => bbox(b),
        },
    }
}

/// A parameter as an indented list of `name  value` lines.
pub fn describe(p: &Param) -> String {
    let rows = fields(p);
    let width = rows.iter().map(|(f, _)| f.name.len()).max().unwrap_or(0);
    let mut out = String::new();
    for (f, v) in rows {
        let _ = writeln!(out, "  {:width$}  {}", f.name, show(f.unit, &v));
    }
    out
}

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn row(out: &mut String, at: usize, bytes: &[u8], what: &str) {
    let _ = writeln!(out, "  {at:2}  {:<35}  {what}", hex(bytes));
}

/// Every field of an 80-byte frame: offset, bytes, name and value.
pub fn annotate(frame: &[u8; FRAME_LEN]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "  at  bytes                                field");
    let ts = u64::from_le_bytes(frame[..8].try_into().expect("8 bytes"));
    row(&mut out, 0, &frame[..8], &format!("timestamp = {ts} µs"));
    row(
        &mut out,
        8,
        &frame[8..9],
        &format!("version = {}", frame[8]),
    );
    let decoded = Message::decode(frame);
    let kind = decoded
        .as_ref()
        .map(|m| m.body.message_type().to_string())
        .unwrap_or_else(|_| message_type_name(frame[9]));
    row(
        &mut out,
        9,
        &frame[9..10],
        &format!("message_type = {kind}"),
    );
    let pt = ParamType::from_u8(frame[10]).map_or("unknown".to_string(), |p| p.to_string());
    row(&mut out, 10, &frame[10..11], &format!("param_type = {pt}"));
    let at = match decoded {
        Ok(Message {
            body: Body::Get(p) | Body::Set(p) | Body::Current(p),
            ..
        }) => annotate_fields(&mut out, frame, &p),
        _ => DATA_AT,
    };
    annotate_end(&mut out, frame, at);
    out
}

/// A parameter's fields, a row each, from [`DATA_AT`]; where they end.
fn annotate_fields(out: &mut String, frame: &[u8; FRAME_LEN], p: &Param) -> usize {
    let mut at = DATA_AT;
    {
        for (f, v) in fields(p) {
            if let Value::Array(boxes) = &v {
                // VIDEO_OUTPUT's views: one row per box, as many as there are.
                for (i, b) in boxes.iter().enumerate() {
                    let shown = show(Unit::Boxes, b);
                    let bytes = &frame[at + 8 * i..at + 8 * (i + 1)];
                    row(
                        out,
                        at + 8 * i,
                        bytes,
                        &format!("{}[{i}] = {shown}", f.name),
                    );
                }
                at += 8 * boxes.len();
                continue;
            }
            let mut what = format!("{} = {}", f.name, show(f.unit, &v));
            if p.param_type() == ParamType::VideoOutput && f.name == "layout_mode" {
                let _ = write!(
                    what,
                    " (low four bits); {} views (high four)",
                    frame[at] >> 4
                );
            }
            row(out, at, &frame[at..at + f.size], &what);
            at += f.size;
        }
    }
    at
}

/// What follows the fields from `at`: unused bytes, the checksum and the padding.
fn annotate_end(out: &mut String, frame: &[u8; FRAME_LEN], at: usize) {
    let end = CHECKSUM_AT;
    if at < end {
        let zero = frame[at..end].iter().all(|&b| b == 0);
        let _ = writeln!(
            out,
            "  {at:2}  {:<35}  {}",
            if zero {
                "00 …".to_string()
            } else {
                hex(&frame[at..end])
            },
            if zero { "unused, zero" } else { "unused" }
        );
    }
    let ok = crc8(&frame[..end]) == frame[end];
    row(
        out,
        end,
        &frame[end..end + 1],
        &format!("checksum (CRC-8 {})", if ok { "ok" } else { "MISMATCH" }),
    );
    row(out, end + 1, &frame[end + 1..], "padding");
}

fn message_type_name(n: u8) -> String {
    MessageType::ALL
        .get(n as usize)
        .map_or(format!("{n} (unknown)"), |m| m.to_string())
}
