//! The thermal camera's picture over the views (issue 57): for each view that shows it, where
//! each of the view's pixels looks in the thermal picture and how much of the thermal colour
//! covers the fisheye's there. A frame plan carries it (`FramePlan::thermal`); the GPU draws
//! it over the output frame after the draw pass (`render::gpu::layer`, shaders/layer.wgsl),
//! and [`ThermalLayer::draw_rgb`] here is the f64 reference that pass is measured against.
//!
//! Three ways to show it ([`ThermalShow`]): blended onto a rectified view where the two
//! cameras' fields overlap, registered through the two mounts (a hot body glows on the
//! fisheye view where it stands); as a picture-in-picture, the thermal camera's whole picture
//! in the view's lower right corner; or as the view's whole picture. The last two show the
//! thermal picture as its own lens saw it, its distortion taken out: an inset pixel looks
//! along the ray a pinhole camera on the thermal camera's axis, with its focal length, would.

use crate::geometry::Projection;
use crate::geometry::rotation::MOUNT_FROM_LENS;
use crate::layout::Rect;
use crate::lens::Lens;
use crate::modes::ThermalShow;
use crate::plan::{FramePlan, PlannedView, ViewMap};
use crate::thermal::{GainTable, Palette, ThermalFrame, colourise};
use glam::{DMat3, DVec2, DVec3};
use image::{RgbImage, RgbaImage};
use std::sync::Arc;

/// How much of a blended pixel is the thermal colour.
pub const BLEND_ALPHA: f64 = 0.5;
/// A picture-in-picture is this fraction of its view's width.
pub const PIP_SHARE: f64 = 1.0 / 3.0;
/// And stands this many pixels in from the view's right and bottom edges.
pub const PIP_MARGIN: u32 = 8;

/// One rectangle of the output the thermal picture covers: its pixels' rays, turned into
/// the thermal lens frame, and how they mix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerEntry {
    pub rect: Rect,
    /// The rectangle's own projection (a point of it, from its top-left corner, to a ray in
    /// the view frame: forward, right, down).
    pub projection: Projection,
    pub thermal_from_view: DMat3,
    /// The projection's rays turned into the world (the view's for a blend, the thermal
    /// camera's own for its picture).
    pub world_from_entry: DMat3,
    /// The thermal colour's share of a pixel the thermal camera sees.
    pub alpha: f64,
    /// Pixels the thermal camera does not see are black (else the fisheye's).
    pub black_outside: bool,
}

impl LayerEntry {
    /// The world ray its point `p` (from its top-left corner) stands for.
    pub fn world_ray(&self, p: DVec2) -> DVec3 {
        self.world_from_entry * self.projection.ray(p)
    }
}

/// A thermal frame coloured and laid over a frame's views.
#[derive(Clone, Debug)]
pub struct ThermalLayer {
    pub frame: Arc<ThermalFrame>,
    pub gain: Arc<GainTable>,
    pub palette: Palette,
    /// The thermal lens at the frame's size.
    pub lens: Lens,
    /// The thermal colour's share of a blended view's pixel ([`BLEND_ALPHA`] unless set).
    pub blend: f64,
    /// The thermal picture's zoom where it is shown whole or inset (1 unless set).
    pub zoom: f64,
    pub entries: Vec<LayerEntry>,
}

impl ThermalLayer {
    /// `frame` coloured with `gain` in `palette`, seen through `lens`; over no view yet.
    pub fn new(
        frame: Arc<ThermalFrame>,
        gain: Arc<GainTable>,
        palette: Palette,
        lens: Lens,
    ) -> ThermalLayer {
        ThermalLayer {
            frame,
            gain,
            palette,
            lens,
            blend: BLEND_ALPHA,
            zoom: 1.0,
            entries: Vec::new(),
        }
    }

    /// Lays the thermal picture over `view` of `plan` as `show` says; `thermal_in_lens` turns
    /// thermal lens rays into the fisheye's lens frame (the two mounts). A blend needs a
    /// rectified view (an unrectified one, crop modes 0 and 4, and a black one get none).
    pub fn add(
        &mut self,
        plan: &FramePlan,
        view: &PlannedView,
        show: ThermalShow,
        thermal_in_lens: DMat3,
    ) {
        let rect = view.rect;
        // Every entry's rays, turned into the world and from there into the thermal lens.
        let thermal_from_world = thermal_in_lens.transpose() * plan.lens_from_world;
        let world_from_thermal = thermal_from_world.transpose() * MOUNT_FROM_LENS.transpose();
        let entry = |rect, projection, world_from_entry, alpha, black_outside| LayerEntry {
            rect,
            projection,
            thermal_from_view: thermal_from_world * world_from_entry,
            world_from_entry,
            alpha,
            black_outside,
        };
        let entry = match (show, view.map) {
            (ThermalShow::Off, _) => return,
            (
                ThermalShow::Blend,
                ViewMap::Rays {
                    projection,
                    world_from_view,
                },
            ) => entry(rect, projection, world_from_view, self.blend, false),
            (ThermalShow::Blend, _) => return,
            (ThermalShow::Pip, _) => {
                let w = ((rect.w as f64 * PIP_SHARE).round() as u32).max(2);
                let h = (w as f64 * self.lens.height as f64 / self.lens.width as f64).round();
                let h = (h as u32).clamp(2, rect.h);
                let x = rect.x + rect.w.saturating_sub(w + PIP_MARGIN);
                let y = rect.y + rect.h.saturating_sub(h + PIP_MARGIN);
                let inset = Rect::new(x, y, w.min(rect.w), h);
                entry(
                    inset,
                    self.own_picture(inset),
                    world_from_thermal,
                    1.0,
                    true,
                )
            }
            (ThermalShow::Thermal, _) => {
                entry(rect, self.own_picture(rect), world_from_thermal, 1.0, true)
            }
        };
        self.entries.push(entry);
    }

