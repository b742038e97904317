//! GET and SET of the whole-system parameter types: SYSTEM_STATUS, VIDEO_OUTPUT, CAPTURE,
//! LENS, CAM_SENSOR, GENERAL_SETTINGS and THERMAL, with the seed's rules field by field.

use super::Refusal;
use crate::layout::{Rect, TILE_SIZE};
use crate::lens::Lenses;
use crate::modes::{LayoutMode, OverlayMode};
use crate::protocol::params::{
    CamSensor, Capture, GeneralSettings, Lens, SystemStatus, Thermal, VideoOutput,
};
use crate::protocol::{BoundingBox, ViewBoxes};
use crate::state::capture::Capturer;
use crate::state::rules::*;
use crate::state::{Report, Settings, ThermalGain};
use crate::thermal::Palette;
use tracing::warn;

pub fn system_status(report: &Report) -> SystemStatus {
    SystemStatus {
        status: report.status() as u8,
        error: report.failure(),
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
pub fn video_output(settings: &Settings) -> Result<VideoOutput, Refusal> {
    let o = &settings.output;
    let l = o.layout().map_err(Refusal::data)?;
    let views = ViewBoxes::new(l.views.iter().map(|(rect, _)| bbox(*rect)));
    Ok(VideoOutput {
        width: o.width as u16,
        height: o.height as u16,
        fps: o.fps as u8,
        layout_mode: o.layout.code(),
        detection_overlay_mode: o.overlay.code(),
        views,
        detection_overlay_box: bbox(l.overlay_box),
        single_detection_size: TILE_SIZE as u16,
    })
}

/// Width and height above the maximum are clamped; below the minimum the size change is
/// ignored (both kept, so the frame never gets an unasked-for shape). Sizes are rounded down
/// to even numbers for 4:2:0 video. fps is clamped; an unknown layout or overlay is ignored.
pub fn set_video_output(s: &mut Settings, p: &VideoOutput) -> Result<(), Refusal> {
    // Each field as its rule has the protocol take it; width and height together (one below
    // its minimum keeps both: the frame never gets an unasked-for shape).
    let o = &mut s.output;
    let (w, h) = (
        OUTPUT_WIDTH.take(p.width as f64, 0.0),
        OUTPUT_HEIGHT.take(p.height as f64, 0.0),
    );
    if w > 0.0 && h > 0.0 {
        (o.width, o.height) = (w as u32, h as u32);
    }
    o.fps = OUTPUT_FPS.take(p.fps as f64, o.fps as f64) as u32;
    let layout = OUTPUT_LAYOUT.take(p.layout_mode as f64, o.layout.code() as f64) as u8;
    let overlay = OUTPUT_OVERLAY.take(p.detection_overlay_mode as f64, o.overlay.code() as f64);
    o.layout = LayoutMode::try_from(layout)?;
    o.overlay = OverlayMode::try_from(overlay as u8)?;
    o.even();
    o.layout().map(|_| ()).map_err(Refusal::data)
}

pub fn capture(capture: &dyn Capturer) -> Capture {
    let c = capture.status();
    Capture {
        flags: (c.recording as u8) << 1,
        images_captured: c.images,
        videos_captured: c.videos,
    }
}

/// Bit 0 takes one still; bit 1 starts (1) or stops (0) recording.
pub fn set_capture(capture: &dyn Capturer, p: &Capture) -> Result<(), Refusal> {
    if p.flags & 1 != 0 {
        capture.still().map_err(Refusal::data)?;
    }
    capture.record(p.flags & 2 != 0).map_err(Refusal::data)
}

pub fn lens(settings: &Settings) -> Lens {
    Lens {
        lens_id: settings.lens,
    }
}

/// A lens_id that lens.cal does not have is refused.
pub fn set_lens(lenses: &Lenses, s: &mut Settings, p: &Lens) -> Result<(), Refusal> {
    if lenses.get(p.lens_id).is_none() {
        return Err(Refusal::Data(format!(
            "lens_id {} is not in lens.cal",
            p.lens_id
        )));
    }
    s.lens = p.lens_id;
    Ok(())
}

pub fn sensor(settings: &Settings) -> CamSensor {
    let s = &settings.sensor;
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
pub fn set_sensor(report: &Report, s: &mut Settings, p: &CamSensor) -> Result<(), Refusal> {
    if let Some(why) = report.sensor_refusal() {
        warn!("CAM_SENSOR SET refused: {why}");
        return Err(Refusal::Data(why));
    }
    let longest = s.sensor.longest_exposure_us();
    let sensor = &mut s.sensor;
    sensor.ae = SENSOR_AE.take(p.ae as f64, sensor.ae as u8 as f64) != 0.0;
    sensor.target_brightness =
        SENSOR_BRIGHTNESS.take(p.target_brightness as f64, sensor.target_brightness as f64) as u8;
    let exposure = SENSOR_EXPOSURE.take(p.exposure_value as f64, 0.0) as u32;
    sensor.exposure_us = exposure.min(longest);
    sensor.gain = SENSOR_GAIN.take(p.gain_value as f64, sensor.gain as f64) as u32;
    Ok(())
}

pub fn general(settings: &Settings) -> GeneralSettings {
    let s = &settings.sensor;
    let (roi_width, roi_height) = s.roi.map_or((0, 0), |[_, _, w, h]| (w as u16, h as u16));
    GeneralSettings {
        camera_width: s.width as u16,
        camera_height: s.height as u16,
        roi_width,
        roi_height,
        camera_fps: s.fps as u8,
        mount_yaw: settings.mount.yaw,
        mount_pitch: settings.mount.pitch,
        mount_roll: settings.mount.roll,
        run_ai: settings.detection.run_ai as u8,
    }
}

/// Camera size 1..=8192 and fps 1..=240, or the message is refused. A ROI of 0x0 means no
/// sensor crop; otherwise it is centred in the lens's calibration frame and must fit in it.
/// Mount yaw wraps, pitch and roll are taken as given; any non-zero run_ai is on.
pub fn set_general(lenses: &Lenses, s: &mut Settings, p: &GeneralSettings) -> Result<(), Refusal> {
    // The camera's size and rate, and whether the crop fits the lens's calibration frame,
    // are `Settings::validate`'s to refuse, as from every other entry.
    let roi = match (p.roi_width as u32, p.roi_height as u32) {
        (0, 0) => None,
        (w, h) => {
            let lens = lenses
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
    s.mount.yaw = MOUNT_YAW.take(p.mount_yaw, s.mount.yaw);
    s.mount.pitch = p.mount_pitch;
    s.mount.roll = p.mount_roll;
    s.detection.run_ai = DETECTION_RUN.take(p.run_ai as f64, 0.0) != 0.0;
    Ok(())
}

pub fn thermal(settings: &Settings) -> Thermal {
    let t = &settings.thermal;
    Thermal {
        palette: t.palette.code(),
        gain: t.gain as u8,
        span_low: t.low,
        span_high: t.high,
        blend: t.blend,
        zoom: t.zoom,
    }
}

/// A palette or gain that does not exist, or a span outside 0..=2000 K or not rising, is
/// refused (the span by `Settings::validate`, as from every entry); the blend and the zoom
/// are clamped.
pub fn set_thermal(s: &mut Settings, p: &Thermal) -> Result<(), Refusal> {
    let t = &mut s.thermal;
    t.palette = Palette::try_from(p.palette)?;
    t.gain = ThermalGain::try_from(p.gain)?;
    (t.low, t.high) = (p.span_low, p.span_high);
    t.blend = THERMAL_BLEND.take(p.blend, t.blend);
    t.zoom = THERMAL_ZOOM.take(p.zoom as f64, t.zoom as f64) as u8;
    Ok(())
}
