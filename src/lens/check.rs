//! `digiview lens check`: is a lens.cal entry self-consistent and usable?

use super::pair::Mask;
use super::{LensEntry, Side};
use glam::{DVec2, DVec3};
use std::f64::consts::PI;

/// The round-trip accuracy every lens must reach over its image circle.
pub const ROUND_TRIP_PX: f64 = 1e-3;

#[derive(Debug)]
pub struct Finding {
    pub ok: bool,
    pub what: String,
}

/// Checks one entry: the declared fov lies where the model is one-to-one, pixels round-trip
/// within 1e-3 px over the whole image circle, the declared circle radius matches the model,
/// and the principal point lies in the frame.
pub fn check(entry: &LensEntry) -> Vec<Finding> {
    if entry.pair.is_some() {
        return check_pair(entry);
    }
    let lens = entry.lens();
    let mut out = vec![];
    let limit = lens.radial.limits.theta_max;
    out.push(Finding {
        ok: entry.fov / 2.0 <= limit + 1e-9,
        what: format!(
            "declared fov {:.2}deg within the model's one-to-one range ({:.2}deg)",
            entry.fov.to_degrees(),
            2.0 * limit.to_degrees()
        ),
    });
    let mut worst: f64 = 0.0;
    let mut failed = 0;
    for ring in 0..=40 {
        let theta = lens.half_fov * ring as f64 / 40.0;
        for k in 0..48 {
            let phi = 2.0 * PI * k as f64 / 48.0;
            let ray = DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            match lens.project(ray).and_then(|p| {
                lens.unproject(p)
                    .and_then(|r| lens.project(r))
                    .map(|q| (q - p).length())
            }) {
                Some(e) => worst = worst.max(e),
                None => failed += 1,
            }
        }
    }
    out.push(Finding {
        ok: failed == 0 && worst < ROUND_TRIP_PX,
        what: format!("pixels round-trip over the image circle: worst {worst:.1e} px, {failed} failures (limit {ROUND_TRIP_PX:e} px)"),
    });
    let computed = lens.circle_radius();
    if let Some(declared) = entry.circle_radius {
        out.push(Finding {
            ok: (declared - computed).abs() <= 0.005 * computed.max(1.0),
            what: format!("declared circle radius {declared:.1} px matches the model's {computed:.1} px (0.5%)"),
        });
    }
    let c = lens.centre();
    out.push(Finding {
        ok: lens.in_frame(c),
        what: format!(
            "principal point ({:.1}, {:.1}) inside the {}x{} frame",
            c.x, c.y, entry.width, entry.height
        ),
    });
    let visible = lens
        .unproject(DVec2::new(c.x.clamp(0.0, entry.width as f64 - 1.0), c.y))
        .is_some();
    out.push(Finding {
        ok: visible,
        what: "the image centre sees the scene".into(),
    });
    out
}

/// Checks a pair (its lenses are checked as entries of their own): every direction is seen
/// and its ray comes back through the pixel it lands on, each lens's image circle lies in
/// its own part of the frame, and the fields overlap by more than the seam's blend needs.
fn check_pair(entry: &LensEntry) -> Vec<Finding> {
    let lens = entry.lens();
    let pair = lens.pair.as_ref().expect("a pair");
    let mut worst: f64 = 0.0;
    let mut unseen = 0;
    let scale = lens.affine.mean_scale();
    for ring in 0..=80 {
        let theta = PI * ring as f64 / 80.0;
        for k in 0..96 {
            let phi = 2.0 * PI * k as f64 / 96.0;
            let ray = DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            match lens.project(ray).and_then(|p| lens.unproject(p)) {
                Some(back) => worst = worst.max((back - ray).length() * scale),
                None => unseen += 1,
            }
        }
    }
    let mut out = vec![Finding {
        ok: unseen == 0 && worst < ROUND_TRIP_PX,
        what: format!(
            "every direction is seen and comes back through its pixel: worst {worst:.1e} px, \
             {unseen} unseen (limit {ROUND_TRIP_PX:e} px)"
        ),
    }];
    for (side, part) in [(Side::First, &pair.first), (Side::Second, &pair.second)] {
        let strays = (0..360)
            .filter_map(|k| {
                let a = (k as f64).to_radians();
                let rim = DVec3::new(
                    part.half_fov.sin() * a.cos(),
                    part.half_fov.sin() * a.sin(),
                    part.half_fov.cos(),
                );
                part.project(rim)
            })
            .filter(|p| pair.side_at(*p) != side || !lens.in_frame(*p))
            .count();
        out.push(Finding {
            ok: strays == 0,
            what: format!("the {side:?} lens's image circle lies in its own part of the frame ({strays} of 360 rim points outside)").to_lowercase(),
        });
    }
    let overlap = pair.first.half_fov + pair.second.half_fov - PI;
    // Both lenses must see the whole blend: half the feather either side of the seam.
    let needed = pair.feather / 2.0;
    out.push(Finding {
        ok: overlap >= needed,
        what: format!(
            "the fields overlap by {:.2}deg, as much as the seam's blend takes ({:.2}deg)",
            overlap.to_degrees(),
            needed.to_degrees()
        ),
    });
    out.extend(
        pair.masks
            .iter()
            .enumerate()
            .map(|(i, m)| mask_finding(pair, i, m)),
    );
    out
}

/// How much of what mask `i` hides the other lens sees unhidden (so the view shows it, not
/// the airframe), over the pixels of the polygon in its lens's image, every fourth each way.
fn mask_finding(pair: &crate::lens::pair::Pair, i: usize, mask: &Mask) -> Finding {
    let (lo, hi) = mask.points.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let (mut inside, mut filled) = (0usize, 0usize);
    for y in (lo.y as i64..=hi.y as i64).step_by(4) {
        for x in (lo.x as i64..=hi.x as i64).step_by(4) {
            let p = DVec2::new(x as f64, y as f64);
            let Some(ray) = pair.unproject(p).filter(|_| mask.contains(p)) else {
                continue;
            };
            inside += 1;
            let other = crate::lens::pair::other(pair.side_at(p));
            let there = pair.project_in(other, ray);
            filled += there.is_some_and(|q| pair.masks.iter().all(|m| !m.contains(q))) as usize;
        }
    }
    let share = filled as f64 / inside.max(1) as f64;
    Finding {
        ok: inside > 0 && share >= 0.99,
        what: format!(
            "mask {}: the other lens sees {:.0}% of what it hides (the rest shows the airframe)",
            i + 1,
            share * 100.0
        ),
    }
}
