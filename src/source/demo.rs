//! The built-in demo camera: the synthetic grid world of `scene` seen through a lens of
//! lens.cal while a simulated vehicle circles and turns, with the world's moving objects.
//! Frames come out in a camera-native layout (NV12 by default). The world is looked up once
//! per 2x2 block along rays worked out once per lens: about 20 ms a 1280x720 frame on two
//! cores.

use crate::exposure::SensorModel;
use crate::frame::yuv::rgb_to_yuv;
use crate::frame::{PixelFormat, PlaneLayout};
use crate::geometry::Euler;
use crate::geometry::GeoPosition;
use crate::geometry::ground::from_ned;
use crate::geometry::shutter::Readout;
use crate::geometry::view::lens_from_world;
use crate::lens::Lens;
use crate::scene::GridWorld;
use crate::scene::synth::{eye_at, world_origin};
use glam::{DMat3, DVec2, DVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// `[demo]` in the serve configuration: the demo camera and its flight.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DemoConfig {
    /// The demo camera's frame size (the lens is scaled to it) and rate.
    pub width: u32,
    pub height: u32,
    pub fps: u32,
    /// Fly a circle (true) or hover at the state's attitude and position (false).
    pub motion: bool,
    /// The world's movers go round (true) or stand where they start (false): warm bodies at
    /// known places for checking the thermal camera's registration.
    pub movers: bool,
    /// Hover yawing 90°/s and rolling ±20° at 1 Hz, by the monotonic clock (for tests with a
    /// simulated autopilot that reports the same; the demo then sends no flight of its own).
    pub spin: bool,
    /// The layout frames arrive in, as a camera's would.
    pub format: PixelFormat,
    /// Draw each frame's capture time (ms) as a barcode at the image centre, for
    /// glass-to-glass latency (scripts/latency.sh; 4:2:0 formats only).
    pub stamp: bool,
    /// A rolling shutter: milliseconds from the first row read (top) to the last, each row
    /// seen at the vehicle's attitude then; frames are stamped with their first row's time
    /// (0: a global shutter).
    pub readout_ms: f64,
}

impl Default for DemoConfig {
    fn default() -> Self {
        DemoConfig {
            width: 1280,
            height: 720,
            fps: 30,
            motion: true,
            movers: true,
            spin: false,
            format: PixelFormat::Nv12,
            stamp: false,
            readout_ms: 0.0,
        }
    }
}

impl DemoConfig {
    /// The frame the demo draws through `lens`: its own size, but for a lens pair, whose two
    /// images come side by side in a frame of the pair's shape (a frame of another shape would
    /// squeeze them), its height at the pair's shape (even).
    pub fn size_for(&self, lens: &Lens) -> (u32, u32) {
        if lens.pair.is_none() {
            return (self.width, self.height);
        }
        let wide = self.height as u64 * lens.width as u64 / lens.height.max(1) as u64;
        ((wide as u32 & !1).max(2), self.height)
    }
}

/// The simulated flight: a circle about the world origin, nose along the track, banked into
/// the turn, with a slow pitch sway.
#[derive(Clone, Debug, PartialEq)]
pub struct Flight {
    /// Where the vehicle hovers when `motion` is off (and the circle's height).
    pub hover: GeoPosition,
    pub attitude: Euler,
    pub motion: bool,
    /// Instead: hover, yawing 90°/s and rolling ±20° at 1 Hz, as a function of the monotonic
    /// clock itself, so an autopilot simulated elsewhere can report the very same attitude.
    pub spin: bool,
    /// Circle radius, metres, and seconds per lap.
    pub radius: f64,
    pub lap: f64,
}

impl Flight {
    /// The vehicle's attitude and position at `t` seconds from the flight's start, which is
    /// `clock_s` on the monotonic clock ([`crate::clock::clock_us`] in seconds).
    pub fn pose_at(&self, t: f64, clock_s: f64) -> (Euler, GeoPosition) {
        if self.spin {
            return (spin(self.attitude, clock_s), self.hover);
        }
        self.pose(t)
    }

    /// The vehicle's attitude and position at `t` seconds.
    pub fn pose(&self, t: f64) -> (Euler, GeoPosition) {
        if !self.motion {
            return (self.attitude, self.hover);
        }
        let a = TAU * t / self.lap;
        let ned = DVec3::new(self.radius * a.cos(), self.radius * a.sin(), 0.0);
        let origin = world_origin(&self.hover);
        let here = from_ned(origin, ned + eye_at(&self.hover));
        let position = GeoPosition {
            lat: here.lat,
            lon: here.lon,
            ..self.hover
        };
        // Clockwise seen from above (north towards east): the track heads 90° on from the
        // radius, and the vehicle banks right into the turn.
        let attitude = Euler {
            yaw: crate::geometry::rotation::wrap_pi(a + TAU / 4.0),
            pitch: (-3.0f64).to_radians() + 2f64.to_radians() * (TAU * t / 7.0).sin(),
            roll: 8f64.to_radians(),
        };
        (attitude, position)
    }
}

