//! `digiview lens pair-fit`: a lens pair's rotation measured from one frame of a scene both
//! lenses see around the seam (`lens::pair_fit`), printed as the pair's lens.cal table, or
//! written in place of it.

use super::lens_entry::{EntryArgs, output_entry};
use super::locate;
use crate::lens::pair_fit::fit_pair;
use crate::lens::{LensEntry, Provenance};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct PairFitArgs {
    /// The pair, as lens.cal names it (e.g. DUAL).
    pair: String,
    /// A frame of the pair (both images, as the camera delivers them) of a scene with
    /// detail all round the seam; any size with the pair's aspect.
    #[arg(long)]
    frame: PathBuf,
    /// Write the measured rotation into lens.cal, in place of the pair's.
    #[arg(long)]
    write: bool,
}

pub fn run(flag: Option<&Path>, args: PairFitArgs) -> Result<()> {
    let (cal, _) = locate::lens_cal(flag)?;
    let entry = cal.find(&args.pair)?;
    let Some(pair) = &entry.pair else {
        bail!(
            "{} is a single lens; pair-fit measures a [[pair]] of lens.cal",
            entry.name
        );
    };
    let luma = image::open(&args.frame)
        .with_context(|| format!("reading the frame {}", args.frame.display()))?
        .to_luma8();
    let (w, h) = luma.dimensions();
    if (w as u64 * entry.height as u64).abs_diff(h as u64 * entry.width as u64) > w as u64 {
        bail!(
            "{} is {w}x{h}; {} takes {}x{} frames (or the same shape at another size)",
            args.frame.display(),
            entry.name,
            entry.width,
            entry.height
        );
    }
    let lens = entry.lens().for_frame(w, h, None);
    eprintln!(
        "fitting {}'s rotation from {} ...",
        entry.name,
        args.frame.display()
    );
    let fit = fit_pair(&lens, &luma, |line| eprintln!("  {line}"))?;
    let [roll, pitch, yaw] = fit.rotation.map(f64::to_degrees);
    let sigma = fit.sigma.iter().fold(0.0f64, |a, s| a.max(*s)).to_degrees();
    println!(
        "# {}: the second lens sits roll {roll:+.4}deg, pitch {pitch:+.4}deg, yaw {yaw:+.4}deg \
         from back to back (formal error {sigma:.4}deg)",
        entry.name
    );
    println!(
        "# the lenses' pictures of the seam differ by {:.1} code values of luma (rms) at the \
         nominal pose, {:.1} at this one, over {} rays (second lens's gain {:.3}); a 0.1deg \
         error in roll, pitch, yaw would add {:.1}, {:.1}, {:.1}",
        fit.before_rms,
        fit.after_rms,
        fit.rays,
        fit.gain,
        fit.sensitivity[0],
        fit.sensitivity[1],
        fit.sensitivity[2]
    );
    let mut pair = pair.clone();
    pair.rotation = fit.rotation;
    let fitted = LensEntry {
        provenance: Provenance {
            kind: "calibrated".into(),
            by: "digiview lens pair-fit".into(),
            date: super::calibrate_cmd::today(),
            source: format!("{}", args.frame.display()),
            assumption: String::new(),
            rms_px: None,
        },
        pair: Some(pair),
        ..entry.clone()
    };
    let out = EntryArgs {
        name: entry.name.clone(),
        id: entry.lens_id,
        fov: None,
        write: args.write,
        replace: true,
    };
    output_entry(flag, &fitted, &out)
}
