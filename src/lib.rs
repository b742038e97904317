//! DigiView: an onboard fisheye "virtual camera" video head.
//!
//! The modules stand in layers; each imports only from layers below it (or beside it, where
//! named here).
//!
//! - **Shared data, at the bottom.** `units` (angles and sizes as people write them),
//!   `geometry` (frames, attitudes, view orientation, the ground), `lens` (the lens models,
//!   lens.cal, importers, calibration), `layout` (where views sit in the output frame),
//!   `plan` (the frame plan: each view's rectangle and how its pixels map to rays and fisheye
//!   pixels, the geometry every service and both renderers share),
//!   `frame` (frames as bytes: pixel formats, plane layouts, YUV), `image_ops` (sampling and
//!   image metrics), `thermal` (a thermal sensor's counts: temperatures, gain, palettes),
//!   `gst` (the GStreamer plumbing sources and streams share), `clock` (the one time base),
//!   `modes` (the modes an operator picks, as enums, and the GPU backend), `protocol` (the control protocol's
//!   codec), `policy` (the one trust boundary: who may change the state, stop the system or
//!   delete files, and the refusal log every control path shares), `supervise` (a service's
//!   thread run again after a panic, its failures reported through a trait the head's report
//!   implements). On them: `state`, the live state in three parts (what an
//!   operator sets, validated by the one table of rules, with the one set of view operations
//!   that steer a view; what the head reports; what the vehicle sends and the detector sees),
//!   the one gate every control path changes the settings through, and the capture hooks
//!   (`state::capture`); `telemetry`, the vehicle's attitude history and position, which the
//!   autopilot link writes and the frame loop reads.
//! - **The data's path.** `source` brings camera frames in (`exposure` sets the camera's
//!   exposure and gain, and runs the auto exposure; `scene` synthesises worlds for the demo
//!   and ground truth), `render` turns a fisheye frame into the output frame as its plan says
//!   (`gpu`, on the adapter `choose` finds drawing right, and the CPU reference; only the
//!   frame loop, `bench` and the CLI use it), `stream` encodes, serves, records and
//!   publishes it.
//! - **The services, beside each other.** `head`, the frame loop along the path (with its
//!   detection stage, which runs `detect`'s detectors and tracker); `control`, the DigiView
//!   protocol's request handling, server and client; `autopilot`, the MAVLink link the
//!   vehicle's attitude and position come in on; `cameras`, each view a MAVLink camera and
//!   gimbal, speaking on the link through the trait and outbox `autopilot` owns; `payload`,
//!   one view as the payload SDK's payload on a link of its own, through `cameras`; `http`, the
//!   tuning page and its JSON API, through `control`'s request handling. Every one that
//!   changes the settings asks `state::Gate` once per request and steers a view by its view
//!   operations. Each owns its section of the serve configuration, and reaches no other
//!   service but as named here: what it needs of another is a small trait or hook of its own
//!   that the assembly fills.
//! - **On top.** `app`, the serve assembly: the configuration file, every service built and
//!   wired; `cli`, the command line.

pub mod app;
pub mod autopilot;
pub mod cameras;
pub mod cli;
pub mod clock;
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
pub mod modes;
pub mod payload;
pub mod plan;
pub mod policy;
pub mod protocol;
pub mod render;
pub mod scene;
pub mod source;
pub mod state;
pub mod stream;
pub mod supervise;
pub mod telemetry;
pub mod thermal;
pub mod units;
