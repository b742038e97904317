//! How the supervised services of a running DigiView fare: for each that has failed, how
//! often it was started again, why it failed last, and whether it was given up. The
//! supervisor (`crate::supervise`) reports to the head's report (`super::Report`), which keeps it here and makes
//! the run's status error 5 (internal); `/api/status` reads it.

use super::report::{Failure, Report};
use crate::supervise::{FailureLog, Locked};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Mutex;

/// One service's failures.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ServiceHealth {
    /// Times it was started again after a failure (counted as it starts).
    pub restarts: u32,
    /// What its last failure said (a panic's message).
    pub last_failure: String,
    /// It failed too often and was given up: the process stops, exiting non-zero.
    pub given_up: bool,
}

/// The services that have failed, by name.
#[derive(Default)]
pub struct Services(Mutex<BTreeMap<&'static str, ServiceHealth>>);

impl Services {
    /// `service` failed with `why`; `given_up` when it will not be started again.
    pub fn failed(&self, service: &'static str, why: &str, given_up: bool) {
        let mut all = self.0.locked();
        let h = all.entry(service).or_default();
        h.last_failure = why.to_string();
        h.given_up |= given_up;
    }

    /// `service` is being started again after a failure.
    pub fn restarted(&self, service: &'static str) {
        let mut all = self.0.locked();
        all.entry(service).or_default().restarts += 1;
    }

    /// Every service that has failed so far.
    pub fn failures(&self) -> BTreeMap<&'static str, ServiceHealth> {
        self.0.locked().clone()
    }

    /// The first service given up, and why, if any.
    pub fn given_up(&self) -> Option<(&'static str, String)> {
        let all = self.0.locked();
        all.iter()
            .find(|(_, h)| h.given_up)
            .map(|(n, h)| (*n, h.last_failure.clone()))
    }
}

impl FailureLog for Report {
    fn failed(&self, service: &'static str, why: &str, given_up: bool) {
        self.services.failed(service, why, given_up);
        self.set_failure(Failure::Internal);
    }

    fn restarted(&self, service: &'static str) {
        self.services.restarted(service);
    }
}
