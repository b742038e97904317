//! The frame loop's beat, as pure arithmetic on times measured from the loop's start: when the
//! next frame is due, how long to wait for a fresh one, whether showing the last one again is
//! worth a render, and each output frame's timestamp.
//!
//! Frames go out a period apart. A frame that was waiting when its turn came keeps that steady
//! beat; one that came in late sets the beat from its arrival, so the loop locks onto a source
//! of the same rate and frames wait little. With no new frame by half a period past due, the
//! last one is shown again (views may have moved), or "no signal" once the source has been
//! silent for a second.

use std::time::Duration;

/// How often an unchanged frame is sent again anyway, to keep decoders fed.
pub const KEEPALIVE: Duration = Duration::from_secs(1);
/// The least step between two output timestamps.
pub const MIN_PTS_STEP: Duration = Duration::from_millis(1);

/// The beat of one frame loop; every time is a duration since the loop started.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pacer {
    next_due: Duration,
    last_pts: Duration,
}

impl Pacer {
    /// When the next frame is due.
    pub fn due(&self) -> Duration {
        self.next_due
    }

    /// Until when to wait for a fresh frame once it is due (or now, if later): half a period.
    pub fn wait_until(&self, now: Duration, period: Duration) -> Duration {
        self.next_due.max(now) + period / 2
    }

    /// Sets when the frame after this one is due: a period after `due` when the frame taken
    /// had `arrived` by then, less half of what it waited (at most a 64th of a period) when
    /// it was the only one since the last (`replaced` is false). So frames that come a
    /// steady part of a period before their turn, or a little sooner each time (a source a
    /// hair faster than the output), stop waiting within a second or two, while a source
    /// faster than the output, or one that makes a frame only when the last was taken (the
    /// demo), cannot pull the output more than 1.6 % above its rate. Nine tenths of a
    /// period after its arrival when it came later, and half a period from `now` when none
    /// came. Never more than a period behind `now`, so a slow frame does not cause a burst.
    pub fn taken(
        &mut self,
        due: Duration,
        arrived: Option<Duration>,
        replaced: bool,
        now: Duration,
        period: Duration,
    ) {
        self.next_due = match arrived {
            Some(a) if a <= due && replaced => due + period,
            Some(a) if a <= due => due + period - ((due - a) / 2).min(period / 64),
            Some(a) => a + period * 9 / 10,
            None => now + period / 2,
        }
        .max(now.saturating_sub(period));
    }

    /// Whether to render now: always for a fresh frame, the "no signal" frame or views that
    /// moved; an unchanged repeat only once per [`KEEPALIVE`] (else it would only delay the
    /// next fresh frame).
    pub fn worth_rendering(&self, fresh: bool, signal: bool, moved: bool, now: Duration) -> bool {
        let repeat = !fresh && signal;
        !(repeat && !moved && self.last_pts + KEEPALIVE > now)
    }

