//! Which encoder starts: for `kind = "auto"` the hardware encoders GStreamer has whose device
//! is present, best first, then the software one; each given [`START_DEADLINE`] to start. A
//! hardware encoder's driver that hangs opening a device it does not have (a peer project saw
//! a Jetson Orin Nano's, which has no encoder, do so) is abandoned, its thread left blocked,
//! and the next one is tried; the log says what was tried and why each was passed over.

use super::Codec;
use crate::gst::{GstError, set_state};
use crate::supervise::Locked;
use gstreamer as gst;
use std::path::Path;
use std::sync::{Mutex, mpsc};
use std::time::Duration;

/// Hardware encoders tried before the software one when `kind` is "auto", best first:
/// Jetson's, NVIDIA's NVENC on a desktop or server GPU (GStreamer's nvcodec plugin registers
/// it only where the driver has an encoder: not on an H100 or H200, which have none),
/// VA-API's, V4L2's.
pub const HARDWARE: [&str; 4] = ["nvv4l2h264enc", "nvh264enc", "vaapih264enc", "v4l2h264enc"];
/// The same for H.265.
pub const HARDWARE_H265: [&str; 4] = ["nvv4l2h265enc", "nvh265enc", "vaapih265enc", "v4l2h265enc"];

/// How long an encoder may take to start before the next is tried.
pub const START_DEADLINE: Duration = Duration::from_secs(5);

/// The hardware encoders for `codec`, best first, and the software one.
pub fn encoders(codec: Codec) -> (&'static [&'static str; 4], &'static str) {
    match codec {
        Codec::H264 => (&HARDWARE, "x264enc"),
        Codec::H265 => (&HARDWARE_H265, "x265enc"),
    }
}

/// The encoders to try for `kind` and `codec`, in order; `usable` says whether a hardware
/// encoder is installed and its device present ([`usable`]).
pub fn candidates(kind: &str, codec: Codec, usable: impl Fn(&str) -> bool) -> Vec<String> {
    let (hardware, software) = encoders(codec);
    match kind {
        "auto" => hardware
            .iter()
            .filter(|n| usable(n))
            .map(|n| n.to_string())
            .chain([software.to_string()])
            .collect(),
        "x264" | "x265" => vec![format!("{kind}enc")],
        other => vec![other.to_string()],
    }
}

/// Whether GStreamer has encoder `name` and the device it drives is there: a Jetson's
/// encoder (`/dev/v4l2-nvenc` from L4T 32.5 on, `/dev/nvhost-msenc` before; an Orin Nano
/// has neither), a VA-API render node. Checked without opening anything.
pub fn usable(name: &str) -> bool {
    gst::ElementFactory::find(name).is_some() && device_present(name, |p| Path::new(p).exists())
}

/// Whether the device encoder `name` drives is there, as `exists` finds paths.
fn device_present(name: &str, exists: impl Fn(&str) -> bool) -> bool {
    if name.starts_with("nvv4l2") {
        return ["/dev/v4l2-nvenc", "/dev/nvhost-msenc"]
            .iter()
            .any(|p| exists(p));
    }
    if name.starts_with("vaapi") {
        return (128..136).any(|n| exists(&format!("/dev/dri/renderD{n}")));
    }
    true
}

/// The encoders that hung starting in this process: not tried again (each try would leave
/// another thread waiting and keep a new viewer's stream waiting the deadline).
static HUNG: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Notes that encoder `name` hung starting.
pub fn hung(name: &str) {
    HUNG.locked().push(name.to_string());
}

/// Whether encoder `name` hung starting before.
pub fn has_hung(name: &str) -> bool {
    HUNG.locked().iter().any(|n| n == name)
}

/// Sets `pipeline` playing, giving up after `deadline`: Err(None) when it did not return in
/// time (the thread that waits on it is left behind), Err(Some) when it refused.
pub fn play_within(pipeline: &gst::Pipeline, deadline: Duration) -> Result<(), Option<GstError>> {
    let play = |p: &gst::Pipeline| set_state(p, gst::State::Playing, || "would not start".into());
    let (tx, rx) = mpsc::channel();
    let waiting = pipeline.clone();
    let started = std::thread::Builder::new()
        .name("encoder start".into())
        .spawn(move || {
            let _ = tx.send(play(&waiting));
        });
    if started.is_err() {
        return play(pipeline).map_err(Some);
    }
    match rx.recv_timeout(deadline) {
        Ok(done) => done.map_err(Some),
        Err(_) => Err(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_tries_the_usable_hardware_encoders_best_first_then_x264() {
        let only = |names: &'static [&'static str]| move |n: &str| names.contains(&n);
        let h264 = Codec::H264;
        assert_eq!(candidates("auto", h264, only(&[])), ["x264enc"]);
        // A desktop NVIDIA GPU with NVENC, and VA-API beside it: NVENC first.
        assert_eq!(
            candidates("auto", h264, only(&["vaapih264enc", "nvh264enc"])),
            ["nvh264enc", "vaapih264enc", "x264enc"]
        );
        // A Jetson's own encoder before the desktop one.
        assert_eq!(
            candidates("auto", h264, only(&["nvh264enc", "nvv4l2h264enc"]))[0],
            "nvv4l2h264enc"
        );
        // A named kind is tried alone, installed or not (its error then says so).
        assert_eq!(candidates("x264", h264, only(&["nvh264enc"])), ["x264enc"]);
        assert_eq!(candidates("nvh264enc", h264, only(&[])), ["nvh264enc"]);
        // H.265: its own hardware encoders, then x265; the H.264 ones are not taken.
        let h265 = Codec::H265;
        assert_eq!(
            candidates("auto", h265, only(&["nvh264enc", "nvh265enc"])),
            ["nvh265enc", "x265enc"]
        );
        assert_eq!(candidates("auto", h265, only(&[])), ["x265enc"]);
    }

    #[test]
    fn a_jetson_encoder_without_its_device_and_vaapi_without_a_render_node_are_passed_over() {
        let on = |paths: &'static [&'static str]| move |p: &str| paths.contains(&p);
        // An Orin Nano: L4T's encoder plugin installed, no encoder device.
        assert!(!device_present("nvv4l2h264enc", on(&["/dev/nvhost-nvdec"])));
        assert!(device_present("nvv4l2h265enc", on(&["/dev/v4l2-nvenc"])));
        assert!(device_present("nvv4l2h264enc", on(&["/dev/nvhost-msenc"])));
        assert!(!device_present("vaapih264enc", on(&["/dev/dri/card0"])));
        assert!(device_present("vaapih264enc", on(&["/dev/dri/renderD129"])));
        // NVENC's plugin registers only with an encoder; V4L2's per encoder device.
        assert!(device_present("nvh264enc", on(&[])));
        assert!(device_present("v4l2h264enc", on(&[])));
    }
}
