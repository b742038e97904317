//! The frame plan: for each view and detection tile of the output frame, its rectangle and how
//! its pixels map to world rays and fisheye pixels. Built once per frame from the state, the
//! lens and the vehicle's attitude: plain geometry on the shared data, below the renderers
//! that draw it (`crate::render`) and beside the services that reason with it (control,
//! cameras, detection, the scene, the KLV writer). `filter` is the minification filter a view
//! is drawn with, `thermal` where a thermal camera's picture lies over the views, `paint`
//! walks a plan pixel by pixel (the CPU reference and the ground truth paint through it).

pub mod filter;
pub mod paint;
pub mod thermal;

pub use filter::{Filter, MAX_LEVELS};

use crate::geometry::shutter::ShutterTable;
use crate::geometry::view::lens_from_world;
use crate::geometry::{Euler, Projection, rotation::direction};
use crate::layout::{Layout, LayoutError, Rect, Slot};
use crate::lens::Lens;
use crate::modes::Crop;
use crate::state::{State, Tracked};
use glam::{DMat3, DVec2, DVec3};
use std::sync::Arc;
use thermal::ThermalLayer;

/// The most samples per axis a minified view takes per output pixel.
pub const MAX_SAMPLES: u32 = 8;
/// The least and most pixels of one mip level that an output pixel may span for
/// [`FramePlan::cheapest_filter`] to draw from that level alone.
pub const ONE_LEVEL_FOOTPRINT: (f64, f64) = (0.6, 2.0);
/// Margin around a tracked object's angular size in its tile.
pub const TILE_MARGIN: f64 = 1.6;
/// The side of the square a camera that the layout does not show is measured in.
pub const UNSHOWN_VIEW: u32 = 540;
pub const TILE_FOV_RANGE: (f64, f64) = (0.02, 1.2);
/// [`crate::geometry::shutter::STEPS`], re-exported for the GPU twins.
pub const SHUTTER_STEPS: usize = crate::geometry::shutter::STEPS;

/// How a view's pixels find their colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewMap {
    /// A rectified view (crop modes 1, 2, 3 and detection tiles): view point → world ray.
    Rays {
        projection: Projection,
        world_from_view: DMat3,
    },
    /// An unrectified view (crop modes 0 and 4): view point p → fisheye point
    /// `origin + p · scale` (fisheye coordinates measured from its top-left corner).
    Fisheye { origin: DVec2, scale: f64 },
    /// An unknown crop mode, or a crop whose centre is outside the lens's view.
    Black,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedView {
    pub rect: Rect,
    pub map: ViewMap,
    /// Supersampling per axis: enough that a minified view does not alias.
    pub samples: u32,
}

#[derive(Clone, Debug)]
pub struct FramePlan {
    pub layout: Layout,
    pub views: Vec<PlannedView>,
    /// The lens at the fisheye frame's size.
    pub lens: Lens,
    /// The lens's orientation when the fisheye frame's middle row was read.
    pub lens_from_world: DMat3,
    /// The rolling shutter's rotations, row by row (None: a global shutter).
    pub shutter: Option<ShutterTable>,
    /// The thermal camera's picture over the views (None: none shows it).
    pub thermal: Option<Arc<ThermalLayer>>,
}

