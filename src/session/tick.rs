//! One collision tick of a session, for the vehicle whose position just arrived: its samples,
//! the moving bodies within its watch range, well clear, the pipeline's step, the feed, and
//! what it shows its observer (`session::observed`). Its buffers (the moving bodies, the
//! well-clear changes, the events) are the session's, reused from tick to tick.

use std::time::Instant;

use super::{traffic, watch, Session};
use crate::collision::events::{Event, EventKind};
use crate::daa::approach::{Approaches, WellClearChange};
use crate::daa::episodes::Change;
use crate::daa::slots::SlotChange;
use crate::error::Result;
use crate::feed::FrameInput;
use crate::pipeline::{Mode, TickReport, VehicleKey};
use crate::scene::Scene;
use crate::world::SenderId;
use crate::world::TrackSample;

/// The tick at hand: whose it is and its two samples.
pub(super) struct TickInput {
    pub(super) sender: SenderId,
    pub(super) key: VehicleKey,
    pub(super) previous: Option<TrackSample>,
    pub(super) current: TrackSample,
    /// When the flight started, seconds of the samples' clock.
    pub(super) flight_start_t_s: f64,
}

impl Session {
    /// One tick for `sender`, whose track has a new position: nothing without a scene.
    pub(super) fn tick(&mut self, sender: SenderId) -> Result<()> {
        let (Some(scene), true) = (self.scene.clone(), self.pipeline.is_some()) else {
            return Ok(());
        };
        let Some(tick) = self.tick_input(sender) else {
            return Ok(());
        };
        self.fill_traffic(&scene, &tick);
        let first_event = self.events.len();
        self.judge_well_clear(&tick);
        self.judge_slot(&tick);
        let (report, cost_ns) = self.step_pipeline(&scene, &tick);
        self.feed_sample(&scene, &tick);
        self.ticks += 1;
        self.observe_tick(&scene, &tick, first_event, report, cost_ns);
        self.write_feed()?;
        self.flush_events()
    }

    /// The track's last two samples and its generation; the flight's start, fixed at the
    /// first tick.
    fn tick_input(&mut self, sender: SenderId) -> Option<TickInput> {
        let track = self.world.vehicle(&sender)?;
        let current = track.history.latest().copied()?;
        let previous = track.history.previous().copied();
        let generation = track.generation;
        // On the vehicle's clock the flight starts at its boot (time_boot_ms 0): scripted
        // traffic is then timed from the same instant whenever its positions begin to arrive.
        let boot_s = if self.vehicle_clock {
            f64::from(current.time_boot_ms) / 1000.0
        } else {
            0.0
        };
        let flight_start_t_s = *self.flight_start_t_s.get_or_insert(current.t_s - boot_s);
        Some(TickInput {
            sender,
            key: VehicleKey {
                vehicle: u16::from(sender.system_id),
                component_id: sender.component_id,
                generation,
            },
            previous,
            current,
            flight_start_t_s,
        })
    }

    /// The moving bodies within the vehicle's watch range, into `dynamic`.
    fn fill_traffic(&mut self, scene: &Scene, tick: &TickInput) {
        let Some(pipeline) = &self.pipeline else {
            return;
        };
        let watch = watch::Watch {
            collision: *pipeline.config(),
            volume: self.approaches.volume(),
            separation_m: self.approaches.separation().map(|s| s.minimum_m),
            feed: self.feed.as_ref().map(|f| watch::Watch::feed_of(&f.config)),
            max_model_radius_m: self.max_model_radius_m,
            pose_all: self.poses_all(pipeline.config().mode),
        };
        let sensing = pipeline.senses_at(tick.key, tick.current.t_s) || self.draws_traffic();
        let interval = traffic::Interval {
            own: tick.sender,
            previous: tick.previous.as_ref(),
            current: &tick.current,
            flight_start_t_s: tick.flight_start_t_s,
            sensing,
            sensing_region: sensing
                .then(|| pipeline.sensing_region(tick.key, &tick.current))
                .flatten(),
            held: pipeline
                .vehicle(tick.key.vehicle, tick.key.component_id)
                .map(|v| &v.sensing),
        };
        let into = traffic::Filling {
            out: &mut self.dynamic,
            approached: &mut self.approached,
        };
        traffic::fill_dynamic(into, scene, &mut self.world, &watch, &interval);
    }

    /// Whether the run is watched: the viewer draws the traffic and the colliders of every
    /// tick's bodies, so every tick takes them all (the answers are the same either way).
    fn draws_traffic(&self) -> bool {
        self.observer.is_some()
    }

    /// Whether every body a tick takes is given to the pipeline whole: in a mode that counts
    /// every collider (`box`, `mesh`) or is the reference, when the viewer draws them and when
    /// the feed reads them.
    fn poses_all(&self, mode: Mode) -> bool {
        let own_reach = matches!(mode, Mode::Exact | Mode::Paper | Mode::None);
        !own_reach || self.draws_traffic() || self.feed.is_some()
    }

