//! Which watched views alone are drawn with this frame. The composed stream comes first: the
//! views share the frame loop's time left in each period after the composed frame, the
//! scans and crops (what a view costs and what the rest takes are followed as running
//! means). That time is saved up from frame to frame as a credit, and once it covers every
//! watched view they are drawn together, in one submission: the views show the same instant,
//! and only the first shares the machine with the composed frame's encoding. While the
//! source's next frame already waits, the loop is a period behind its source and the views
//! wait too: drawn then, they would let the frame after replace that one unshown (a composed
//! frame dropped). Where the machine has time for every view every frame (a GPU), every view
//! is drawn every frame; where it has not (a software rasterizer on two cores), the views'
//! own streams run at a lower rate, but a view is never left undrawn for longer than
//! [`MAX_GAP`].

use crate::stream::rtsp::VIEW_MOUNTS;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// A watched view is drawn at least this often, whatever the budget.
pub const MAX_GAP: Duration = Duration::from_millis(250);
/// The share of each period the frame loop may fill, views included; the rest absorbs
/// what varies from frame to frame.
const BUSY_SHARE: f64 = 0.97;
/// Weight of the newest figure in the running means.
const NEWEST: f64 = 0.2;

#[derive(Default)]
pub(super) struct ViewPacing {
    /// When each view was last drawn.
    last: [Option<Instant>; VIEW_MOUNTS],
    /// The frame loop's time per frame besides the views, ms (running mean).
    busy_ms: Option<f64>,
    /// One view's drawing time, ms (running mean).
    view_ms: Option<f64>,
    /// The views' drawing time in the frame under way.
    this_frame: Duration,
    /// Time saved up for views, ms (negative: owed, after views drawn for `MAX_GAP`).
    credit: f64,
}

fn mean(old: Option<f64>, new: f64) -> Option<f64> {
    Some(old.map_or(new, |o| o + NEWEST * (new - o)))
}

impl ViewPacing {
    /// Of the views `watched`, those to draw with this frame, `period` long, at `now`;
    /// `behind`: the source's next frame already waits.
    pub fn pick(
        &mut self,
        watched: [bool; VIEW_MOUNTS],
        period: Duration,
        now: Instant,
        behind: bool,
    ) -> [bool; VIEW_MOUNTS] {
        let waited = |i: usize| self.last[i].map_or(Duration::MAX, |t| now - t);
        let mut order: Vec<usize> = (0..VIEW_MOUNTS).filter(|&i| watched[i]).collect();
        order.sort_by_key(|&i| std::cmp::Reverse(waited(i)));
        let mut draw = [false; VIEW_MOUNTS];
        // Until both costs are known, every watched view is drawn (and measured).
        let (Some(busy), Some(view)) = (self.busy_ms, self.view_ms) else {
            order.into_iter().for_each(|i| draw[i] = true);
            return draw;
        };
        let period_ms = period.as_secs_f64() * 1e3;
        // Saved up to a round of the watched views beyond this period's spare time (a round
        // that costs a little more than a period's spare time is drawn in most periods, not
        // every other one; no burst after a pause); owed at most a period.
        let left = BUSY_SHARE * period_ms - busy;
        let round = view * order.len() as f64;
        self.credit = (self.credit + left).clamp(-period_ms, round + left.max(0.0));
        // All together when the credit covers them all (one submission; the first drawn
        // shares the machine with the composed frame's encoding, the rest do not) and the
        // loop is not behind its source, else those that waited MAX_GAP.
        let all = self.credit >= round && !behind;
        for i in order {
            if all || waited(i) >= MAX_GAP {
                draw[i] = true;
                self.credit -= view;
            }
        }
        draw
    }

    /// `views` were drawn at `now`, in `took`.
    pub fn drawn(&mut self, views: &[usize], took: Duration, now: Instant) {
        if views.is_empty() {
            return;
        }
        for &i in views {
            self.last[i] = Some(now);
        }
        self.this_frame += took;
        self.view_ms = mean(self.view_ms, took.as_secs_f64() * 1e3 / views.len() as f64);
    }

    /// The frame loop spent `took` on this frame, views included.
    pub fn frame_done(&mut self, took: Duration) {
        let besides = took.saturating_sub(std::mem::take(&mut self.this_frame));
        self.busy_ms = mean(self.busy_ms, besides.as_secs_f64() * 1e3);
    }

    /// Forgets when views were drawn, for a view that stops being watched (its next watcher
    /// gets a picture at once).
    pub fn forget(&mut self, i: usize) {
        self.last[i] = None;
    }
}

/// The span over which a view's own stream's rate is measured.
pub const RATE_SPAN: Duration = Duration::from_secs(2);

/// The rate a view's own stream really has: its frames over the last [`RATE_SPAN`] of its own
/// timestamps, as a client plays them (frames leave an encoder that is catching up faster
/// than they were made).
#[derive(Default)]
pub(super) struct RateMeter {
    frames: VecDeque<Duration>,
}

