//! The one gate every control path changes the settings through: the DigiView protocol over
//! TCP and UDP, the web API and its WebSocket (through the protocol's handling), MAVLink's
//! camera and gimbal commands and parameters. Each asks [`Gate::permit`] once per request,
//! the one place the policy (`crate::policy`) is asked, then turns its wire format into a
//! view operation (`view::Op`), which [`Gate::steer`] applies by the one set of them
//! (`view::apply`), or into a change of the other settings ([`Gate::change`]); so a view
//! behaves the same whoever steers it.

use super::Invalid;
use super::live::LiveSettings;
use super::sensed::Sensed;
use super::settings::Settings;
use super::view::{self, Op, Seen, ViewError};
use crate::policy::{Act, Forbidden, Peer, Policy};
use std::sync::Arc;

/// Why a change through the gate was refused; nothing was changed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refused {
    /// The policy does not permit the peer.
    #[error(transparent)]
    Forbidden(#[from] Forbidden),
    /// The operation cannot be carried out (coordinate control with no target, no place).
    #[error(transparent)]
    View(#[from] ViewError),
    /// The settings it would leave are refused.
    #[error(transparent)]
    Invalid(#[from] Invalid),
}

pub struct Gate {
    settings: Arc<LiveSettings>,
    sensed: Arc<Sensed>,
    policy: Arc<Policy>,
}

impl Gate {
    pub fn new(settings: Arc<LiveSettings>, sensed: Arc<Sensed>, policy: Arc<Policy>) -> Gate {
        Gate {
            settings,
            sensed,
            policy,
        }
    }

    pub fn settings(&self) -> &Arc<LiveSettings> {
        &self.settings
    }

    pub fn sensed(&self) -> &Arc<Sensed> {
        &self.sensed
    }

    /// The policy, for its refusal log (what a path refused for reasons of its own).
    pub fn policy(&self) -> &Arc<Policy> {
        &self.policy
    }

    /// Whether `peer` may do `act` (change the settings, stop the system, delete files): the
    /// one place any control path asks. A refusal is noted with `what` was asked.
    pub fn permit(&self, peer: Peer, act: Act, what: &str) -> Result<(), Forbidden> {
        self.policy.allow(peer, act, what)
    }

    /// Applies view operation `op` to camera `cam`: what a request permitted by
    /// [`Gate::permit`] asked for, one the head makes itself (the detection stage keeping a
    /// click on its object), or one a permitted request goes on making (a gimbal's rate, a
    /// continuous zoom, tick by tick).
    pub fn steer(&self, cam: usize, op: Op) -> Result<(), Refused> {
        let vehicle = self.sensed.vehicle();
        let tracked = self.sensed.tracked();
        let seen = Seen {
            vehicle: &vehicle,
            tracked: &tracked,
        };
        self.settings.update(|s| {
            let Some(c) = s.cameras.get_mut(cam) else {
                return Err(Invalid(format!("there is no camera {cam}")).into());
            };
            view::apply(c, &op, &seen).map_err(Refused::View)
        })
    }

    /// Changes the settings other than a view's steering, whole or not at all
    /// (`LiveSettings::update`): what a request permitted by [`Gate::permit`] asked for, or
    /// what the head changes itself (the auto exposure; the detection stage's followers,
    /// `view::follow`).
    /// Detection turned off takes its objects with it at once (its followers stop in the
    /// same change: `LiveSettings::update`).
    pub fn change<T, E: From<Invalid>>(
        &self,
        change: impl FnOnce(&mut Settings) -> Result<T, E>,
    ) -> Result<T, E> {
        let was_on = self.settings.snapshot().detection.run_ai;
        let out = self.settings.update(change)?;
        if was_on && !self.settings.snapshot().detection.run_ai {
            self.sensed.set_tracked(vec![]);
        }
        Ok(out)
    }
}
