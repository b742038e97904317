//! Every way into the state takes and refuses the same values: random values go in through
//! the command line's flags, a state file, a serve config file (naming that state file and a
//! lens) and the control protocol, and the outcomes are compared.
//!
//! The rule (docs/decisions.md, "Hardening"): the protocol follows the seed, which clamps
//! some values and drops others; a flag or a file never changes what the user typed, so it
//! takes exactly the values the protocol takes unchanged and refuses the rest with a reason.
//! The one change every path makes is rounding an odd output size down to even.

use crate::common;

use digiview::app::Config;
use digiview::cli::StateArgs;
use digiview::control::Controller;
use digiview::lens::LensCal;
use digiview::protocol::params::*;
use digiview::protocol::{Body, Message, Param, Verdict};
use digiview::state::State;
use proptest::prelude::*;
use std::net::{IpAddr, Ipv4Addr};

/// What one path made of a value: the state it produced, or its refusal.
pub(crate) type Outcome = Result<State, String>;

/// The control protocol: one SET from a loopback client on the default state.
pub(crate) fn by_protocol(cal: &LensCal, p: Param) -> Outcome {
    let c = Controller::direct(State::default(), cal);
    let frame = Message::new(Body::Set(p)).encode();
    let out = c.handle(&frame, IpAddr::V4(Ipv4Addr::LOCALHOST));
    match out.replies[0].body {
        Body::Verdict(Verdict::Acknowledgement, _) => Ok(c.state()),
        b => Err(format!("{b:?}")),
    }
}

/// Flags (as `render`, `synth` and `serve` take them) on the default state.
pub(crate) fn by_flags(cal: &LensCal, args: StateArgs) -> Outcome {
    args.state(cal).map_err(|e| format!("{e:#}"))
}

/// A state file with `toml` in it, read through `--state`.
pub(crate) fn by_state_file(cal: &LensCal, toml: &str) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.toml");
    std::fs::write(&path, toml).unwrap();
    let args = StateArgs {
        state: Some(path),
        ..StateArgs::default()
    };
    by_flags(cal, args)
}

/// A serve config naming a state file with `toml` in it, and optionally a lens.
pub(crate) fn by_config(cal: &LensCal, toml: &str, lens: Option<&str>) -> Outcome {
    let dir = tempfile::tempdir().unwrap();
    let state = dir.path().join("state.toml");
    std::fs::write(&state, toml).unwrap();
    let mut text = format!("state = {:?}\n", state.to_str().unwrap());
    if let Some(l) = lens {
        text = format!("lens = {l:?}\n{text}");
    }
    let cfg = Config::parse(&text).map_err(|e| e.to_string())?;
    let args = StateArgs {
        state: cfg.state,
        lens: cfg.lens,
        ..StateArgs::default()
    };
    by_flags(cal, args)
}

/// The paths agree: the file paths and the flags alike, and they take a value exactly when
/// the protocol takes it unchanged (`same` compares the part of the state the value set).
fn agree(
    protocol: Outcome,
    others: &[(&str, Outcome)],
    same: impl Fn(&State, &State) -> bool,
) -> Result<(), TestCaseError> {
    let (first, want) = &others[0];
    for (name, got) in &others[1..] {
        prop_assert_eq!(
            got.is_ok(),
            want.is_ok(),
            "{} {:?} vs {} {:?}",
            name,
            got,
            first,
            want
        );
    }
    match (want, &protocol) {
        (Ok(s), Ok(p)) => prop_assert!(same(s, p), "{first} {s:?}\nprotocol {p:?}"),
        (Ok(s), Err(e)) => prop_assert!(false, "{first} took {s:?}, the protocol refused: {e}"),
        // Refused by the user's paths: that the protocol took it only by changing it is the
        // caller's check.
        (Err(_), _) => {}
    }
    Ok(())
}

/// Reads back the field a case set.
type Reads = Box<dyn Fn(&State) -> f64>;