impl FramePlan {
    /// Plans the output frame of `state` for fisheye frames that `lens` describes.
    pub fn new(state: &State, lens: &Lens) -> Result<FramePlan, LayoutError> {
        let settings = &state.settings;
        let layout = settings.output.layout()?;
        let vehicle = state.vehicle.attitude.euler();
        let position = &state.vehicle.position;
        let lens_from_world = lens_from_world(vehicle, settings.mount.euler());
        let mut views = Vec::new();
        for (i, &(rect, slot)) in layout.views.iter().enumerate() {
            let map = match slot {
                Slot::Debug => debug_map(rect, lens),
                _ => {
                    let cam = &settings.cameras[i];
                    camera_map(
                        rect,
                        cam.crop(),
                        cam.fov(),
                        cam.steering().world_from_view(vehicle, position),
                        lens,
                        &lens_from_world,
                    )
                }
            };
            views.push(PlannedView {
                rect,
                map,
                samples: 1,
            });
        }
        for (rect, obj) in layout.tiles.iter().zip(&state.tracked) {
            views.push(PlannedView {
                rect: *rect,
                map: tile_map(*rect, obj),
                samples: 1,
            });
        }
        let mut plan = FramePlan {
            layout,
            views,
            lens: lens.clone(),
            lens_from_world,
            shutter: None,
            thermal: None,
        };
        for i in 0..plan.views.len() {
            plan.views[i].samples = plan.samples_for(&plan.views[i]);
        }
        Ok(plan)
    }

    /// Camera `i` alone, filling a `width` × `height` frame: a per-view stream's picture and a
    /// camera's still, with the same crop mode, fov and aim as in the composed frame.
    pub fn single_view(state: &State, lens: &Lens, i: usize, width: u32, height: u32) -> FramePlan {
        let rect = Rect::new(0, 0, width, height);
        let vehicle = &state.vehicle;
        let mount = state.settings.mount.euler();
        let lens_from_world = lens_from_world(vehicle.attitude.euler(), mount);
        let cam = &state.settings.cameras[i];
        let world_from_view = cam
            .steering()
            .world_from_view(vehicle.attitude.euler(), &vehicle.position);
        let map = camera_map(
            rect,
            cam.crop(),
            cam.fov(),
            world_from_view,
            lens,
            &lens_from_world,
        );
        let mut plan = FramePlan {
            layout: Layout {
                width,
                height,
                views: vec![(rect, Slot::Square)],
                overlay_box: Rect::new(0, 0, 0, 0),
                tiles: vec![],
            },
            views: vec![PlannedView {
                rect,
                map,
                samples: 1,
            }],
            lens: lens.clone(),
            lens_from_world,
            shutter: None,
            thermal: None,
        };
        plan.views[0].samples = plan.samples_for(&plan.views[0]);
        plan
    }

    /// Level rectilinear views aimed at world directions (yaw, pitch, fov across; radians),
    /// each `width` × `height` pixels, tiled row by row in one frame: the detector's input, scan views
    /// and crops around objects. The frame is as wide as a row of `columns` views.
    pub fn mosaic(
        lens: &Lens,
        lens_from_world: DMat3,
        aims: &[(f64, f64, f64)],
        (width, height): (u32, u32),
        columns: u32,
    ) -> FramePlan {
        let columns = columns.max(1);
        let rows = (aims.len() as u32).div_ceil(columns).max(1);
        let mut plan = FramePlan {
            layout: Layout {
                width: columns * width,
                height: rows * height,
                views: vec![],
                overlay_box: Rect::new(0, 0, 0, 0),
                tiles: vec![],
            },
            views: vec![],
            lens: lens.clone(),
            lens_from_world,
            shutter: None,
            thermal: None,
        };
        for (i, &(yaw, pitch, fov)) in aims.iter().enumerate() {
            let i = i as u32;
            let rect = Rect::new(i % columns * width, i / columns * height, width, height);
            plan.layout.views.push((rect, Slot::Square));
            let mut view = PlannedView {
                rect,
                map: ViewMap::Rays {
                    projection: Projection::Rectilinear {
                        width: width as f64,
                        height: height as f64,
                        fov,
                    },
                    world_from_view: Euler::new(yaw, pitch, 0.0).matrix(),
                },
                samples: 1,
            };
            view.samples = plan.samples_for(&view);
            plan.views.push(view);
        }
        plan
    }

