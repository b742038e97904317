//! Frames and angles as `shared/spec/conventions.md` defines them: world NED, body FRD, the
//! fisheye mount, the lens frame, user views with lock flags, and the ground.
//!
//! Shared math, upstream of every renderer and of the protocol: nothing here knows about
//! images or sockets. All angles are radians, all vectors f64.

pub mod attitude;
pub mod ground;
pub mod position_track;
pub mod projection;
pub mod rotation;
pub mod shutter;
pub mod view;

pub use attitude::AttitudeTrack;
pub use ground::{GeoPoint, GeoPosition};
pub use position_track::{PositionSample, PositionTrack};
pub use projection::Projection;
pub use rotation::{Euler, wrap_pi};
pub use view::{LockFlags, lens_from_world, view_orientation};

#[cfg(test)]
mod tests;
