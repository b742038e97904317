//! No thread of `serve` fails silently: the one supervisor. A service's work (a thread of its
//! own under [`spawn`], a stage of the video head under [`supervised`], an async task under
//! [`keep_serving`]) is watched: a panic is caught, logged with its message, reported (to the
//! head's report, which makes it SYSTEM_STATUS error 5 and lists it in `/api/status`'s
//! `services`), and the work is started again after [`PAUSE`]; one that fails
//! [`MAX_FAILURES`] times within [`WINDOW`] is given up, and `serve` then stops, exiting
//! non-zero saying why. What fails and may come back (a camera, a relay, the autopilot's link)
//! is tried again with the one [`Backoff`]. At the bottom: every service uses it, it knows
//! none of them, and it reports through [`FailureLog`], which the head's report
//! (`crate::state::Report`) implements.
//!
//! For tests of this very path, `DIGIVIEW_FAULT=NAME` makes the service of that name panic
//! half a second after it starts ([`Fault`]): once, or at every start for one that must be
//! given up.

use std::collections::VecDeque;
use std::future::Future;
use std::net::SocketAddr;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use tracing::error;

/// Failures within this long count together.
pub const WINDOW: Duration = Duration::from_secs(60);
/// This many failures within the window and the service is given up.
pub const MAX_FAILURES: usize = 3;
/// The pause before a service is started again.
pub const PAUSE: Duration = Duration::from_millis(500);