impl RateMeter {
    /// A frame stamped `pts` went out; the rate since the oldest one kept, frames per second,
    /// once half a span is covered.
    pub fn tick(&mut self, pts: Duration) -> Option<f64> {
        self.frames.push_back(pts);
        while self
            .frames
            .front()
            .is_some_and(|t| pts.saturating_sub(*t) > RATE_SPAN)
        {
            self.frames.pop_front();
        }
        let span = pts.saturating_sub(*self.frames.front()?).as_secs_f64();
        (span >= RATE_SPAN.as_secs_f64() / 2.0).then(|| (self.frames.len() - 1) as f64 / span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PERIOD: Duration = Duration::from_millis(33);

    fn paced(busy_ms: u64, view_ms: u64) -> ViewPacing {
        let mut p = ViewPacing::default();
        let t = Instant::now();
        p.drawn(&[0], Duration::from_millis(view_ms), t);
        p.frame_done(Duration::from_millis(busy_ms + view_ms));
        p.last = [None; VIEW_MOUNTS];
        p
    }

    #[test]
    fn every_view_is_drawn_where_the_period_has_room_for_them_all() {
        let mut p = paced(5, 2);
        assert_eq!(p.pick([true; 4], PERIOD, Instant::now(), false), [true; 4]);
        assert_eq!(
            p.pick([false, true, false, true], PERIOD, Instant::now(), false),
            [false, true, false, true]
        );
    }

    #[test]
    fn short_of_time_the_views_are_drawn_together_as_often_as_the_time_left_allows() {
        // 32.3 ms of a 33 ms period may be filled: 23 ms besides the views leaves 9.3 ms a
        // frame, four 6 ms views every 2.6 frames.
        let mut p = paced(23, 6);
        let start = Instant::now();
        p.last = [Some(start); VIEW_MOUNTS];
        let mut drawn = [0; VIEW_MOUNTS];
        for frame in 0..30u32 {
            let now = start + PERIOD * frame;
            let pick = p.pick([true; 4], PERIOD, now, false);
            let views: Vec<usize> = (0..VIEW_MOUNTS).filter(|&i| pick[i]).collect();
            assert!(matches!(views.len(), 0 | 4), "frame {frame}: {pick:?}");
            views.iter().for_each(|&i| drawn[i] += 1);
            p.drawn(&views, Duration::from_millis(6 * views.len() as u64), now);
            p.frame_done(Duration::from_millis(23 + 6 * views.len() as u64));
        }
        assert!((10..=12).contains(&drawn[0]), "{drawn:?}");
        assert!(drawn.iter().all(|&n| n == drawn[0]), "{drawn:?}");
    }

    #[test]
    fn a_round_a_little_dearer_than_the_spare_time_is_drawn_in_most_periods() {
        // 17 ms spare a period, four 5 ms views: 17/20 of the periods draw them all (a credit
        // capped at one round drew them every other period, half the rate the time allows),
        // and the loop stays within its share of the time.
        let mut p = paced(15, 5);
        let start = Instant::now();
        p.last = [Some(start); VIEW_MOUNTS];
        let (mut rounds, mut filled) = (0, 0.0);
        for frame in 1..=60u32 {
            let now = start + PERIOD * frame;
            let pick = p.pick([true; 4], PERIOD, now, false);
            let views: Vec<usize> = (0..VIEW_MOUNTS).filter(|&i| pick[i]).collect();
            rounds += (views.len() == 4) as u32;
            let took = Duration::from_millis(5 * views.len() as u64);
            p.drawn(&views, took, now);
            p.frame_done(Duration::from_millis(15) + took);
            filled += 15.0 + took.as_secs_f64() * 1e3;
        }
        assert!((48..=53).contains(&rounds), "{rounds} rounds in 60 periods");
        let share = filled / (60.0 * PERIOD.as_secs_f64() * 1e3);
        assert!(
            share <= BUSY_SHARE + 0.02,
            "the loop filled {share:.3} of the time"
        );
    }

    #[test]
    fn with_no_time_left_a_view_still_gets_a_frame_every_max_gap() {
        let mut p = paced(40, 6);
        let start = Instant::now();
        assert_eq!(
            p.pick([true; 4], PERIOD, start, false),
            [true; 4],
            "never drawn"
        );
        p.drawn(&[0, 1, 2, 3], Duration::from_millis(24), start);
        p.frame_done(Duration::from_millis(64));
        assert_eq!(p.pick([true; 4], PERIOD, start + PERIOD, false), [false; 4]);
        assert_eq!(p.pick([true; 4], PERIOD, start + MAX_GAP, false), [true; 4]);
    }

    #[test]
    fn while_the_next_source_frame_waits_the_views_wait_unless_they_waited_max_gap() {
        // Time enough for every view every frame, but the loop is behind its source.
        let mut p = paced(5, 2);
        let start = Instant::now();
        p.last = [Some(start); VIEW_MOUNTS];
        assert_eq!(p.pick([true; 4], PERIOD, start + PERIOD, true), [false; 4]);
        // Caught up: the round saved up is drawn.
        assert_eq!(
            p.pick([true; 4], PERIOD, start + PERIOD * 2, false),
            [true; 4]
        );
        // Behind, but view 2 last drawn MAX_GAP ago: it is drawn all the same.
        p.drawn(&[0, 1, 3], Duration::from_millis(6), start + PERIOD * 2);
        assert_eq!(
            p.pick([true; 4], PERIOD, start + MAX_GAP, true),
            [false, false, true, false]
        );
    }

    #[test]
    fn a_streams_rate_is_its_frames_over_the_last_two_seconds_of_its_timestamps() {
        let mut m = RateMeter::default();
        let at = Duration::from_millis;
        // Nothing said before a second is covered.
        assert_eq!(m.tick(at(0)), None);
        assert_eq!(m.tick(at(500)), None);
        // 7 fps: a frame every 1/7 s for 3 s; the oldest dropped past 2 s.
        let mut last = None;
        for k in 0..=21u64 {
            last = m.tick(at(1000 + k * 1000 / 7));
        }
        let rate = last.expect("a rate once a second is covered");
        assert!((rate - 7.0).abs() < 0.2, "{rate}");
    }
}
