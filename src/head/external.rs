//! The external detector's side of the detection stage: another process's boxes (fisheye
//! pixels or angles, JSON lines on a local socket, `crate::detect::external`) become world
//! directions the tracker takes, through the lens at the state's attitude.

use super::Head;
use crate::detect::external::{Batch, Place};
use crate::detect::scan::{MOTION_VIEWS, visible};
use crate::detect::{AngularBox, Detection};
use crate::plan::FramePlan;
use crate::state::State;
use glam::DVec2;
use tracing::warn;

impl Head {
    /// The external detector's boxes as directions in the world (fisheye pixels through the
    /// lens at the state's attitude), and the views that cover the lens's field (what the
    /// detector was looking at). Boxes the lens does not image are left out.
    pub(super) fn external_boxes(
        &self,
        state: &State,
        batch: &Batch,
        labels: &mut Vec<String>,
    ) -> Option<(Vec<Detection>, FramePlan)> {
        // The frames' own size (what the sender's pixels are in), once one has come.
        let sensor = self.frame_size_or_sensor(state);
        let lens = match self.gate.settings().lenses().for_frame(
            state.settings.lens,
            sensor,
            state.settings.sensor.roi(),
        ) {
            Ok(lens) => lens,
            Err(e) => {
                warn!("detection: {e}");
                return None;
            }
        };
        let to_lens = crate::geometry::view::lens_from_world(
            state.vehicle.attitude.euler(),
            state.settings.mount.euler(),
        );
        let to_world = |p: DVec2| lens.unproject(p).map(|r| to_lens.transpose() * r);
        let mut found = vec![];
        for b in &batch.boxes {
            let bbox = match b.place {
                Place::Angles {
                    yaw,
                    pitch,
                    width,
                    height,
                } => AngularBox::new(yaw, pitch, width, height),
                Place::Pixels { x0, y0, x1, y1 } => {
                    let c = DVec2::new(x0 + x1, y0 + y1) / 2.0;
                    let rays = [c, DVec2::new(x0, c.y), DVec2::new(x1, c.y)]
                        .into_iter()
                        .chain([DVec2::new(c.x, y0), DVec2::new(c.x, y1)])
                        .map(to_world)
                        .collect::<Option<Vec<_>>>();
                    let Some(r) = rays else {
                        continue;
                    };
                    AngularBox {
                        centre: r[0],
                        width: r[1].angle_between(r[2]),
                        height: r[3].angle_between(r[4]),
                    }
                }
            };
            let class = match labels.iter().position(|l| *l == b.label) {
                Some(i) => i,
                None if labels.len() < u16::MAX as usize => {
                    labels.push(b.label.clone());
                    labels.len() - 1
                }
                None => continue,
            };
            found.push(Detection {
                bbox,
                confidence: b.confidence,
                class: class as u16,
                velocity: None,
            });
        }
        let (_, plan) = visible(&lens, to_lens, MOTION_VIEWS);
        Some((found, plan))
    }
}
