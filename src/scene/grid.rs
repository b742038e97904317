//! The procedural world: flat ground at the world origin's altitude with a metric grid (lines
//! every 10 m, heavier every 50 m), coloured landmark discs at known positions, objects that
//! move on circles, haze with distance, and a sky that meets the haze at the horizon.
//! Every edge is soft (a fraction of a metre) so the world is band-limited enough for image
//! comparisons to measure geometry, not aliasing. [`GridWorld::colour_seen`] is what one
//! camera pixel of a given angular size sees: every edge spread over the pixel's footprint on
//! the ground, a line narrower than it dimmed to the share of it the line covers (as a
//! sensor's pixel integrates its area), so far lines do not flicker from frame to frame as
//! point samples of them would.

use super::{World, smoothstep};
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

#[derive(Clone, Debug, PartialEq)]
pub struct Landmark {
    pub name: &'static str,
    /// North, east of the world origin, metres (on the ground).
    pub position: DVec2,
    pub radius: f64,
    pub colour: DVec3,
}

/// An object moving on a circle about `centre` at `speed` rad/s.
#[derive(Clone, Debug, PartialEq)]
pub struct Mover {
    pub centre: DVec2,
    pub orbit: f64,
    pub speed: f64,
    pub phase: f64,
    pub radius: f64,
    pub colour: DVec3,
}

impl Mover {
    pub fn position(&self, t: f64) -> DVec2 {
        let a = self.phase + self.speed * t;
        self.centre + DVec2::new(a.cos(), a.sin()) * self.orbit
    }
}

const GROUND: DVec3 = DVec3::new(95.0, 120.0, 75.0);
const GRID: DVec3 = DVec3::new(200.0, 200.0, 180.0);
const HAZE: DVec3 = DVec3::new(200.0, 210.0, 222.0);
const ZENITH: DVec3 = DVec3::new(60.0, 110.0, 200.0);
/// Soft edge half-width of discs and lines, metres.
pub(super) const EDGE: f64 = 0.3;

#[derive(Clone, Debug)]
pub struct GridWorld {
    pub landmarks: Vec<Landmark>,
    pub movers: Vec<Mover>,
    /// Distance at which haze hides 63% of the ground.
    pub haze_distance: f64,
}

fn rgb(r: f64, g: f64, b: f64) -> DVec3 {
    DVec3::new(r, g, b)
}

impl Default for GridWorld {
    fn default() -> Self {
        let lm = |name, n, e, colour| Landmark {
            name,
            position: DVec2::new(n, e),
            radius: 4.0,
            colour,
        };
        GridWorld {
            landmarks: vec![
                lm("red", 25.0, -25.0, rgb(230.0, 40.0, 40.0)),
                lm("blue", -25.0, 15.0, rgb(40.0, 70.0, 235.0)),
                lm("yellow", 15.0, 35.0, rgb(245.0, 225.0, 40.0)),
                lm("magenta", 55.0, 15.0, rgb(225.0, 50.0, 215.0)),
                lm("cyan", 85.0, -25.0, rgb(40.0, 215.0, 225.0)),
                lm("orange", 125.0, 25.0, rgb(250.0, 140.0, 30.0)),
                lm("white", -65.0, -35.0, rgb(250.0, 250.0, 250.0)),
                lm("purple", 5.0, -75.0, rgb(120.0, 40.0, 190.0)),
                lm("black", -15.0, 85.0, rgb(15.0, 15.0, 20.0)),
            ],
            movers: vec![
                Mover {
                    centre: DVec2::ZERO,
                    orbit: 32.0,
                    speed: 0.12,
                    phase: 0.3,
                    radius: 2.0,
                    colour: rgb(255.0, 150.0, 180.0),
                },
                Mover {
                    centre: DVec2::new(40.0, 40.0),
                    orbit: 20.0,
                    speed: -0.2,
                    phase: 2.0,
                    radius: 2.0,
                    colour: rgb(150.0, 255.0, 60.0),
                },
                Mover {
                    centre: DVec2::new(-40.0, -20.0),
                    orbit: 15.0,
                    speed: 0.3,
                    phase: 4.0,
                    radius: 1.5,
                    colour: rgb(90.0, 60.0, 30.0),
                },
            ],
            haze_distance: 900.0,
        }
    }
}

