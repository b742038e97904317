//! How the thermal picture is coloured, set on each control path and seen in camera 0's own
//! stream as FFmpeg decodes it: the demo's thermal camera looks at the car whose engine bay
//! is the hottest thing it sees, and view 0 shows it. A palette and a span set over the
//! DigiView protocol (`digiview ctl`), a palette and the automatic gain over the web API, and
//! a palette over MAVLink as a pymavlink ground station sets it (PALETTE), each colour the
//! decoded picture as the CPU reference does (≥ 30 dB through the encoder, and ≥ 10 dB
//! nearer it than to any other palette's or to the look before), as does a 2x zoom, whose field the view's stream then gives; the blend share set over the protocol is the thermal colour's share of each
//! blended pixel (within 0.05); and a span that does not rise, or a palette that does not
//! exist, is refused with the reason and changes nothing.

use crate::common;
use common::gpu::as_format;
use common::peers::LinePeer;
use common::thermal::{
    SIZE, aimed, decoded, engine_ray, engine_serve, luma, mount_towards, reference_layer,
};
use digiview::frame::{PixelFormat, yuv};
use digiview::geometry::Euler;
use digiview::image_ops::psnr;
use digiview::lens::Lenses;
use digiview::modes::ThermalShow;
use digiview::plan::FramePlan;
use digiview::state::{State, ThermalGain, ThermalLook};
use digiview::thermal::Palette;
use image::RgbImage;
use serde_json::{Value, json};
use std::time::Duration;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The head, what view 0 is, and where to reach it.
struct Head {
    serve: common::serve::Serve,
    station: LinePeer,
    state: State,
    plan: FramePlan,
    mount: Euler,
}

impl Head {
    fn url(&self) -> String {
        format!("{}/cam0", self.serve.rtsp.clone().unwrap())
    }

    /// `digiview ctl` with `args`: whether it was taken, and what it said on stderr.
    fn ctl(&self, args: &[&str]) -> (bool, String) {
        let out = common::ctl(&self.serve.addr.to_string(), args);
        let said = String::from_utf8_lossy(&out.stderr).to_string();
        (out.status.success(), said)
    }

    /// THERMAL as the DigiView protocol reads it.
    fn thermal(&self) -> Value {
        let out = common::ctl(&self.serve.addr.to_string(), &["--json", "get", "thermal"]);
        let read: Value = serde_json::from_slice(&out.stdout).unwrap();
        read["values"].clone()
    }

    /// A PUT to the web API: its status and answer.
    fn put(&self, name: &str, body: Value) -> (u16, Value) {
        let http = self.serve.http.clone().unwrap();
        let host = http.trim_start_matches("http://").trim_end_matches('/');
        let path = format!("/api/params/{name}");
        let (code, text) =
            common::raw_request(host, "PUT", &path, &[("Host", host)], &body.to_string()).unwrap();
        (code, serde_json::from_str(&text).unwrap_or(Value::Null))
    }

    /// Camera 0's stream a moment after a change (thermal frames come 9 times a second).
    fn settled(&self) -> RgbImage {
        std::thread::sleep(Duration::from_millis(1500));
        decoded(&self.url())
    }

    /// The CPU reference of view 0 showing the thermal picture `show`'s way in `look` over
    /// `under`, and the rectangle it covers.
    fn reference(
        &self,
        show: ThermalShow,
        look: &ThermalLook,
        under: RgbImage,
    ) -> (RgbImage, digiview::layout::Rect) {
        let layer = reference_layer(&self.plan, &self.state, show, self.mount, look);
        let mut picture = under;
        layer.draw_rgb(&mut picture);
        (picture, layer.entries[0].rect)
    }

    /// How near `frame` (view 0 showing the thermal picture alone) is to the reference in
    /// `look`, dB: the reference through the 4:2:0 the stream takes (a palette's saturated
    /// colours lose their sharp chroma edges there, the rest is the encoder's).
    fn likeness(&self, frame: &RgbImage, look: &ThermalLook) -> f64 {
        let black = RgbImage::new(SIZE.0, SIZE.1);
        let (want, rect) = self.reference(ThermalShow::Thermal, look, black);
        let (data, layout) = as_format(&want, PixelFormat::I420);
        psnr(frame, &yuv::decode(&data, &layout).unwrap(), rect)
    }
}

fn start() -> Head {
    let state = State::default();
    let ray = engine_ray(&state);
    let mount = mount_towards(&state, ray);
    // View 0 a little beside the engine, which stands off its middle.
    let (yaw, pitch) = (ray.y.atan2(ray.x) - 8.0 * DEG, -ray.z.asin() + 5.0 * DEG);
    let (serve, station, _) = engine_serve(mount, (yaw, pitch));
    let state = aimed(&state, yaw, pitch);
    let fisheye = Lenses::new(&common::lens_cal())
        .for_frame(0, SIZE, None)
        .unwrap();
    let plan = FramePlan::single_view(&state, &fisheye, 0, SIZE.0, SIZE.1);
    Head {
        serve,
        station,
        state,
        plan,
        mount,
    }
}

