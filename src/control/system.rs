//! GET and SET of the whole-system parameter types: SYSTEM_STATUS, VIDEO_OUTPUT, CAPTURE,
//! LENS, CAM_SENSOR and GENERAL_SETTINGS, with the seed's rules field by field.

use super::Refusal;
use crate::layout::{Rect, TILE_SIZE, layout};
use crate::protocol::ParamType;
use crate::protocol::params::{
    CamSensor, Capture, GeneralSettings, Lens, SystemStatus, VideoOutput,
};
use crate::protocol::{BoundingBox, ViewBoxes};
use crate::state::{Live, State, rules};
use tracing::warn;

pub fn system_status(live: &Live) -> SystemStatus {
    SystemStatus {
        status: live.status() as u8,
        error: live.failure(),
    }
}

fn bbox(r: Rect) -> BoundingBox {
    // Rectangles lie inside a frame of at most 1920x1080, so they fit u16.
    BoundingBox {
        x: r.x as u16,
        y: r.y as u16,
        w: r.w as u16,
        h: r.h as u16,
    }
}

/// The output and the rectangles the renderer draws.
pub fn video_output(state: &State) -> Result<VideoOutput, Refusal> {
    let o = &state.output;
    let l = layout(o.width, o.height, o.layout, o.overlay).map_err(Refusal::data)?;
    let views = ViewBoxes::new(l.views.iter().map(|(rect, _)| bbox(*rect)));
    Ok(VideoOutput {
        width: o.width as u16,
        height: o.height as u16,
        fps: o.fps as u8,
        layout_mode: o.layout,
        detection_overlay_mode: o.overlay,
        views,
        detection_overlay_box: bbox(l.overlay_box),
        single_detection_size: TILE_SIZE as u16,
    })
}

/// Width and height above the maximum are clamped; below the minimum the size change is
/// ignored (both kept, so the frame never gets an unasked-for shape). Sizes are rounded down
/// to even numbers for 4:2:0 video. fps is clamped; an unknown layout or overlay is ignored.
pub fn set_video_output(s: &mut State, p: &VideoOutput) -> Result<(), Refusal> {
    // Each field as its rule has the protocol take it; width and height together (one below
    // its minimum keeps both: the frame never gets an unasked-for shape).
    let take = |field: &str, v: f64, was: f64| rules::take(ParamType::VideoOutput, field, v, was);
    let o = &mut s.output;
    let (w, h) = (
        take("width", p.width as f64, 0.0),
        take("height", p.height as f64, 0.0),
    );
    if w > 0.0 && h > 0.0 {
        (o.width, o.height) = (w as u32, h as u32);
    }
    o.fps = take("fps", p.fps as f64, o.fps as f64) as u32;
    o.layout = take("layout_mode", p.layout_mode as f64, o.layout as f64) as u8;
    o.overlay = take(
        "detection_overlay_mode",
        p.detection_overlay_mode as f64,
        o.overlay as f64,
    ) as u8;
    s.even_output();
    let o = &s.output;
    layout(o.width, o.height, o.layout, o.overlay)
        .map(|_| ())
        .map_err(Refusal::data)
}

pub fn capture(live: &Live) -> Capture {
    let c = live.capture().status();
    Capture {
        flags: (c.recording as u8) << 1,
        images_captured: c.images,
        videos_captured: c.videos,
    }
}

/// Bit 0 takes one still; bit 1 starts (1) or stops (0) recording.
pub fn set_capture(live: &Live, p: &Capture) -> Result<(), Refusal> {
    if p.flags & 1 != 0 {
        live.capture().still().map_err(Refusal::data)?;
    }
    live.capture()
        .record(p.flags & 2 != 0)
        .map_err(Refusal::data)
}

pub fn lens(state: &State) -> Lens {
    Lens {
        lens_id: state.lens,
    }
}

/// A lens_id that lens.cal does not have is refused.
pub fn set_lens(live: &Live, s: &mut State, p: &Lens) -> Result<(), Refusal> {
    if live.lenses().get(p.lens_id).is_none() {
        return Err(Refusal::Data(format!(
            "lens_id {} is not in lens.cal",
            p.lens_id
        )));
    }
    s.lens = p.lens_id;
    Ok(())
}