/// The spinning attitude at `clock_s` on the monotonic clock: `base` turned 90°/s in yaw,
/// rolled 20° · sin(2π · clock_s).
pub fn spin(base: Euler, clock_s: f64) -> Euler {
    Euler {
        yaw: crate::geometry::rotation::wrap_pi(base.yaw + (90f64.to_radians() * clock_s) % TAU),
        pitch: base.pitch,
        roll: base.roll + 20f64.to_radians() * (TAU * clock_s.fract()).sin(),
    }
}

/// Makes demo frames of one lens at one size. The world is evaluated once per 2x2 block (at
/// its centre) and luma is interpolated between block centres: the world's soft edges span
/// several pixels, so this keeps the picture while cutting the cost four times. Each block
/// sees the world as a pixel of its angular size does (`GridWorld::colour_seen`): a grid
/// line far away covers part of it and shows dimmed, steadily, rather than flickering on and
/// off between frames as the vehicle moves (which a motion detector would take for motion).
pub struct DemoCamera {
    world: GridWorld,
    layout: PlaneLayout,
    /// Blocks across and down.
    blocks: (usize, usize),
    /// The unit ray (lens frame) through each block centre, and the angle to its neighbours
    /// (radians); None outside the image circle.
    rays: Vec<Option<(Vec3, f32)>>,
    mount: Euler,
    /// The lens's image centre, pixels.
    centre: DVec2,
    /// How the sensor reads its rows out (top to bottom, stamped at the first).
    readout: Readout,
}

impl DemoCamera {
    /// `lens` must already be at the frame size `layout` describes (even width and height).
    pub fn new(lens: &Lens, layout: PlaneLayout, mount: Euler) -> DemoCamera {
        assert_eq!((lens.width, lens.height), (layout.width, layout.height));
        let blocks = (layout.width as usize / 2, layout.height as usize / 2);
        let ray = |bx: usize, by: usize| {
            // OpenCV pixel coordinates: the block's centre lies between its pixels.
            lens.unproject(DVec2::new(2.0 * bx as f64 + 0.5, 2.0 * by as f64 + 0.5))
        };
        let rays = (0..blocks.1)
            .into_par_iter()
            .flat_map_iter(|by| {
                (0..blocks.0).map(move |bx| {
                    let r = ray(bx, by)?;
                    // The larger of the angles to the next block across and down.
                    let next = [ray(bx + 1, by), ray(bx, by + 1)];
                    let size = next.iter().flatten().map(|n| n.angle_between(r));
                    Some((r.as_vec3(), size.fold(0.0, f64::max) as f32))
                })
            })
            .collect();
        DemoCamera {
            world: GridWorld::default(),
            layout,
            blocks,
            rays,
            mount,
            centre: lens.centre(),
            readout: Readout::default(),
        }
    }

    /// The same camera in `world` (the demo's own by default).
    pub fn in_world(mut self, world: GridWorld) -> DemoCamera {
        self.world = world;
        self
    }

    /// The same camera with a rolling shutter reading out top to bottom in `readout_ms`, its
    /// frames stamped with their first row's time.
    pub fn with_readout(mut self, readout_ms: f64) -> DemoCamera {
        self.readout = Readout::top_to_bottom(readout_ms);
        self
    }

    pub fn layout(&self) -> &PlaneLayout {
        &self.layout
    }

    pub fn world(&self) -> &GridWorld {
        &self.world
    }

