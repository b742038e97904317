//! Synthetic thermal frames whose truth is known: warm bodies (discs of one temperature, their
//! edges blended as a sensor's pixels would see them) at given places on a background that
//! warms gently from top to bottom (sky to ground), in counts under a calibration.

use super::{Calibration, ThermalFrame};

/// A warm (or cold) body: a disc of one temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Its centre, in the frame's pixels (the first pixel's centre is (0.5, 0.5)).
    pub x: f64,
    pub y: f64,
    pub radius: f64,
    pub kelvin: f64,
}

/// The background: `top_k` along the top row to `bottom_k` along the bottom.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Background {
    pub top_k: f64,
    pub bottom_k: f64,
}

/// Sub-samples a side of each pixel for a body's edge.
const SUB: u32 = 4;

/// A `width` × `height` frame of `bodies` (later ones over earlier) on `background`.
pub fn frame(
    width: u32,
    height: u32,
    background: Background,
    bodies: &[Body],
    cal: &Calibration,
) -> ThermalFrame {
    let mut counts = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        let along = (y as f64 + 0.5) / height as f64;
        let ground = background.top_k + (background.bottom_k - background.top_k) * along;
        for x in 0..width {
            let kelvin = bodies.iter().fold(ground, |under, b| {
                let cover = coverage(b, x, y);
                under + (b.kelvin - under) * cover
            });
            counts.push(cal.counts(kelvin));
        }
    }
    ThermalFrame::new(width, height, counts).expect("a frame of its own size")
}

/// The share of pixel (`x`, `y`) that body `b` covers.
fn coverage(b: &Body, x: u32, y: u32) -> f64 {
    let near = (x as f64 + 0.5 - b.x).abs() <= b.radius + 1.0
        && (y as f64 + 0.5 - b.y).abs() <= b.radius + 1.0;
    if !near {
        return 0.0;
    }
    let mut inside = 0;
    for sy in 0..SUB {
        for sx in 0..SUB {
            let px = x as f64 + (sx as f64 + 0.5) / SUB as f64;
            let py = y as f64 + (sy as f64 + 0.5) / SUB as f64;
            if (px - b.x).hypot(py - b.y) <= b.radius {
                inside += 1;
            }
        }
    }
    inside as f64 / (SUB * SUB) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hottest_and_coldest_are_the_bodies_at_their_middles_and_temperatures() {
        let cal = Calibration::default();
        let bodies = [
            Body {
                x: 100.3,
                y: 60.7,
                radius: 4.0,
                kelvin: 310.15,
            },
            Body {
                x: 30.0,
                y: 90.5,
                radius: 3.0,
                kelvin: 255.4,
            },
        ];
        let sky = Background {
            top_k: 270.0,
            bottom_k: 290.0,
        };
        let f = frame(160, 120, sky, &bodies, &cal);
        let e = f.extremes(&cal);
        for (spot, body) in [(e.hottest, bodies[0]), (e.coldest, bodies[1])] {
            assert!(
                (spot.kelvin - body.kelvin).abs() <= 0.01,
                "{spot:?} {body:?}"
            );
            let off = (spot.x - body.x).hypot(spot.y - body.y);
            assert!(off <= 0.5, "{off:.2} px from {body:?}: {spot:?}");
        }
        // A point's temperature: inside a body, on the background, and between.
        let inside = f.spot(100.3, 60.7, &cal).unwrap();
        assert!((inside.kelvin - 310.15).abs() < 0.01, "{inside:?}");
        let ground = f.spot(80.0, 60.0, &cal).unwrap().kelvin;
        assert!((ground - 280.0).abs() < 0.1, "{ground}");
        let e = f.spot(161.0, 10.0, &cal).unwrap_err();
        assert!(e.to_string().contains("outside the 160x120"), "{e}");
    }
}