pub fn sensor(state: &State) -> CamSensor {
    let s = &state.sensor;
    CamSensor {
        ae: s.ae as u8,
        target_brightness: s.target_brightness,
        exposure_value: s.exposure_us,
        gain_value: s.gain,
    }
}

/// Any non-zero ae is on. Brightness, exposure and gain are clamped into the seed's open
/// ranges; exposure also to the camera's frame time. Refused for a source with no exposure to
/// set (a file, an image), saying why.
pub fn set_sensor(live: &Live, s: &mut State, p: &CamSensor) -> Result<(), Refusal> {
    if let Some(why) = live.sensor_refusal() {
        warn!("CAM_SENSOR SET refused: {why}");
        return Err(Refusal::Data(why));
    }
    let longest = s.sensor.longest_exposure_us();
    let take = |field: &str, v: f64, was: f64| rules::take(ParamType::CamSensor, field, v, was);
    let sensor = &mut s.sensor;
    sensor.ae = take("ae", p.ae as f64, sensor.ae as u8 as f64) != 0.0;
    sensor.target_brightness = take(
        "target_brightness",
        p.target_brightness as f64,
        sensor.target_brightness as f64,
    ) as u8;
    let exposure = take("exposure_value", p.exposure_value as f64, 0.0) as u32;
    sensor.exposure_us = exposure.min(longest);
    sensor.gain = take("gain_value", p.gain_value as f64, sensor.gain as f64) as u32;
    Ok(())
}

pub fn general(state: &State) -> GeneralSettings {
    let s = &state.sensor;
    let (roi_width, roi_height) = s.roi.map_or((0, 0), |[_, _, w, h]| (w as u16, h as u16));
    GeneralSettings {
        camera_width: s.width as u16,
        camera_height: s.height as u16,
        roi_width,
        roi_height,
        camera_fps: s.fps as u8,
        mount_yaw: state.mount.yaw,
        mount_pitch: state.mount.pitch,
        mount_roll: state.mount.roll,
        run_ai: state.detection.run_ai as u8,
    }
}

/// Camera size 1..=8192 and fps 1..=240, or the message is refused. A ROI of 0x0 means no
/// sensor crop; otherwise it is centred in the lens's calibration frame and must fit in it.
/// Mount yaw wraps, pitch and roll are taken as given; any non-zero run_ai is on.
pub fn set_general(live: &Live, s: &mut State, p: &GeneralSettings) -> Result<(), Refusal> {
    // The camera's size and rate, and whether the crop fits the lens's calibration frame,
    // are `State::validate`'s to refuse, as from every other entry.
    let roi = match (p.roi_width as u32, p.roi_height as u32) {
        (0, 0) => None,
        (w, h) => {
            let lens = live
                .lenses()
                .get(s.lens)
                .ok_or_else(|| Refusal::data("the state's lens is not in lens.cal"))?;
            let (cw, ch) = (lens.width, lens.height);
            Some([cw.saturating_sub(w) / 2, ch.saturating_sub(h) / 2, w, h])
        }
    };
    s.sensor.width = p.camera_width as u32;
    s.sensor.height = p.camera_height as u32;
    s.sensor.fps = p.camera_fps as u32;
    // A faster camera has a shorter frame: the exposure follows it down.
    s.sensor.exposure_us = s.sensor.exposure_us.min(s.sensor.longest_exposure_us());
    s.sensor.roi = roi;
    s.mount.yaw = rules::take(
        ParamType::GeneralSettings,
        "mount_yaw",
        p.mount_yaw,
        s.mount.yaw,
    );
    s.mount.pitch = p.mount_pitch;
    s.mount.roll = p.mount_roll;
    s.detection.run_ai =
        rules::take(ParamType::GeneralSettings, "run_ai", p.run_ai as f64, 0.0) != 0.0;
    Ok(())
}
