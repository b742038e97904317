//! The one time base, shared below everything: microseconds on the monotonic clock GStreamer
//! stamps buffers with (CLOCK_MONOTONIC). Capture times, the vehicle's attitude samples, the
//! autopilot's clock mapped onto ours and the tracked objects' sightings are all on it.

/// Microseconds on the monotonic clock GStreamer stamps buffers with (CLOCK_MONOTONIC):
/// the one time base of capture times and telemetry.
pub fn clock_us() -> u64 {
    gstreamer::get_timestamp().useconds()
}

/// A time on [`clock_us`] as microseconds since 1970 (the UNIX time KLV metadata carries),
/// by the system clock now.
pub fn unix_us(at: u64) -> u64 {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    now.saturating_sub(clock_us().saturating_sub(at))
}

/// When one frame passed each stage on its way to the stream, on [`clock_us`] (0 for a stage
/// not reached): captured (the source's stamp), in the slot, taken by the frame loop,
/// rendered and read back, handed to the encoder, out of the encoder, handed to the RTSP
/// clients, page viewers, recorder and relays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stamps {
    pub captured: u64,
    pub arrived: u64,
    pub taken: u64,
    pub rendered: u64,
    pub encoder_in: u64,
    pub encoded: u64,
    pub sent: u64,
}