    /// The frame seen from `position` at scene time `t` through `sensor` (the exposure and
    /// gain; `number` varies its noise from frame to frame), with `stamp` (when given, and
    /// the layout 4:2:0) drawn as the [`stamp`] barcode at the image centre. Each row is seen
    /// at `attitude(dt_us)`, `dt_us` after the frame's first row was read (0 for every row
    /// of a global shutter).
    pub fn frame(
        &self,
        attitude: impl Fn(f64) -> Euler + Sync,
        position: &GeoPosition,
        t: f64,
        sensor: (SensorModel, u64),
        stamp: Option<u32>,
    ) -> Vec<u8> {
        let (sensor, number) = sensor;
        let colours = self.block_colours(attitude, position, t, &sensor);
        let l = self.layout;
        let mut out = vec![0u8; l.size as usize];
        let (w, h) = (l.width as usize, l.height as usize);
        let up = Upsample::new(self.blocks, w);
        if l.format == PixelFormat::Rgba {
            let channels: Vec<Vec<f64>> = (0..3)
                .map(|k| colours.iter().map(|c| c[k]).collect())
                .collect();
            out.par_chunks_mut(l.stride as usize)
                .take(h)
                .enumerate()
                .for_each(|(y, row)| {
                    let ty = taps(y, up.rows);
                    for x in 0..w {
                        let c = [0, 1, 2].map(|k| byte(up.value(&channels[k], x, ty)));
                        row[4 * x..4 * x + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
                    }
                });
            sensor.add_noise(&mut out, l.stride as usize, 4 * w, number);
            out.chunks_exact_mut(4).for_each(|px| px[3] = 255);
            return out;
        }
        let luma: Vec<f64> = colours.iter().map(|c| rgb_to_yuv(*c).x).collect();
        let (y_plane, _) = out.split_at_mut(l.chroma[0] as usize);
        y_plane
            .par_chunks_mut(l.stride as usize)
            .enumerate()
            .for_each(|(y, row)| {
                let ty = taps(y, up.rows);
                for (x, px) in row.iter_mut().take(w).enumerate() {
                    *px = byte(up.value(&luma, x, ty));
                }
            });
        let bw = self.blocks.0;
        for (i, c) in colours.iter().enumerate() {
            let yuv = rgb_to_yuv(*c);
            let (u, v) = l.chroma_at((i % bw) as u32, (i / bw) as u32);
            out[u] = byte(yuv.y);
            out[v] = byte(yuv.z);
        }
        let luma_bytes = l.chroma[0] as usize;
        sensor.add_noise(&mut out[..luma_bytes], l.stride as usize, w, number);
        if let Some(value) = stamp {
            stamp::draw(&mut out, &l, self.centre, value);
        }
        out
    }

    /// The world's colour at every 2x2 block's centre, through the sensor, each row of
    /// blocks as the lens was when it was read; rows in parallel.
    fn block_colours(
        &self,
        attitude: impl Fn(f64) -> Euler + Sync,
        position: &GeoPosition,
        t: f64,
        sensor: &SensorModel,
    ) -> Vec<DVec3> {
        let eye = eye_at(position);
        let (bw, bh) = self.blocks;
        let size = (self.layout.width, self.layout.height);
        let stamp_to_middle = self.readout.middle_after_stamp_us();
        let world_from_lens: Vec<DMat3> = (0..bh)
            .map(|by| {
                let row = DVec2::new(0.0, 2.0 * by as f64 + 0.5);
                let dt = self.readout.point_us(row, size) + stamp_to_middle;
                lens_from_world(attitude(dt), self.mount).transpose()
            })
            .collect();
        (0..bh)
            .into_par_iter()
            .flat_map_iter(|by| {
                let world_from_lens = world_from_lens[by];
                (0..bw).map(move |bx| match self.rays[by * bw + bx] {
                    Some((r, size)) => {
                        let ray = world_from_lens * r.as_dvec3();
                        let seen = self.world.colour_seen(eye, ray, t, size as f64);
                        (seen * sensor.scale).min(DVec3::splat(255.0))
                    }
                    None => DVec3::ZERO,
                })
            })
            .collect()
    }
}

/// Pixel x lies (x - 0.5) / 2 block centres in: the two block centres around it, and how far
/// from the first, of `n`.
fn taps(x: usize, n: usize) -> (usize, usize, f64) {
    let g = (x as f64 - 0.5) / 2.0;
    let i = g.floor().clamp(0.0, (n - 1) as f64) as usize;
    let j = (i + 1).min(n - 1);
    (i, j, (g - i as f64).clamp(0.0, 1.0))
}

/// The blocks' values interpolated to pixels: every column's taps worked out once, a row's
/// once a row.
struct Upsample {
    columns: Vec<(usize, usize, f64)>,
    across: usize,
    rows: usize,
}

impl Upsample {
    fn new((bw, bh): (usize, usize), width: usize) -> Upsample {
        Upsample {
            columns: (0..width).map(|x| taps(x, bw)).collect(),
            across: bw,
            rows: bh,
        }
    }

    /// `grid` (a value a block) at pixel `x` of the row whose taps are `(y0, y1, fy)`.
    fn value(&self, grid: &[f64], x: usize, (y0, y1, fy): (usize, usize, f64)) -> f64 {
        let (x0, x1, fx) = self.columns[x];
        let bw = self.across;
        let row = |r: usize| grid[r * bw + x0] * (1.0 - fx) + grid[r * bw + x1] * fx;
        row(y0) * (1.0 - fy) + row(y1) * fy
    }
}

fn byte(v: f64) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// The timestamp barcode the demo can draw at the image centre (straight along the lens axis)
/// for glass-to-glass latency: 32 bits of a millisecond clock, 8 cells across and 4 down,
/// most significant bit first, white for 1 and black for 0, inside a one-cell grey border.
pub mod stamp {
    use crate::frame::PlaneLayout;
    use glam::DVec2;