impl GridWorld {
    /// The demo's world, its movers going round (`moving`) or standing where they start.
    pub fn demo(moving: bool) -> GridWorld {
        let mut world = GridWorld::default();
        if !moving {
            world.movers.iter_mut().for_each(|m| m.speed = 0.0);
        }
        world
    }
}

/// 1 on a line of the grid of `spacing` with half-width `half`, 0 away from it; seen through
/// a footprint `f` metres wide (0: a point), the share of it the line covers.
pub(super) fn line(x: f64, spacing: f64, half: f64, f: f64) -> f64 {
    let d = (x - (x / spacing).round() * spacing).abs();
    if f <= 2.0 * EDGE {
        return smoothstep(half + EDGE, half - EDGE, d);
    }
    // The footprint [d - f/2, d + f/2] against the nearest line and the next one over.
    let covered = |c: f64| ((d + f / 2.0).min(c + half) - (d - f / 2.0).max(c - half)).max(0.0);
    ((covered(0.0) + covered(spacing)) / f).min(1.0)
}

/// A gentle large-scale tone of the ground at `p`, -1 to 1, so it is not one flat colour
/// (nor one temperature).
pub(super) fn tone(p: DVec2) -> f64 {
    (p.x * TAU / 47.0).sin() * (p.y * TAU / 53.0).sin()
}

/// How far a ray at or above the horizon is from the horizon's haze towards the zenith's sky,
/// 0 to 1.
pub(super) fn skyward(ray: DVec3) -> f64 {
    let elevation = (-ray.z).clamp(0.0, 1.0).asin();
    1.0 - (-4.0 * elevation).exp()
}

impl GridWorld {
    /// The colour a camera pixel `pixel` radians across sees from `eye` along `ray` at `t`:
    /// as [`World::colour`], its edges spread over the pixel's footprint on the ground.
    pub fn colour_seen(&self, eye: DVec3, ray: DVec3, t: f64, pixel: f64) -> DVec3 {
        if ray.z > 1e-9 && eye.z < 0.0 {
            let distance = -eye.z / ray.z;
            let hit = eye + ray * distance;
            // Across the pixel, along the ground where the ray meets it at a slant.
            let footprint = distance * pixel / ray.z;
            let c = self.ground(DVec2::new(hit.x, hit.y), (distance, footprint), t);
            HAZE.lerp(c, (-distance / self.haze_distance).exp())
        } else {
            HAZE.lerp(ZENITH, skyward(ray))
        }
    }

    fn ground(&self, p: DVec2, (distance, f): (f64, f64), t: f64) -> DVec3 {
        let mut c = GROUND * (1.0 + 0.07 * tone(p));
        // Grid lines fade with distance, before they shrink below a pixel anywhere.
        let fade = (-distance / 250.0).exp();
        let minor = line(p.x, 10.0, 0.25, f).max(line(p.y, 10.0, 0.25, f));
        let major = line(p.x, 50.0, 0.6, f).max(line(p.y, 50.0, 0.6, f));
        let edge = EDGE.max(f / 2.0);
        c = c.lerp(GRID, minor.max(major) * fade);
        // Discs: only those near `p` can colour it (most of the cost is skipped this way).
        let disc = |c: DVec3, centre: DVec2, radius: f64, colour: DVec3| {
            let d2 = (p - centre).length_squared();
            if d2 >= (radius + edge) * (radius + edge) {
                return c;
            }
            // A disc smaller than the footprint is dimmed to the share it covers.
            let share = (radius / edge).min(1.0);
            c.lerp(
                colour,
                share * smoothstep(radius + edge, radius - edge, d2.sqrt()),
            )
        };
        for l in &self.landmarks {
            c = disc(c, l.position, l.radius, l.colour);
        }
        for m in &self.movers {
            let reach = m.orbit + m.radius + edge;
            if (p - m.centre).length_squared() < reach * reach {
                c = disc(c, m.position(t), m.radius, m.colour);
            }
        }
        c
    }
}

impl World for GridWorld {
    fn colour(&self, eye: DVec3, ray: DVec3, t: f64) -> DVec3 {
        self.colour_seen(eye, ray, t, 0.0)
    }
}
