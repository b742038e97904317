//! The one time base, shared below everything: microseconds on the monotonic clock GStreamer
//! stamps buffers with (CLOCK_MONOTONIC). Capture times, the vehicle's attitude samples, the
//! autopilot's clock mapped onto ours and the tracked objects' sightings are all on it.

/// Microseconds on the monotonic clock GStreamer stamps buffers with (CLOCK_MONOTONIC):
/// the one time base of capture times and telemetry.
pub fn clock_us() -> u64 {
    gstreamer::get_timestamp().useconds()
}
