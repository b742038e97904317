//! The one time base, shared below everything: microseconds on the monotonic clock GStreamer
//! stamps buffers with (CLOCK_MONOTONIC). Capture times, the vehicle's attitude samples, the
//! autopilot's clock mapped onto ours and the tracked objects' sightings are all on it.

/// Microseconds on the monotonic clock GStreamer stamps buffers with (CLOCK_MONOTONIC):
/// the one time base of capture times and telemetry.
pub fn clock_us() -> u64 {
    gstreamer::get_timestamp().useconds()
}

/// A time on [`clock_us`] as microseconds since 1970 (the UNIX time KLV metadata, stills,
/// file names and the control protocol's frames carry): [`clock_us`] plus where its zero lies
/// on the system clock, read at each call. That zero only moves forward: a system clock set
/// forward (GPS or NTP setting a clock that booted behind) is followed at once, one set back
/// is not, so the UNIX times DigiView gives never go back, and run ahead of the system clock
/// by the step until the next start. Each step over a second is logged once.
pub fn unix_us(at: u64) -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    /// The UNIX time of [`clock_us`]'s zero, µs, as given so far (0: not read yet).
    static ZERO: AtomicU64 = AtomicU64::new(0);
    /// The last zero the system clock was seen stepped back to, so each step logs once.
    static BACK: AtomicU64 = AtomicU64::new(0);
    let wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64);
    let seen = wall.saturating_sub(clock_us());
    let zero = ZERO.fetch_max(seen, Ordering::Relaxed);
    const STEP: u64 = 1_000_000;
    if zero != 0 && seen > zero + STEP {
        tracing::warn!(
            "the system clock was set forward {:.1} s: UNIX times follow it",
            (seen - zero) as f64 / 1e6
        );
    } else if seen + STEP < zero && BACK.swap(seen, Ordering::Relaxed).abs_diff(seen) > STEP {
        tracing::warn!(
            "the system clock was set back {:.1} s: UNIX times go on from where they were \
             (ahead of the system clock by as much), so they never go back",
            (zero - seen) as f64 / 1e6
        );
    }
    zero.max(seen) + at
}

/// Now as microseconds since 1970, never going back ([`unix_us`]).
pub fn utc_us() -> u64 {
    unix_us(clock_us())
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