/// Where a supervised service's failures are told.
pub trait FailureLog: Send + Sync {
    /// `service` failed with `why`; `given_up` when it will not be started again.
    fn failed(&self, service: &'static str, why: &str, given_up: bool);
    /// `service` is being started again after a failure.
    fn restarted(&self, service: &'static str);
}

/// Runs `work` on a thread named `service` until it returns or `stop` is set, starting it
/// again after each panic (see the module's doc).
pub fn spawn(
    report: Arc<dyn FailureLog>,
    service: &'static str,
    stop: Arc<AtomicBool>,
    mut work: impl FnMut() + Send + 'static,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name(service.into())
        .spawn(move || {
            let _ = supervised(&*report, service, &stop, &mut work);
        })
}

/// Runs `work` on this thread until it returns, starting it again after each panic (see the
/// module's doc); what it returned, or the last panic's message once `service` is given up or
/// `stop` was set meanwhile.
pub fn supervised<T>(
    report: &dyn FailureLog,
    service: &'static str,
    stop: &AtomicBool,
    mut work: impl FnMut() -> T,
) -> Result<T, String> {
    let mut failures = Failures::default();
    loop {
        let why = match catch_unwind(AssertUnwindSafe(&mut work)) {
            Ok(done) => return Ok(done),
            Err(panic) => panic_message(panic.as_ref()),
        };
        if failures.given_up(report, service, &why) || !sleep_unless(stop, PAUSE) {
            return Err(why);
        }
        report.restarted(service);
    }
}

/// A service's failures within the last [`WINDOW`], for a supervisor of its own (an async
/// task's, where [`spawn`]'s thread does not fit).
#[derive(Default)]
pub struct Failures(VecDeque<Instant>);

impl Failures {
    /// Notes a failure of `service` (`why`), logs and reports it; whether it is given up now.
    pub fn given_up(&mut self, report: &dyn FailureLog, service: &'static str, why: &str) -> bool {
        self.0.push_back(Instant::now());
        self.0.retain(|t| t.elapsed() < WINDOW);
        let give_up = self.0.len() >= MAX_FAILURES;
        report.failed(service, why, give_up);
        if give_up {
            error!(
                "the {service} service failed ({why}) {} times within {} s: stopping",
                self.0.len(),
                WINDOW.as_secs()
            );
        } else {
            error!(
                "the {service} service failed ({why}); starting it again in {} ms",
                PAUSE.as_millis()
            );
        }
        give_up
    }
}

/// Runs an async service that serves on a socket of `address`: `serve(socket)` in a task of
/// its own, starting with `first`, and after each failure (an error it returns, `why`, or a
/// panic) the address bound again with `bind` after [`PAUSE`]. It ends when `serve` ends
/// well, when `stopped()` says so after a failure, or when the service is given up. `prefix`
/// goes before every failure's reason (which part of the service failed).
pub async fn keep_serving<S, B, BF, F, SF, E>(
    report: &dyn FailureLog,
    service: &'static str,
    prefix: &str,
    (first, address): (S, SocketAddr),
    bind: B,
    serve: F,
    stopped: impl Fn() -> bool,
) where
    B: Fn(SocketAddr) -> BF,
    BF: Future<Output = std::io::Result<S>>,
    F: Fn(S) -> SF,
    SF: Future<Output = Result<(), E>> + Send + 'static,
    E: std::fmt::Display + Send + 'static,
{
    let mut socket = Some(first);
    let mut failures = Failures::default();
    loop {
        let bound = match socket.take() {
            Some(s) => Ok(s),
            None => bind(address).await,
        };
        let why = match bound {
            Ok(s) => match tokio::spawn(serve(s)).await {
                Ok(Ok(())) => return,
                Ok(Err(why)) => why.to_string(),
                Err(e) => match e.try_into_panic() {
                    Ok(panic) => panic_message(panic.as_ref()),
                    Err(e) => e.to_string(),
                },
            },
            Err(e) => format!("cannot listen on {address}: {e}"),
        };
        if failures.given_up(report, service, &format!("{prefix}{why}")) {
            return;
        }
        tokio::time::sleep(PAUSE).await;
        if stopped() {
            return;
        }
        report.restarted(service);
    }
}

/// The waits between attempts at something that failed and may come back (a camera, a relay,
/// the autopilot's link): the first wait, doubling up to the longest, and the first again
/// once an attempt held. Every retry loop of `serve` waits by one of these.
#[derive(Clone, Debug)]
pub struct Backoff {
    first: Duration,
    longest: Duration,
    /// Failed attempts since the last that held.
    failures: u32,
}

impl Backoff {
    pub const fn new(first: Duration, longest: Duration) -> Backoff {
        Backoff {
            first,
            longest,
            failures: 0,
        }
    }

    /// Notes a failed attempt; the wait before the next.
    pub fn failed(&mut self) -> Duration {
        let wait = self.first.saturating_mul(1 << self.failures.min(20));
        self.failures = self.failures.saturating_add(1);
        wait.min(self.longest)
    }

    /// Failed attempts in a row, the last one noted included.
    pub fn failures(&self) -> u32 {
        self.failures
    }

    /// Whether the failure just noted is worth a line in the log: the first three in a row,
    /// then one in sixty (a camera unplugged for an hour is not a thousand lines).
    pub fn worth_logging(&self) -> bool {
        let n = self.failures.saturating_sub(1);
        n < 3 || n.is_multiple_of(60)
    }

    /// The attempt held: the next failure waits the first wait again.
    pub fn held(&mut self) {
        self.failures = 0;
    }
}

/// Sleeps `wait`, or less once `stop` is set; whether it slept it all.
pub fn sleep_unless(stop: &AtomicBool, wait: Duration) -> bool {
    let until = Instant::now() + wait;
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return true;
        }
        std::thread::sleep(left.min(Duration::from_millis(20)));
    }
}

/// A lock taken even where a thread panicked holding it: the supervisor reports the panic and
/// starts that work again, and the value guarded (a slot, a queue, a figure, replaced whole
/// by whoever holds the lock) is used as it was left rather than passed on as a panic of
/// every other thread that shares it.
pub trait Locked<T> {
    fn locked(&self) -> MutexGuard<'_, T>;
}