/// `frame` is coloured in `look`: nearer its reference than any other palette's under the
/// same gain by 10 dB at least, and 30 dB near it (through x264 at the view stream's rate a
/// busy saturated picture, the rainbow under the automatic gain, keeps about 34 dB; the
/// palettes themselves are held to 45 dB before the encoder, tests/it/thermal.rs); and no
/// longer in `before`.
fn coloured_as(
    head: &Head,
    frame: &RgbImage,
    look: &ThermalLook,
    before: &ThermalLook,
    path: &str,
) {
    let db = head.likeness(frame, look);
    let was = head.likeness(frame, before);
    let others = Palette::ALL
        .into_iter()
        .filter(|&p| p != look.palette)
        .map(|palette| head.likeness(frame, &ThermalLook { palette, ..*look }))
        .fold(f64::MIN, f64::max);
    eprintln!(
        "{path}: {} under {:?}: {db:.1} dB against its reference, {others:.1} dB at most \
         against another palette's, {was:.1} dB against the look before",
        look.palette.name(),
        look.gain
    );
    assert!(db >= 30.0, "{path}: {db:.1} dB");
    assert!(
        others + 10.0 <= db,
        "{path}: {others:.1} dB against another palette"
    );
    assert!(
        was + 10.0 <= db,
        "{path}: {was:.1} dB against the look before"
    );
}

/// The least-squares share of the thermal colour in `blended` over `off`, where `thermal` is
/// the thermal colour wherever the thermal camera sees (and `off` elsewhere), in luma.
fn share(blended: &RgbImage, off: &RgbImage, thermal: &RgbImage) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for y in 0..SIZE.1 {
        for x in 0..SIZE.0 {
            let t = luma(thermal, x, y) - luma(off, x, y);
            num += (luma(blended, x, y) - luma(off, x, y)) * t;
            den += t * t;
        }
    }
    num / den
}

#[test]
fn the_palette_gain_and_blend_set_on_each_control_path_colour_the_stream_as_the_reference() {
    let _alone = crate::one_at_a_time();
    let mut head = start();
    assert!(head.ctl(&["set", "cam_thermal", "cam=0", "show=3"]).0);
    let auto = ThermalLook::default();
    // The DigiView protocol: ironbow over 300 to 340 K.
    let set = ["palette=2", "gain=1", "span_low=300", "span_high=340"];
    let (taken, said) = head.ctl(&[&["set", "thermal"][..], &set].concat());
    assert!(taken, "{said}");
    let ironbow = ThermalLook {
        palette: Palette::Ironbow,
        gain: ThermalGain::Span,
        low: 300.0,
        high: 340.0,
        ..auto
    };
    coloured_as(&head, &head.settled(), &ironbow, &auto, "ctl");
    // The web API: black-hot under the automatic gain (the span kept).
    let (code, read) = head.put("THERMAL", json!({"palette": 1, "gain": 0}));
    assert_eq!(code, 200, "{read}");
    let black = ThermalLook {
        palette: Palette::BlackHot,
        gain: ThermalGain::Auto,
        ..ironbow
    };
    coloured_as(&head, &head.settled(), &black, &ironbow, "web API");
    // MAVLink's camera setting PALETTE, the one value every path reads.
    let heard = head
        .station
        .ask(&json!({"camera": 100, "setting": "PALETTE", "value": 3}));
    assert_eq!(
        (heard["ack"].clone(), heard["value"].clone()),
        (json!(0), json!(3))
    );
    assert_eq!(head.thermal()["palette"], 3);
    let rainbow = ThermalLook {
        palette: Palette::Rainbow,
        ..black
    };
    coloured_as(&head, &head.settled(), &rainbow, &black, "MAVLink");
    // The zoom: the middle half of the thermal frame fills the view, and the view's stream
    // says the field it shows now (VIDEO_STREAM_INFORMATION).
    assert!(head.ctl(&["set", "thermal", "zoom=2"]).0);
    let zoomed = ThermalLook { zoom: 2, ..rainbow };
    coloured_as(&head, &head.settled(), &zoomed, &rainbow, "zoom 2x");
    let heard = head.station.ask(&json!({"camera": 100, "streams": true}));
    let boson = Lenses::new(&common::lens_cal())
        .named("BOSON320")
        .unwrap()
        .hfov();
    let want = (2.0 * ((boson / 2.0).tan() / 2.0).atan())
        .to_degrees()
        .round();
    assert_eq!(heard["hfov"]["1"], want, "{heard}");
    assert!(head.ctl(&["set", "thermal", "zoom=1"]).0);
    // Refused, and nothing changed: a span that does not rise, a palette there is not.
    let before = head.thermal();
    let (taken, said) = head.ctl(&["set", "thermal", "span_low=350", "span_high=340"]);
    assert!(!taken && said.contains("span"), "{said}");
    let (code, read) = head.put("THERMAL", json!({"palette": 9}));
    assert_eq!(code, 422, "{read}");
    assert!(read.to_string().contains("palette"), "{read}");
    assert_eq!(head.thermal(), before);
    // The blend share: the thermal colour's part of each blended pixel, as set.
    assert!(head.ctl(&["set", "cam_thermal", "cam=0", "show=0"]).0);
    let off = head.settled();
    let full = ThermalLook {
        blend: 1.0,
        ..rainbow
    };
    let (thermal, _) = head.reference(ThermalShow::Blend, &full, off.clone());
    assert!(head.ctl(&["set", "cam_thermal", "cam=0", "show=1"]).0);
    for blend in [0.8, 0.3] {
        assert!(head.ctl(&["set", "thermal", &format!("blend={blend}")]).0);
        let got = share(&head.settled(), &off, &thermal);
        eprintln!("blend {blend}: the thermal colour is {got:.3} of each blended pixel");
        assert!((got - blend).abs() <= 0.05, "blend {blend}: {got:.3}");
    }
}