    /// The timestamp of a frame shown `now`: never less than [`MIN_PTS_STEP`] after the last.
    pub fn pts(&mut self, now: Duration) -> Duration {
        self.last_pts = now.max(self.last_pts + MIN_PTS_STEP);
        self.last_pts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: Duration = Duration::from_micros(33_333);

    fn ms(v: f64) -> Duration {
        Duration::from_secs_f64(v / 1e3)
    }

    #[test]
    fn a_frame_waiting_when_due_keeps_the_beat_and_a_late_one_sets_it() {
        let mut p = Pacer::default();
        p.taken(ms(100.0), Some(ms(100.0)), false, ms(101.0), PERIOD);
        assert_eq!(p.due(), ms(100.0) + PERIOD);
        // One that waited 10 ms pulls the beat a 64th of a period towards the arrivals...
        p.taken(ms(100.0), Some(ms(90.0)), false, ms(101.0), PERIOD);
        assert_eq!(p.due(), ms(100.0) + PERIOD - PERIOD / 64);
        // ...unless it replaced others: the source is faster, the output keeps its rate.
        p.taken(ms(100.0), Some(ms(90.0)), true, ms(101.0), PERIOD);
        assert_eq!(p.due(), ms(100.0) + PERIOD);
        p.taken(ms(100.0), Some(ms(110.0)), false, ms(111.0), PERIOD);
        assert_eq!(p.due(), ms(110.0) + PERIOD * 9 / 10);
        // No frame: look again half a period later.
        p.taken(ms(100.0), None, false, ms(116.0), PERIOD);
        assert_eq!(p.due(), ms(116.0) + PERIOD / 2);
        // A fresh frame is awaited until half a period past due, or past now if later.
        assert_eq!(p.wait_until(ms(120.0), PERIOD), p.due() + PERIOD / 2);
        assert_eq!(p.wait_until(ms(140.0), PERIOD), ms(140.0) + PERIOD / 2);
    }

    #[test]
    fn after_a_slow_frame_the_next_is_due_at_most_a_period_back_not_in_a_burst() {
        let mut p = Pacer::default();
        // Due at 100 ms, the frame was waiting, but the render took until 400 ms.
        p.taken(ms(100.0), Some(ms(95.0)), false, ms(400.0), PERIOD);
        assert_eq!(p.due(), ms(400.0) - PERIOD);
    }

    /// The frame loop at `period` against a camera whose frames arrive at `arrival(k)`,
    /// rendering in 12 ms, for 10 s: how many frames came and were shown, and how long each
    /// shown one waited.
    fn run_against(
        period: Duration,
        arrival: impl Fn(u32) -> Duration,
    ) -> (u32, u32, Vec<Duration>) {
        let render = ms(12.0);
        let mut p = Pacer::default();
        let (mut now, mut next_frame, mut waits, mut shown) = (Duration::ZERO, 0, vec![], 0);
        while now < Duration::from_secs(10) {
            let due = p.due();
            now = now.max(due);
            let deadline = p.wait_until(now, period);
            // The slot hands over the newest frame that has come (older ones are dropped),
            // else waits for the next one until the deadline.
            let (mut arrived, mut replaced) = (None, false);
            while arrival(next_frame) <= now {
                replaced |= arrived.is_some();
                arrived = Some(arrival(next_frame));
                next_frame += 1;
            }
            if arrived.is_none() && arrival(next_frame) <= deadline {
                arrived = Some(arrival(next_frame));
                next_frame += 1;
            }
            now = match arrived {
                Some(a) => now.max(a),
                None => deadline,
            };
            if let Some(a) = arrived {
                waits.push(now - a);
                shown += 1;
            }
            p.taken(due, arrived, replaced, now, period);
            now += render;
        }
        (next_frame, shown, waits)
    }

    #[test]
    fn against_a_camera_of_the_same_rate_the_loop_locks_on_and_takes_each_frame_as_it_comes() {
        // A 30 fps camera starting 7 ms into the loop.
        let (next_frame, shown, waits) = run_against(PERIOD, |k| ms(7.0) + PERIOD * k);
        assert!(
            next_frame - shown <= 1,
            "{} of {next_frame} frames dropped",
            next_frame - shown
        );
        let locked = &waits[30..];
        let worst = locked.iter().max().unwrap();
        assert!(
            *worst <= ms(1.0),
            "frames waited up to {worst:?} once locked"
        );
    }

    #[test]
    fn against_a_slightly_faster_jittery_camera_frames_wait_little() {
        // 30.3 fps, each frame up to 4 ms early or late (its synthesis or readout varies).
        let (_, _, waits) = run_against(PERIOD, |k| {
            ms(24.0 + 33.0 * k as f64 + 4.0 * (k as f64 * 2.399).sin())
        });
        let mut locked = waits[30..].to_vec();
        locked.sort();
        let p90 = locked[locked.len() * 9 / 10];
        assert!(p90 <= ms(5.0), "one frame in ten waited {p90:?} or more");
    }

    #[test]
    fn a_camera_twice_as_fast_as_the_output_leaves_the_output_at_its_rate() {
        // A 30 fps camera with 4 ms of jitter, 15 fps out: 150 frames in 10 s.
        let (_, shown, _) = run_against(PERIOD * 2, |k| {
            ms(9.0 + 33.333 * k as f64 + 4.0 * (k as f64 * 2.399).sin())
        });
        assert!(
            (145..=155).contains(&shown),
            "{shown} frames in 10 s at 15 fps"
        );
    }

    #[test]
    fn an_unchanged_repeat_is_rendered_only_once_a_second() {
        let mut p = Pacer::default();
        p.pts(ms(1000.0));
        assert!(p.worth_rendering(true, true, false, ms(1010.0)), "fresh");
        assert!(
            p.worth_rendering(false, true, true, ms(1010.0)),
            "views moved"
        );
        assert!(
            p.worth_rendering(false, false, false, ms(1010.0)),
            "no signal"
        );
        assert!(!p.worth_rendering(false, true, false, ms(1500.0)), "repeat");
        assert!(
            p.worth_rendering(false, true, false, ms(2000.0)),
            "keepalive"
        );
    }

    #[test]
    fn timestamps_always_move_forward_by_at_least_a_millisecond() {
        let mut p = Pacer::default();
        assert_eq!(p.pts(ms(50.0)), ms(50.0));
        assert_eq!(p.pts(ms(50.0)), ms(51.0));
        assert_eq!(p.pts(ms(50.5)), ms(52.0));
        assert_eq!(p.pts(ms(80.0)), ms(80.0));
    }
}
