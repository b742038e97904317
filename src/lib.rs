//! DigiView: an onboard fisheye "virtual camera" video head.
//!
//! The modules follow the data's path. Shared below everything: `units` (angles and sizes as
//! people write them), `geometry` (frames, attitudes, view orientation, the ground), `lens`
//! (the lens models, lens.cal, importers), `layout` (where views sit in the output frame),
//! `frame` (frames as bytes: pixel formats, plane layouts, YUV) and `image_ops` (sampling and
//! image metrics). `state` is everything an operator can set and the live handle the frame
//! loop snapshots once per frame. Then the path itself: `source` brings camera frames in
//! (`exposure` sets the camera's exposure and gain, and runs the auto exposure),
//! `render` turns a fisheye frame into the output frame (`gpu`, and the CPU reference),
//! `stream` encodes and serves it, and `head` runs the frame loop between them; `gst` is the
//! GStreamer plumbing the sources and the stream share, and `scene` synthesises fisheye input
//! and ground truth from a known world. Beside the path, changing the live state: `protocol`
//! (the control protocol's codec) and `control` (its request handling, server and client),
//! `autopilot` (the MAVLink link the vehicle's attitude and position come in on) and `cameras`
//! (each view a MAVLink camera and gimbal on that link); `http` is the head's HTTP server;
//! `detect` finds and tracks objects in crops of the frames, for the detection tiles.
//! `cli` is the command line.

pub mod autopilot;
pub mod cameras;
pub mod cli;
pub mod control;
pub mod detect;
pub mod exposure;
pub mod frame;
pub mod geometry;
pub mod gst;
pub mod head;
pub mod http;
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
