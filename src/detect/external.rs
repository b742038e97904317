//! The external detector: another process on the board (a DeepStream or Hailo pipeline
//! reading the same camera) sends its detections as JSON lines over a local (Unix) socket;
//! they go to the tracker as a scan's would. One line is one frame's detections:
//!
//! ```text
//! {"t": 12.34, "boxes": [{"x0": 812, "y0": 640, "x1": 860, "y1": 731, "confidence": 0.8, "class": "person"},
//!                        {"yaw": 31.5, "pitch": -40.2, "width": 3.1, "height": 4.0, "confidence": 0.6, "class": 2}]}
//! ```
//!
//! A box is either fisheye pixels (x0, y0 its top-left corner, x1, y1 its bottom-right, in the
//! frame as captured) or angles in degrees (world yaw and pitch of its centre, its angular
//! width and height). `t` is the frame's time in seconds on the sender's clock (optional: the
//! time of arrival otherwise). A line that is not right is answered with `error: ...` on the
//! same connection and changes nothing.

use crate::supervise::Locked;
use serde::Deserialize;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// The longest line taken, bytes.
pub const MAX_LINE: usize = 64 * 1024;
/// The most boxes in one line.
pub const MAX_BOXES: usize = 500;

/// Where a box is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Place {
    /// Fisheye pixels: top-left and bottom-right corners.
    Pixels { x0: f64, y0: f64, x1: f64, y1: f64 },
    /// World yaw and pitch of the centre, angular width and height (radians).
    Angles {
        yaw: f64,
        pitch: f64,
        width: f64,
        height: f64,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct ExternalBox {
    pub place: Place,
    pub confidence: f64,
    /// The class as sent (a name, or a number written out).
    pub label: String,
}

/// One line's detections.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    pub t: Option<f64>,
    pub boxes: Vec<ExternalBox>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WireBatch {
    t: Option<f64>,
    boxes: Vec<WireBox>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WireBox {
    x0: Option<f64>,
    y0: Option<f64>,
    x1: Option<f64>,
    y1: Option<f64>,
    yaw: Option<f64>,
    pitch: Option<f64>,
    width: Option<f64>,
    height: Option<f64>,
    confidence: f64,
    class: Option<serde_json::Value>,
}

/// What is wrong with a line: it is answered with this.
#[derive(Debug, thiserror::Error)]
pub enum LineError {
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    #[error("t is not a number of seconds")]
    Time,
    #[error("{0} boxes; at most {MAX_BOXES} a line")]
    TooMany(usize),
    #[error("box {0}: {1}")]
    Box(usize, BoxError),
}

/// What is wrong with one box of a line.
#[derive(Debug, thiserror::Error)]
pub enum BoxError {
    #[error("confidence {0} is outside 0..=1")]
    Confidence(f64),
    #[error("class {0} is not a name (64 characters at most) or a number")]
    Class(serde_json::Value),
    #[error("{0} is not a number")]
    NotANumber(&'static str),
    #[error("x1, y1 must be right of and below x0, y0")]
    Corners,
    #[error("pitch {0} is outside -90..=90 degrees")]
    Pitch(f64),
    #[error("width and height must be in (0, 180] degrees")]
    Size,
    #[error("give x0, y0, x1, y1 (fisheye pixels) or yaw, pitch, width, height (degrees)")]
    Place,
}

/// Reads one line; the error says what is wrong with it.
pub fn parse(line: &str) -> Result<Batch, LineError> {
    let wire: WireBatch = serde_json::from_str(line)?;
    if wire.t.is_some_and(|t| !t.is_finite()) {
        return Err(LineError::Time);
    }
    if wire.boxes.len() > MAX_BOXES {
        return Err(LineError::TooMany(wire.boxes.len()));
    }
    let boxes = wire
        .boxes
        .into_iter()
        .enumerate()
        .map(|(i, b)| to_box(b).map_err(|e| LineError::Box(i, e)))
        .collect::<Result<_, _>>()?;
    Ok(Batch { t: wire.t, boxes })
}

fn to_box(b: WireBox) -> Result<ExternalBox, BoxError> {
    if !(0.0..=1.0).contains(&b.confidence) {
        return Err(BoxError::Confidence(b.confidence));
    }
    let label = match b.class {
        None => String::new(),
        Some(serde_json::Value::String(s)) if s.chars().count() <= 64 => s,
        Some(serde_json::Value::Number(n)) if n.as_u64().is_some_and(|n| n < 65536) => {
            n.to_string()
        }
        Some(other) => return Err(BoxError::Class(other)),
    };
    let finite = |v: f64, name: &'static str| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(BoxError::NotANumber(name))
        }
    };
    let place = match (b.x0, b.y0, b.x1, b.y1, b.yaw, b.pitch, b.width, b.height) {
        (Some(x0), Some(y0), Some(x1), Some(y1), None, None, None, None) => {
            let (x0, y0, x1, y1) = (
                finite(x0, "x0")?,
                finite(y0, "y0")?,
                finite(x1, "x1")?,
                finite(y1, "y1")?,
            );
            if x1 <= x0 || y1 <= y0 {
                return Err(BoxError::Corners);
            }
            Place::Pixels { x0, y0, x1, y1 }
        }
        (None, None, None, None, Some(yaw), Some(pitch), Some(width), Some(height)) => {
            let (yaw, pitch) = (finite(yaw, "yaw")?, finite(pitch, "pitch")?);
            let (width, height) = (finite(width, "width")?, finite(height, "height")?);
            if !(-90.0..=90.0).contains(&pitch) {
                return Err(BoxError::Pitch(pitch));
            }
            if !(width > 0.0 && width <= 180.0 && height > 0.0 && height <= 180.0) {
                return Err(BoxError::Size);
            }
            Place::Angles {
                yaw: yaw.to_radians(),
                pitch: pitch.to_radians(),
                width: width.to_radians(),
                height: height.to_radians(),
            }
        }
        _ => return Err(BoxError::Place),
    };
    Ok(ExternalBox {
        place,
        confidence: b.confidence,
        label,
    })
}

/// What the socket's connections have sent, newest line first-come: the detection thread
/// takes the newest batch (with when it arrived), older ones not yet taken are replaced.
#[derive(Default)]
pub struct Inbox {
    batch: Mutex<Option<(Batch, Instant)>>,
    ready: Condvar,
}

impl Inbox {
    fn put(&self, batch: Batch) {
        *self.batch.locked() = Some((batch, Instant::now()));
        self.ready.notify_one();
    }

    /// The newest batch, waiting up to `wait` for one.
    pub fn take(&self, wait: Duration) -> Option<(Batch, Instant)> {
        let guard = self.batch.locked();
        let (mut guard, _) = self
            .ready
            .wait_timeout_while(guard, wait, |b| b.is_none())
            .unwrap_or_else(|e| e.into_inner());
        guard.take()
    }
}

/// Listens on `path` (a stale socket left there is replaced; any other file is an error)
/// until `stop`, each connection on a thread of its own.
pub fn listen(path: &Path, inbox: Arc<Inbox>, stop: Arc<AtomicBool>) -> std::io::Result<()> {
    if path.exists() {
        let in_use = UnixStream::connect(path).is_ok();
        let is_socket = std::fs::symlink_metadata(path).is_ok_and(|m| {
            use std::os::unix::fs::FileTypeExt;
            m.file_type().is_socket()
        });
        if in_use || !is_socket {
            return Err(std::io::Error::new(
                std::io::ErrorKind::AddrInUse,
                format!(
                    "{} is in use (another process, or not a socket)",
                    path.display()
                ),
            ));
        }
        std::fs::remove_file(path)?;
    }
    let listener = UnixListener::bind(path)?;
    listener.set_nonblocking(true)?;
    let path: PathBuf = path.to_path_buf();
    std::thread::Builder::new()
        .name("detections".into())
        .spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        let (inbox, stop) = (inbox.clone(), stop.clone());
                        let _ = std::thread::Builder::new()
                            .name("detections-in".into())
                            .spawn(move || serve_connection(stream, &inbox, &stop));
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                        std::thread::sleep(Duration::from_millis(50));
                    }
                    Err(e) => {
                        tracing::warn!("detections socket: {e}");
                        std::thread::sleep(Duration::from_millis(200));
                    }
                }
            }
            let _ = std::fs::remove_file(&path);
        })?;
    Ok(())
}

