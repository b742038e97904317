//! DigiView: an onboard fisheye "virtual camera" video head.
//!
//! The modules follow the data's path: `lens` (fisheye models and lens.cal) and `geometry`
//! (frames, attitudes, the ground) are the shared math; `layout` places views in the output
//! frame; `state` is everything an operator can set; `scene` synthesises fisheye input and
//! ground truth from a known world; `render` turns a fisheye frame into the output frame;
//! `image_ops` holds the sampling and image metrics both sides share; `source` brings camera
//! frames in, `stream` encodes and serves them, `head` runs the frame loop between them, and
//! `cli` is the command line.

pub mod cli;
pub mod control;
pub mod frame;
pub mod geometry;
pub mod gst;
pub mod head;
pub mod image_ops;
pub mod layout;
pub mod lens;
pub mod protocol;
pub mod render;
pub mod scene;
pub mod source;
pub mod state;
pub mod stream;
pub mod units;