    /// Camera `i`'s view as the frame draws it or, when the layout does not show that camera,
    /// as a square of [`UNSHOWN_VIEW`] pixels (what CAM_OFFSET and CAM_TARGET measure in).
    pub fn camera_view(&self, state: &State, i: usize) -> PlannedView {
        match self.shows_camera(i) {
            true => self.views[i],
            false => {
                let rect = Rect::new(0, 0, UNSHOWN_VIEW, UNSHOWN_VIEW);
                let cam = &state.settings.cameras[i];
                let vehicle = &state.vehicle;
                let world_from_view = cam
                    .steering()
                    .world_from_view(vehicle.attitude.euler(), &vehicle.position);
                PlannedView {
                    rect,
                    map: camera_map(
                        rect,
                        cam.crop(),
                        cam.fov(),
                        world_from_view,
                        &self.lens,
                        &self.lens_from_world,
                    ),
                    samples: 1,
                }
            }
        }
    }

    /// The same plan for a frame read out by a rolling shutter: `shutter` is its table (from
    /// [`ShutterTable::new`], around the middle row, whose attitude the plan was made with).
    pub fn with_shutter(mut self, shutter: Option<ShutterTable>) -> FramePlan {
        self.shutter = shutter;
        self
    }

    /// The same plan with `layer` drawn over its views.
    pub fn with_thermal(mut self, layer: Option<Arc<ThermalLayer>>) -> FramePlan {
        self.thermal = layer;
        self
    }

    /// Where a ray in the lens frame (as the lens was at the middle row) lands in the fisheye
    /// (OpenCV pixels), whether or not inside the frame; None outside the lens's fov. With a
    /// rolling shutter, projected again [`SHUTTER_STEPS`] times with the rotation of the row
    /// it landed on: the point where the row read saw the ray.
    pub fn lens_pixel(&self, ray: DVec3) -> Option<DVec2> {
        match &self.shutter {
            Some(shutter) => shutter.project(ray, |r| self.lens.project(r)),
            None => self.lens.project(ray),
        }
    }

    /// The ray in the lens frame (as the lens was at the middle row) that fisheye point `q`
    /// saw when its row was read; None where the lens model has no ray.
    pub fn lens_ray(&self, q: DVec2) -> Option<DVec3> {
        let ray = self.lens.unproject(q)?;
        Some(match &self.shutter {
            Some(shutter) => shutter.at(q).conjugate() * ray,
            None => ray,
        })
    }

    /// Whether the frame draws camera `i`'s view (a debug panel does not count).
    pub fn shows_camera(&self, i: usize) -> bool {
        matches!(self.layout.views.get(i), Some(&(_, slot)) if slot != Slot::Debug)
    }

    /// Where a round thing of angular diameter `size` seen along `ray` shows in a view: its
    /// centre (view pixels, as [`FramePlan::view_point`]) and its radius there, the mean
    /// distance to the points of its rim the view shows (0 where it shows none). None where
    /// the view does not show its centre.
    pub fn view_circle(&self, view: &PlannedView, ray: DVec3, size: f64) -> Option<(DVec2, f64)> {
        let centre = self.view_point(view, ray)?;
        let (u, v) = ray.any_orthonormal_pair();
        let (sin, cos) = (size / 2.0).sin_cos();
        let rim: Vec<f64> = [u, -u, v, -v]
            .iter()
            .filter_map(|&side| self.view_point(view, ray * cos + side * sin))
            .map(|p| p.distance(centre))
            .collect();
        Some((centre, rim.iter().sum::<f64>() / rim.len().max(1) as f64))
    }

    /// The fisheye pixel (OpenCV coordinates) seen at point `p` of a view, None where the
    /// output is black (outside the lens's fov or the fisheye frame).
    pub fn fisheye_pixel(&self, view: &PlannedView, p: DVec2) -> Option<DVec2> {
        let q = match view.map {
            ViewMap::Rays {
                projection,
                world_from_view,
            } => self.lens_pixel(self.lens_from_world * world_from_view * projection.ray(p))?,
            ViewMap::Fisheye { origin, scale } => {
                let q = origin + p * scale - DVec2::splat(0.5);
                self.lens.unproject(q)?;
                q
            }
            ViewMap::Black => return None,
        };
        self.lens.in_frame(q).then_some(q)
    }