impl<T> Locked<T> for Mutex<T> {
    fn locked(&self) -> MutexGuard<'_, T> {
        self.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// What a panic said.
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// A fault injected into a service for tests: `DIGIVIEW_FAULT=NAME` (its thread's name).
pub struct Fault {
    armed: bool,
    after: Instant,
    /// Fires at every start, not once per process.
    every_start: bool,
}

/// A fault fires once per process: the service started again runs clean.
static FIRED: AtomicBool = AtomicBool::new(false);

impl Fault {
    /// The fault for `service`, armed when the environment names it.
    pub fn for_service(service: &str) -> Fault {
        Fault {
            armed: std::env::var("DIGIVIEW_FAULT").is_ok_and(|s| s == service),
            after: Instant::now() + Duration::from_millis(500),
            every_start: false,
        }
    }

    /// As [`Fault::for_service`], firing at every start: the service is given up.
    pub fn at_every_start(service: &str) -> Fault {
        Fault {
            every_start: true,
            ..Fault::for_service(service)
        }
    }

    /// Whether this fault is still to fire.
    pub fn pending(&self) -> bool {
        self.armed && !FIRED.load(Ordering::Relaxed)
    }

    /// When it fires, once [`Fault::check`] is called.
    pub fn when(&self) -> Instant {
        self.after
    }

    /// Panics once (or at every start), when armed and half a second has passed since the
    /// fault was made.
    #[track_caller]
    pub fn check(&self, service: &str) {
        let due = self.armed && Instant::now() >= self.after;
        if due && (self.every_start || !FIRED.swap(true, Ordering::Relaxed)) {
            panic!("fault injected into the {service} service (DIGIVIEW_FAULT)");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU32;

    /// What was reported, in order.
    #[derive(Default)]
    struct Told(Mutex<Vec<String>>);

    impl FailureLog for Told {
        fn failed(&self, service: &'static str, why: &str, given_up: bool) {
            let line = format!("{service} failed: {why}, given up: {given_up}");
            self.0.lock().unwrap().push(line);
        }
        fn restarted(&self, service: &'static str) {
            self.0.lock().unwrap().push(format!("{service} restarted"));
        }
    }

    #[test]
    fn a_backoff_doubles_to_its_longest_logs_the_first_few_and_starts_again_once_held() {
        let secs = Duration::from_secs;
        let mut b = Backoff::new(Duration::from_millis(500), secs(4));
        let waits: Vec<Duration> = (0..6).map(|_| b.failed()).collect();
        let ms = |m| Duration::from_millis(m);
        assert_eq!(
            waits,
            [ms(500), ms(1000), ms(2000), ms(4000), ms(4000), ms(4000)]
        );
        b.held();
        assert_eq!(b.failed(), ms(500), "afresh once held");
        let mut logged = vec![];
        for _ in 0..200 {
            b.failed();
            if b.worth_logging() {
                logged.push(b.failures());
            }
        }
        assert_eq!(
            logged,
            [2, 3, 61, 121, 181],
            "after the first, already logged"
        );
    }

    #[test]
    fn a_service_that_panics_is_started_again_and_given_up_when_it_keeps_failing() {
        let told = Arc::new(Told::default());
        let stop = Arc::new(AtomicBool::new(false));
        let runs = Arc::new(AtomicU32::new(0));
        let counted = runs.clone();
        let t = spawn(told.clone(), "flaky", stop.clone(), move || {
            if counted.fetch_add(1, Ordering::Relaxed) == 0 {
                panic!("first run fails");
            }
        })
        .unwrap();
        t.join().unwrap();
        assert_eq!(runs.load(Ordering::Relaxed), 2, "started again once");
        assert_eq!(
            *told.0.lock().unwrap(),
            [
                "flaky failed: first run fails, given up: false",
                "flaky restarted"
            ]
        );

        told.0.lock().unwrap().clear();
        let t = spawn(told.clone(), "broken", stop, || panic!("always")).unwrap();
        t.join().unwrap();
        let lines = told.0.lock().unwrap().clone();
        assert_eq!(lines.len(), 2 * MAX_FAILURES - 1, "{lines:?}");
        assert_eq!(
            lines.last().unwrap(),
            "broken failed: always, given up: true"
        );
    }
}