    /// The projection of the thermal picture filling `rect`: a pinhole on the thermal axis
    /// (forward, right, down) whose focal length is the lens's, scaled so that the whole
    /// frame fits, times the zoom.
    fn own_picture(&self, rect: Rect) -> Projection {
        let (w, h) = (rect.w as f64, rect.h as f64);
        let scale = (w / self.lens.width as f64).min(h / self.lens.height as f64);
        let focal = self.lens.affine.matrix.x_axis.x * scale * self.zoom;
        Projection::Rectilinear {
            width: w,
            height: h,
            fov: 2.0 * (0.5 * w / focal).atan(),
        }
    }

    /// Where point `p` of `entry` (from its top-left corner) looks in the thermal frame
    /// (OpenCV pixels: a pixel's centre at its integer coordinates), None where the thermal
    /// camera does not see.
    pub fn thermal_pixel(&self, entry: &LayerEntry, p: DVec2) -> Option<DVec2> {
        let ray: DVec3 = entry.thermal_from_view * entry.projection.ray(p);
        let q = self.lens.project(ray)?;
        self.lens.in_frame(q).then_some(q)
    }

    /// The thermal picture filling `rect`, where the view there shows it alone: the entry,
    /// and the thermal frame's extent in it (its top-left corner and size; the rest is the
    /// black bars where the aspects differ, unless the zoom fills them).
    pub fn alone_in(&self, rect: Rect) -> Option<(&LayerEntry, DVec2, DVec2)> {
        let e = self
            .entries
            .iter()
            .rev()
            .find(|e| e.black_outside && e.rect == rect)?;
        let whole = DVec2::new(rect.w as f64, rect.h as f64);
        let frame = DVec2::new(self.lens.width as f64, self.lens.height as f64);
        let size = (frame * (whole / frame).min_element() * self.zoom).min(whole);
        Some((e, (whole - size) / 2.0, size))
    }

    /// The entry drawn at output pixel (x, y): the last one holding it.
    pub fn entry_at(&self, x: u32, y: u32) -> Option<&LayerEntry> {
        self.entries.iter().rev().find(|e| {
            let r = e.rect;
            x >= r.x && y >= r.y && x < r.x + r.w && y < r.y + r.h
        })
    }

    /// The thermal frame's colours, as the GPU's colouring pass makes them.
    pub fn colours(&self) -> RgbaImage {
        colourise(&self.frame, &self.gain, self.palette)
    }

    /// The layer drawn over `out` (the output frame as RGB), in f64: each covered pixel's
    /// colour mixed with the thermal colour, bilinear between the thermal pixels, at its
    /// entry's share.
    pub fn draw_rgb(&self, out: &mut RgbImage) {
        let colours = self.colours();
        for y in 0..out.height() {
            for x in 0..out.width() {
                let Some(e) = self.entry_at(x, y) else {
                    continue;
                };
                let p = DVec2::new((x - e.rect.x) as f64 + 0.5, (y - e.rect.y) as f64 + 0.5);
                let (colour, alpha) = match self.thermal_pixel(e, p) {
                    Some(q) => (sample(&colours, q), e.alpha),
                    None if e.black_outside => ([0.0; 3], 1.0),
                    None => continue,
                };
                let px = out.get_pixel_mut(x, y);
                for (v, t) in px.0.iter_mut().zip(colour) {
                    *v = (*v as f64 * (1.0 - alpha) + t * alpha)
                        .round()
                        .clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
}

/// `colours` at OpenCV point `q`, bilinear, the edge pixels held beyond the edge (0..255).
pub fn sample(colours: &RgbaImage, q: DVec2) -> [f64; 3] {
    let (w, h) = (colours.width() as i64, colours.height() as i64);
    let (x0, y0) = (q.x.floor(), q.y.floor());
    let (fx, fy) = (q.x - x0, q.y - y0);
    let at = |x: f64, y: f64| {
        let x = (x as i64).clamp(0, w - 1) as u32;
        let y = (y as i64).clamp(0, h - 1) as u32;
        colours.get_pixel(x, y).0
    };
    let corners = [
        (at(x0, y0), (1.0 - fx) * (1.0 - fy)),
        (at(x0 + 1.0, y0), fx * (1.0 - fy)),
        (at(x0, y0 + 1.0), (1.0 - fx) * fy),
        (at(x0 + 1.0, y0 + 1.0), fx * fy),
    ];
    let mut c = [0.0; 3];
    for (px, weight) in corners {
        for i in 0..3 {
            c[i] += px[i] as f64 * weight;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_between_pixels_is_their_mean_and_past_the_edge_the_edge() {
        let mut img = RgbaImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgba([0, 100, 200, 255]));
        img.put_pixel(1, 0, image::Rgba([100, 200, 0, 255]));
        assert_eq!(sample(&img, DVec2::new(0.5, 0.0)), [50.0, 150.0, 100.0]);
        assert_eq!(sample(&img, DVec2::new(-3.0, 0.0)), [0.0, 100.0, 200.0]);
        assert_eq!(sample(&img, DVec2::new(1.0, 0.7)), [100.0, 200.0, 0.0]);
    }
}