    /// The world ray seen at point `p` of a view, None where the output is black. Same mask as
    /// [`FramePlan::fisheye_pixel`].
    pub fn world_ray(&self, view: &PlannedView, p: DVec2) -> Option<DVec3> {
        let q = self.fisheye_pixel(view, p)?;
        match view.map {
            ViewMap::Rays {
                projection,
                world_from_view,
            } => Some(world_from_view * projection.ray(p)),
            _ => Some(self.lens_from_world.transpose() * self.lens_ray(q)?),
        }
    }

    /// The world ray a view's point `p` looks along, whether or not the lens images it (a
    /// rectified view's own projection, an unrectified view's fisheye point unprojected);
    /// None for a black view or a point the lens model has no ray for.
    pub fn view_ray(&self, view: &PlannedView, p: DVec2) -> Option<DVec3> {
        match view.map {
            ViewMap::Rays {
                projection,
                world_from_view,
            } => Some(world_from_view * projection.ray(p)),
            ViewMap::Fisheye { origin, scale } => {
                Some(self.lens_from_world.transpose() * self.lens_ray(origin + p * scale)?)
            }
            ViewMap::Black => None,
        }
    }

    /// Where a world ray shows in a view (view pixels from its top-left corner), None where
    /// the view does not show it: the inverse of [`FramePlan::world_ray`].
    pub fn view_point(&self, view: &PlannedView, ray: DVec3) -> Option<DVec2> {
        let p = match view.map {
            ViewMap::Rays {
                projection,
                world_from_view,
            } => projection.point(world_from_view.transpose() * ray)?,
            ViewMap::Fisheye { origin, scale } => {
                let q = self.lens_pixel(self.lens_from_world * ray)?;
                (q + DVec2::splat(0.5) - origin) / scale
            }
            ViewMap::Black => return None,
        };
        let size = DVec2::new(view.rect.w as f64, view.rect.h as f64);
        let inside = p.cmpge(DVec2::ZERO).all() && p.cmplt(size).all();
        (inside && self.fisheye_pixel(view, p).is_some()).then_some(p)
    }

    /// Fisheye pixels per output pixel, worst case over a grid of the view, rounded up.
    fn samples_for(&self, view: &PlannedView) -> u32 {
        (self.footprints(view).1.ceil() as u32).clamp(1, MAX_SAMPLES)
    }

    /// The least and the most fisheye pixels one output pixel of `view` spans, across or
    /// down, over a 9x9 grid of its pixels ((∞, 0) where none images the fisheye).
    pub fn footprints(&self, view: &PlannedView) -> (f64, f64) {
        let r = view.rect;
        let (mut least, mut most) = (f64::INFINITY, 0.0f64);
        for i in 0..=8 {
            for j in 0..=8 {
                let p = DVec2::new(
                    r.w as f64 * (0.05 + 0.9 * i as f64 / 8.0),
                    r.h as f64 * (0.05 + 0.9 * j as f64 / 8.0),
                );
                let (Some(a), Some(bx), Some(by)) = (
                    self.fisheye_pixel(view, p),
                    self.fisheye_pixel(view, p + DVec2::X),
                    self.fisheye_pixel(view, p + DVec2::Y),
                ) else {
                    continue;
                };
                let wide = (bx - a).length().max((by - a).length());
                (least, most) = (least.min(wide), most.max(wide));
            }
        }
        (least, most)
    }