/// Reads lines until the sender goes or `stop`; each bad line is answered `error: ...`.
fn serve_connection(stream: UnixStream, inbox: &Inbox, stop: &AtomicBool) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let Ok(mut reply) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    let mut line = Vec::new();
    let mut number = 0u64;
    while !stop.load(Ordering::Relaxed) {
        let mut chunk = Vec::new();
        match reader
            .by_ref()
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut chunk)
        {
            Ok(0) => return,
            Ok(_) => line.extend_from_slice(&chunk),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                line.extend_from_slice(&chunk);
                continue;
            }
            Err(_) => return,
        }
        if line.len() > MAX_LINE {
            // Skip to the end of the over-long line, then say so.
            if !line.ends_with(b"\n") {
                line.clear();
                let mut rest = Vec::new();
                loop {
                    rest.clear();
                    match reader
                        .by_ref()
                        .take(MAX_LINE as u64)
                        .read_until(b'\n', &mut rest)
                    {
                        Ok(0) => return,
                        Ok(_) if rest.ends_with(b"\n") => break,
                        Ok(_) => continue,
                        Err(_) if stop.load(Ordering::Relaxed) => return,
                        Err(_) => continue,
                    }
                }
            }
            number += 1;
            line.clear();
            let _ = writeln!(reply, "error: line {number}: longer than {MAX_LINE} bytes");
            continue;
        }
        if !line.ends_with(b"\n") {
            continue;
        }
        number += 1;
        let text = String::from_utf8_lossy(&line).trim().to_string();
        line.clear();
        if text.is_empty() {
            continue;
        }
        match parse(&text) {
            Ok(batch) => inbox.put(batch),
            Err(e) => {
                let _ = writeln!(reply, "error: line {number}: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_read_in_either_form_and_bad_ones_say_why() {
        let b = parse(
            r#"{"t": 1.5, "boxes": [{"x0": 10, "y0": 20, "x1": 30, "y1": 60, "confidence": 0.8, "class": "person"},
                {"yaw": 30, "pitch": -40, "width": 4, "height": 2, "confidence": 0.5, "class": 7}]}"#,
        )
        .unwrap();
        assert_eq!(b.t, Some(1.5));
        assert_eq!(b.boxes[0].label, "person");
        assert_eq!(
            b.boxes[0].place,
            Place::Pixels {
                x0: 10.0,
                y0: 20.0,
                x1: 30.0,
                y1: 60.0
            }
        );
        assert_eq!(b.boxes[1].label, "7");
        assert!(
            matches!(b.boxes[1].place, Place::Angles { pitch, .. } if (pitch + 40f64.to_radians()).abs() < 1e-12)
        );
        assert!(parse(r#"{"boxes": []}"#).unwrap().boxes.is_empty());
        for (line, says) in [
            ("not json", "expected"),
            (
                r#"{"boxes": [{"x0": 1, "y0": 1, "x1": 0, "y1": 2, "confidence": 0.5}]}"#,
                "box 0: x1, y1",
            ),
            (
                r#"{"boxes": [{"x0": 1, "y0": 1, "confidence": 0.5}]}"#,
                "give x0",
            ),
            (
                r#"{"boxes": [{"x0": 1, "y0": 1, "x1": 2, "y1": 2, "yaw": 3, "confidence": 0.5}]}"#,
                "give x0",
            ),
            (
                r#"{"boxes": [{"yaw": 0, "pitch": 95, "width": 1, "height": 1, "confidence": 0.5}]}"#,
                "pitch 95",
            ),
            (
                r#"{"boxes": [{"yaw": 0, "pitch": 0, "width": 0, "height": 1, "confidence": 0.5}]}"#,
                "width and height",
            ),
            (
                r#"{"boxes": [{"yaw": 0, "pitch": 0, "width": 1, "height": 1, "confidence": 1.5}]}"#,
                "confidence 1.5",
            ),
            (
                r#"{"boxes": [{"yaw": 0, "pitch": 0, "width": 1, "height": 1, "confidence": 0.5, "class": [1]}]}"#,
                "class [1]",
            ),
            (r#"{"boxes": [], "extra": 1}"#, "unknown field"),
        ] {
            let e = parse(line).unwrap_err().to_string();
            assert!(e.contains(says), "{line}: {e}");
        }
        let many = format!(
            r#"{{"boxes": [{}]}}"#,
            vec![
                r#"{"yaw": 0, "pitch": 0, "width": 1, "height": 1, "confidence": 0.5}"#;
                MAX_BOXES + 1
            ]
            .join(",")
        );
        assert!(parse(&many).unwrap_err().to_string().contains("at most"));
    }

    proptest::proptest! {
        /// Whatever a sender writes, a line is read or refused, never a panic.
        #[test]
        fn any_line_is_read_or_refused(line in ".{0,300}") {
            let _ = parse(&line);
        }

        #[test]
        fn any_box_numbers_are_read_or_refused(
            v in proptest::collection::vec(proptest::num::f64::ANY, 8),
            confidence in proptest::num::f64::ANY,
        ) {
            let num = |x: f64| serde_json::Number::from_f64(x).map_or(serde_json::Value::Null, Into::into);
            let pixels = serde_json::json!({"boxes": [{"x0": num(v[0]), "y0": num(v[1]),
                "x1": num(v[2]), "y1": num(v[3]), "confidence": num(confidence)}]});
            let angles = serde_json::json!({"boxes": [{"yaw": num(v[4]), "pitch": num(v[5]),
                "width": num(v[6]), "height": num(v[7]), "confidence": num(confidence)}]});
            for line in [pixels, angles] {
                if let Ok(b) = parse(&line.to_string()) {
                    let b = &b.boxes[0];
                    proptest::prop_assert!((0.0..=1.0).contains(&b.confidence));
                    if let Place::Angles { pitch, width, .. } = b.place {
                        proptest::prop_assert!(pitch.abs() <= std::f64::consts::FRAC_PI_2 + 1e-12);
                        proptest::prop_assert!(width > 0.0);
                    }
                }
            }
        }
    }
}