    pub const COLS: i64 = 8;
    pub const ROWS: i64 = 4;
    /// Cell side in pixels of a 1280-wide frame; scaled with the frame width.
    pub const CELL_1280: f64 = 14.0;

    fn cell(width: u32) -> f64 {
        CELL_1280 * width as f64 / 1280.0
    }

    /// Which bit (0 = most significant) pixel `p` of a `width`-wide frame shows, Some(None)
    /// on the border, None away from the code.
    pub fn bit_at(p: DVec2, centre: DVec2, width: u32) -> Option<Option<u32>> {
        let c = (p - centre) / cell(width);
        let (col, row) = (
            (c.x + COLS as f64 / 2.0).floor() as i64,
            (c.y + ROWS as f64 / 2.0).floor() as i64,
        );
        if !(-1..=COLS).contains(&col) || !(-1..=ROWS).contains(&row) {
            return None;
        }
        if col == -1 || col == COLS || row == -1 || row == ROWS {
            return Some(None);
        }
        Some(Some((row * COLS + col) as u32))
    }

    /// Draws `value` into the luma plane of a 4:2:0 frame (chroma left as the world's).
    pub fn draw(out: &mut [u8], layout: &PlaneLayout, centre: DVec2, value: u32) {
        let reach = cell(layout.width) * (COLS as f64 / 2.0 + 1.0);
        let (x0, x1) = (
            (centre.x - reach).max(0.0),
            (centre.x + reach).min(layout.width as f64 - 1.0),
        );
        let (y0, y1) = (
            (centre.y - reach).max(0.0),
            (centre.y + reach).min(layout.height as f64 - 1.0),
        );
        for y in y0 as u32..=y1 as u32 {
            for x in x0 as u32..=x1 as u32 {
                let Some(bit) = bit_at(DVec2::new(x as f64, y as f64), centre, layout.width) else {
                    continue;
                };
                out[(y * layout.stride + x) as usize] = match bit {
                    None => 126,
                    Some(b) if value >> (31 - b) & 1 == 1 => 235,
                    Some(_) => 16,
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ground::to_ned;

    #[test]
    fn the_demo_flies_a_circle_nose_along_the_track_and_hovers_when_told() {
        let hover = crate::state::DEFAULT_POSITION;
        let flight = Flight {
            hover,
            attitude: Euler::new(0.3, 0.0, 0.0),
            motion: true,
            spin: false,
            radius: 30.0,
            lap: 90.0,
        };
        let origin = world_origin(&hover);
        let at = |t: f64| to_ned(origin, flight.pose(t).1.point()) - eye_at(&hover);
        for t in [0.0, 10.0, 47.0] {
            let (attitude, p) = flight.pose(t);
            assert!(
                (at(t).truncate().length() - 30.0).abs() < 0.01,
                "on the circle"
            );
            assert_eq!(p.relative_alt, hover.relative_alt);
            // The nose points where the vehicle goes next.
            let step = (at(t + 0.01) - at(t)).truncate();
            let track = step.y.atan2(step.x);
            let off = crate::geometry::rotation::wrap_pi(attitude.yaw - track);
            assert!(
                off.abs() < 0.01,
                "heading {} vs track {track}",
                attitude.yaw
            );
            assert!(attitude.roll > 0.0, "banked into the turn");
        }
        let still = Flight {
            motion: false,
            spin: false,
            ..flight.clone()
        };
        assert_eq!(still.pose(12.0), (Euler::new(0.3, 0.0, 0.0), hover));
    }

    #[test]
    fn the_demo_draws_a_lens_pair_in_the_pairs_shape_and_one_lens_at_its_own_size() {
        let cal = crate::lens::LensCal::load(std::path::Path::new("lens-cal/lens.cal")).unwrap();
        let lenses = crate::lens::Lenses::new(&cal);
        let demo = DemoConfig::default();
        let dual = lenses.named("DUAL").unwrap();
        assert_eq!((dual.width, dual.height), (3840, 1920));
        assert_eq!(demo.size_for(dual), (1440, 720));
        let one = lenses
            .get(crate::state::State::default().settings.lens)
            .unwrap();
        assert_eq!(demo.size_for(one), (1280, 720));
        let small = DemoConfig {
            width: 640,
            height: 481,
            ..demo
        };
        assert_eq!(small.size_for(dual), (962, 481));
    }
}