    /// The cheaper way to draw the plan alike, where there is one: the bilinear filter from
    /// one level `k` of the mip chain when every view's pixels span between
    /// [`ONE_LEVEL_FOOTPRINT`]'s bounds of that level's pixels (at level 0, no lower bound:
    /// magnified pixels are what trilinear draws there too); else the mip filter. Trilinear
    /// draws a pixel at its own level of detail, blending two levels, from the wider of its
    /// footprint's two sides (so it blurs along the other); one level drawn this way is at
    /// most one level sharper (aliasing only detail finer than 2 of its pixels, which a lens
    /// and demosaic rarely pass) or 0.74 blurrier. Against ground truth it scores as well or
    /// better (tests/it/view_filters.rs); on a software rasterizer it draws in half the time.
    pub fn cheapest_filter(&self) -> (Filter, u32) {
        let (least, most) = self
            .views
            .iter()
            .map(|v| self.footprints(v))
            .fold((f64::INFINITY, 0.0f64), |(l, m), (vl, vm)| {
                (l.min(vl), m.max(vm))
            });
        let (low, high) = ONE_LEVEL_FOOTPRINT;
        if most <= high {
            return (Filter::Bilinear, 0);
        }
        let k = (most / high).log2().ceil();
        match least / k.exp2() >= low && k < MAX_LEVELS as f64 {
            true => (Filter::Bilinear, k as u32),
            false => (Filter::Mip, 0),
        }
    }
}

fn camera_map(
    rect: Rect,
    crop_mode: Crop,
    fov: f64,
    world_from_view: DMat3,
    lens: &Lens,
    lens_from_world: &DMat3,
) -> ViewMap {
    let (w, h) = (rect.w as f64, rect.h as f64);
    match crop_mode {
        Crop::Rectilinear | Crop::RectifiedCrop | Crop::Panorama => {
            let view = Euler::from_matrix(&world_from_view);
            let projection =
                Projection::for_view(crop_mode, w, h, fov, view).expect("rectified crop mode");
            ViewMap::Rays {
                projection,
                world_from_view,
            }
        }
        Crop::FisheyeCrop => {
            // An axis-aligned crop of the fisheye around where the view's forward ray lands,
            // as wide as the view's fov at the lens's radial scale there.
            let fwd = *lens_from_world * world_from_view * DVec3::X;
            let Some(centre) = lens.project(fwd) else {
                return ViewMap::Black;
            };
            let theta = fwd.x.hypot(fwd.y).atan2(fwd.z);
            let scale = fov * lens.pixels_per_radian(theta) / w;
            let centre = centre + DVec2::splat(0.5);
            ViewMap::Fisheye {
                origin: centre - DVec2::new(w, h) * 0.5 * scale,
                scale,
            }
        }
        Crop::Whole => debug_map(rect, lens),
        _ => ViewMap::Black,
    }
}

/// The whole fisheye frame fitted into the view, aspect kept, centred.
fn debug_map(rect: Rect, lens: &Lens) -> ViewMap {
    let (fw, fh) = (lens.width as f64, lens.height as f64);
    let scale = (fw / rect.w as f64).max(fh / rect.h as f64);
    let origin = DVec2::new(fw, fh) * 0.5 - DVec2::new(rect.w as f64, rect.h as f64) * 0.5 * scale;
    ViewMap::Fisheye { origin, scale }
}

/// A level rectilinear view aimed at a tracked object, framing it with a margin.
/// The field across a detection tile showing an object `size` radians across.
pub fn tile_fov(size: f64) -> f64 {
    (size * TILE_MARGIN).clamp(TILE_FOV_RANGE.0, TILE_FOV_RANGE.1)
}

fn tile_map(rect: Rect, obj: &Tracked) -> ViewMap {
    let fov = tile_fov(obj.size);
    let aim = direction(obj.yaw, obj.pitch);
    let (yaw, pitch) = crate::geometry::rotation::yaw_pitch(aim);
    ViewMap::Rays {
        projection: Projection::Rectilinear {
            width: rect.w as f64,
            height: rect.h as f64,
            fov,
        },
        world_from_view: Euler::new(yaw, pitch, 0.0).matrix(),
    }
}