fn cal() -> LensCal {
    common::lens_cal()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn output_size_rate_layout_and_overlay(
        w in 0u32..2600, h in 0u32..1500, fps in 0u32..40, layout in 0u8..9, overlay in 0u8..8
    ) {
        let cal = cal();
        let protocol = by_protocol(&cal, Param::VideoOutput(VideoOutput {
            width: w as u16, height: h as u16, fps: fps as u8,
            layout_mode: layout, detection_overlay_mode: overlay,
            ..VideoOutput::default()
        }));
        let toml = format!(
            "[output]\nwidth = {w}\nheight = {h}\nfps = {fps}\nlayout = {layout}\noverlay = {overlay}\n"
        );
        let flags = StateArgs {
            size: Some((w, h)), fps: Some(fps), layout: Some(layout), overlay: Some(overlay),
            ..StateArgs::default()
        };
        let even = (w & !1, h & !1);
        let others = [
            ("flags", by_flags(&cal, flags)),
            ("state file", by_state_file(&cal, &toml)),
            ("config", by_config(&cal, &toml, None)),
        ];
        let same = |a: &State, b: &State| a.settings.output == b.settings.output;
        agree(protocol.clone(), &others, same)?;
        // The protocol changed nothing it was given (after rounding) exactly when the others
        // took it.
        let unchanged = protocol.as_ref().is_ok_and(|p| {
            let o = &p.settings.output;
            let modes = (o.layout.code(), o.overlay.code());
            (o.width, o.height, o.fps, modes) == (even.0, even.1, fps, (layout, overlay))
        });
        prop_assert_eq!(others[0].1.is_ok(), unchanged, "{:?}", others[0].1);
    }

    #[test]
    fn a_camera_s_fov_crop_lock_and_control(
        fov_mrad in -500i32..7000, crop in 0u8..12, lock in 0u8..20, control in 0u8..6,
        which in 0usize..4
    ) {
        let cal = cal();
        let fov = fov_mrad as f64 / 1000.0;
        // One field at a time, as a client sets them: fov, crop, lock, control.
        let cases: [(Param, String, String, Reads); 4] = [
            (Param::CamFov(CamFov { cam_id: 0, fov }), format!("fov={fov}"),
             format!("fov = {fov}"), Box::new(|s: &State| s.settings.cameras[0].fov())),
            (Param::CamCropMode(CamCropMode { cam_id: 0, mode: crop }), format!("crop={crop}"),
             format!("crop = {crop}"), Box::new(|s: &State| s.settings.cameras[0].crop().code() as f64)),
            (Param::CamLockFlags(CamLockFlags { cam_id: 0, flags: lock }), format!("lock={lock}"),
             format!("lock = {lock}"), Box::new(|s: &State| s.settings.cameras[0].locks().0 as f64)),
            (Param::CamControlMode(CamControlMode { cam_id: 0, mode: control }),
             format!("control={control}"), format!("control = {control}"),
             Box::new(|s: &State| s.settings.cameras[0].control().code() as f64)),
        ];
        let (param, flag, line, field) = &cases[which];
        let asked = [fov, crop as f64, lock as f64, control as f64][which];
        let protocol = by_protocol(&cal, *param);
        let toml = format!("[[camera]]\nid = 0\n{line}\n");
        let flags = StateArgs { cams: vec![format!("0:{flag}")], ..StateArgs::default() };
        let others = [
            ("flags", by_flags(&cal, flags)),
            ("state file", by_state_file(&cal, &toml)),
            ("config", by_config(&cal, &toml, None)),
        ];
        let same = |a: &State, b: &State| a.settings.cameras == b.settings.cameras;
        agree(protocol.clone(), &others, same)?;
        let unchanged = protocol.as_ref().is_ok_and(|p| field(p) == asked);
        prop_assert_eq!(others[0].1.is_ok(), unchanged, "{:?} {:?}", others[0].1, protocol);
    }

    #[test]
    fn the_lens_and_the_sensor_crop(
        lens in 0u8..6, roi_w in 0u32..4200, roi_h in 0u32..2400, cam_w in 0u32..9000,
        cam_h in 0u32..9000, cam_fps in 0u32..260, whole in any::<bool>()
    ) {
        let cal = cal();
        // The lens, by id through every path, by name through the config.
        let protocol = by_protocol(&cal, Param::Lens(Lens { lens_id: lens }));
        let name = cal.entries.iter().find(|e| e.lens_id == lens).map(|e| e.name.clone());
        let flags = StateArgs { lens: Some(lens.to_string()), ..StateArgs::default() };
        let mut others = vec![
            ("flags", by_flags(&cal, flags)),
            ("state file", by_state_file(&cal, &format!("lens = {lens}\n"))),
            ("config", by_config(&cal, "", Some(&lens.to_string()))),
        ];
        if let Some(n) = &name {
            others.push(("state file by name", by_state_file(&cal, &format!("lens = {n:?}\n"))));
            others.push(("config by name", by_config(&cal, "", Some(n))));
        }
        agree(protocol.clone(), &others, |a, b| a.settings.lens == b.settings.lens)?;
        prop_assert_eq!(others[0].1.is_ok(), protocol.is_ok());

        // The fisheye frame and its centred crop (GENERAL_SETTINGS; a state file's [sensor]).
        let (rw, rh) = if whole { (0, 0) } else { (roi_w, roi_h) };
        // 0 x 0 on the wire is no crop: the file then has no roi.
        let whole = (rw, rh) == (0, 0);
        let protocol = by_protocol(&cal, Param::GeneralSettings(GeneralSettings {
            camera_width: cam_w as u16, camera_height: cam_h as u16,
            roi_width: rw as u16, roi_height: rh as u16, camera_fps: cam_fps.min(255) as u8,
            mount_pitch: State::default().settings.mount.pitch,
            ..GeneralSettings::default()
        }));
        let lens0 = &cal.entries[0];
        let roi = if whole {
            String::new()
        } else {
            let x = lens0.width.saturating_sub(rw) / 2;
            let y = lens0.height.saturating_sub(rh) / 2;
            format!("roi = [{x}, {y}, {rw}, {rh}]\n")
        };
        let toml = format!(
            "[sensor]\nwidth = {cam_w}\nheight = {cam_h}\nfps = {}\n{roi}", cam_fps.min(255)
        );
        let others = [
            ("state file", by_state_file(&cal, &toml)),
            ("config", by_config(&cal, &toml, None)),
        ];
        agree(protocol.clone(), &others, |a, b| a.settings.sensor == b.settings.sensor)?;
        prop_assert_eq!(others[0].1.is_ok(), protocol.is_ok(), "{:?} {:?}", others[0].1, protocol);
    }
}