    /// Closest approaches and well clear against the moving bodies within the approach reach;
    /// each change of well clear an event.
    fn judge_well_clear(&mut self, tick: &TickInput) {
        let (sender, current) = (tick.sender, &tick.current);
        self.approaches.observe(
            sender,
            tick.previous.as_ref(),
            current,
            self.approached.iter().map(|a| a.passing(&self.dynamic)),
            &mut self.well_clear_changes,
        );
        for c in &self.well_clear_changes {
            let kind = well_clear_event(&self.approaches, sender, c);
            self.events.push(Event {
                t: current.t_s,
                time_boot_ms: current.time_boot_ms,
                vehicle: u16::from(sender.system_id),
                compid: sender.component_id,
                kind,
            });
        }
    }

    /// The vehicle against its slot (`--slots`), at its sample: leaving it or coming back is
    /// an event.
    fn judge_slot(&mut self, tick: &TickInput) {
        let Some(slots) = self.slots.as_mut() else {
            return;
        };
        let current = &tick.current;
        let start = tick.flight_start_t_s;
        let show_t_s = current.t_s - start;
        let Some(change) = slots.observe(tick.sender, show_t_s, current.position_enu_m) else {
            return;
        };
        let kind = match change {
            SlotChange::Left {
                t_s,
                deviation_m,
                slot_enu_m,
            } => EventKind::LeftSlot {
                left_t: t_s + start,
                deviation_m,
                slot_enu_m: slot_enu_m.to_array(),
            },
            SlotChange::Back {
                t_s,
                duration_s,
                max_deviation_m,
            } => EventKind::BackInSlot {
                back_t: t_s + start,
                duration_s,
                max_deviation_m,
            },
        };
        self.events.push(Event {
            t: current.t_s,
            time_boot_ms: current.time_boot_ms,
            vehicle: u16::from(tick.sender.system_id),
            compid: tick.sender.component_id,
            kind,
        });
    }

    /// The pipeline's step for the vehicle, its events into `events`; its report and what it
    /// cost, nanoseconds (recorded in `tick_costs`).
    fn step_pipeline(&mut self, scene: &Scene, tick: &TickInput) -> (TickReport, u64) {
        let Some(pipeline) = self.pipeline.as_mut() else {
            return (TickReport::default(), 0);
        };
        let started = Instant::now();
        let report = pipeline.step(
            scene,
            tick.key,
            tick.previous.as_ref(),
            &tick.current,
            &self.dynamic,
            &mut self.events,
        );
        let cost_ns = started.elapsed().as_nanos().min(u128::from(u64::MAX)) as u64;
        self.tick_costs.record(cost_ns);
        (report, cost_ns)
    }

    /// The closed-loop feed's frame for this sample, if one is due, into `feed_out`.
    fn feed_sample(&mut self, scene: &Scene, tick: &TickInput) {
        let (Some(feed), Some(pipeline)) = (&mut self.feed, self.pipeline.as_mut()) else {
            return;
        };
        let input = FrameInput {
            scene,
            plane: self.world.plane(),
            sender: tick.sender,
            key: tick.key,
            current: &tick.current,
            dynamic: &self.dynamic,
        };
        feed.on_sample(pipeline, &input, &mut self.feed_out);
        if let Some(kept) = self.companion_inputs.as_mut() {
            kept.captures.extend_from_slice(feed.captures());
            let id = tick.sender.system_id;
            kept.traffic
                .extend(feed.adsb_sent().iter().map(|a| (id, a.clone())));
        }
    }
}

/// The event of a change of well clear (or of the separation minimum) of vehicle `own`: a
/// loss (of well clear, with the separations then), or a regain with its length.
fn well_clear_event(approaches: &Approaches, own: SenderId, c: &WellClearChange) -> EventKind {
    let track = c.body.to_string();
    match (c.change, c.separation) {
        (Change::Lost { t_s }, false) => {
            let episode = approaches.pair(own, c.source).and_then(|pair| {
                let episodes = pair.well_clear.episodes.iter();
                episodes.rev().find(|e| e.start_t_s == t_s)
            });
            EventKind::WellClearLost {
                track,
                lost_t: t_s,
                horizontal_m: episode.map_or(f64::NAN, |e| e.lost_horizontal_m),
                vertical_m: episode.map_or(f64::NAN, |e| e.lost_vertical_m),
            }
        }
        (Change::Regained { t_s, duration_s }, false) => EventKind::WellClearRegained {
            track,
            regained_t: t_s,
            duration_s,
        },
        (Change::Lost { t_s }, true) => EventKind::SeparationLost {
            track,
            lost_t: t_s,
            minimum_m: approaches.separation().map_or(f64::NAN, |s| s.minimum_m),
        },
        (Change::Regained { t_s, duration_s }, true) => EventKind::SeparationRegained {
            track,
            regained_t: t_s,
            duration_s,
        },
    }
}
