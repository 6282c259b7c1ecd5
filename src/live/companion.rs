//! A companion beside a vehicle that flies in wall time (`savsim live --companion`, a study
//! row on SITL's own physics): after each chunk the vehicle's newest position sets the
//! companion's clock (its `time_boot_ms`), what its devices made and the traffic it was sent
//! are handed over, a frame goes at each instant the planner is free for, and the commands it
//! answered go on the route the vehicle was last heard on once their time has come.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use crate::companion::protocol::State;
use crate::companion::slot::{CompanionConfig, CompanionCounts, Intent, Slot};
use crate::error::{Error, Result};
use crate::links::sockets::{Network, Outgoing};
use crate::session::Session;
use crate::world::SenderId;

/// A companion as a live run asks for it.
#[derive(Debug, Clone)]
pub struct CompanionOptions {
    /// The planner, its rate and latency.
    pub config: CompanionConfig,
    /// The vehicle it flies, its system id.
    pub target_system_id: u8,
    /// Whether the vehicle is PX4 (its mode names).
    pub px4: bool,
    /// Where its output goes (`companion.log`).
    pub dir: PathBuf,
    /// Where a pilot puts what its plan asks (the frames' `intent_enu_mps`).
    pub intent: Intent,
}

impl PartialEq for CompanionOptions {
    fn eq(&self, other: &Self) -> bool {
        self.config == other.config
            && self.target_system_id == other.target_system_id
            && self.px4 == other.px4
            && self.dir == other.dir
            && std::sync::Arc::ptr_eq(&self.intent, &other.intent)
    }
}

/// The companion of a live run.
pub(super) struct LiveCompanion {
    slot: Slot,
    target: u8,
    /// The generation of the vehicle's track last seen (a new one at each reboot).
    generation: Option<u32>,
}

impl LiveCompanion {
    /// Start `options`' planner, greeted with `session`'s devices; `session` keeps what they
    /// make for it.
    pub(super) fn start(
        options: &CompanionOptions,
        session: &mut Session,
        stop: &AtomicBool,
    ) -> Result<Self> {
        session.keep_companion_inputs();
        let target = SenderId {
            system_id: options.target_system_id,
            component_id: 1,
        };
        let slot = Slot::start_beside(
            &options.config,
            (target, options.px4),
            (&options.dir, stop),
            &session.sensor_names(),
            options.intent.clone(),
        )
        .map_err(|e| Error::Companion(e.to_string()))?;
        Ok(Self {
            slot,
            target: options.target_system_id,
            generation: None,
        })
    }

    /// What it did.
    pub(super) fn counts(&self) -> &CompanionCounts {
        &self.slot.counts
    }

    /// After a chunk: inputs handed over, a frame offered at an instant, answers taken, and
    /// the commands whose time came sent to the vehicle's route.
    pub(super) fn step(
        &mut self,
        session: &mut Session,
        routes: impl Iterator<Item = (SenderId, crate::links::supervisor::Endpoint)>,
        network: &Network,
    ) -> Result<()> {
        let inputs = session.drain_companion_inputs();
        self.slot.collect(&inputs.captures, &inputs.traffic);
        let id = self.target;
        let world = session.world();
        let Some(track) = world.vehicle_of_system(id) else {
            return Ok(());
        };
        // The world's track starts a new generation when the vehicle reboots (its one rule,
        // `world::clock::step`): the companion's instants start again on the new clock.
        if self
            .generation
            .replace(track.generation)
            .is_some_and(|g| g != track.generation)
        {
            self.slot.restart();
        }
        let Some(latest) = track.history.latest() else {
            return Ok(());
        };
        let time_us = u64::from(latest.time_boot_ms) * 1000;
        let [roll, pitch, yaw] = latest
            .attitude
            .euler_ned_rad(world.plane(), &latest.position);
        let reported = State {
            position_enu_m: latest.position_enu_m,
            velocity_enu_mps: latest.velocity_enu_mps,
            attitude_deg: [
                roll.to_degrees(),
                pitch.to_degrees(),
                yaw.to_degrees().rem_euclid(360.0),
            ],
        };
        // Beside a vehicle in wall time savsim knows what the autopilot reports: it is both
        // the truth it mirrors and the estimate (hello's `clock` says so).
        self.slot
            .at(time_us, reported, Some((latest.position_enu_m, 0.0)))
            .map_err(|e| Error::Companion(e.to_string()))?;
        // Without a route yet, its commands wait for one.
        let mut routes = routes;
        let Some((_, to)) = routes.find(|(v, _)| v.system_id == id) else {
            return Ok(());
        };
        for bytes in self.slot.due(time_us) {
            network.send(Outgoing { to, bytes });
        }
        Ok(())
    }
}
