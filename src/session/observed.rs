//! What a session shows whoever watches it (`observe::Observer`, the viewer): each tick's pose,
//! rays, feed, colliders, traffic and events; each line a vehicle says (at its clock's last
//! position, held until it has one); every closest approach at the end. Nothing is made
//! without an observer.

use super::tick::TickInput;
use super::{Session, HELD_NOTES};
use crate::codec::frame::RawFrame;
use crate::codec::notes::Note;
use crate::collision::events::EventKind;
use crate::error::Result;
use crate::observe::{ApproachFrame, Frame, NoteFrame, TickFrame};
use crate::pipeline::TickReport;
use crate::scene::Scene;
use crate::world::SenderId;

impl Session {
    /// What a vehicle said in `frame` (received at `t_s`), to the observer at the vehicle's
    /// last clock; held until its first position when it has none yet. Nothing without an
    /// observer or from savsim's own senders.
    pub(super) fn note_for_observer(&mut self, t_s: f64, frame: &RawFrame<'_>) {
        if self.observer.is_none() {
            return;
        }
        let Some(note) = self.notes.take(frame) else {
            return;
        };
        if self.own.contains(&note.sender) {
            return;
        }
        let latest = self
            .world
            .vehicle(&note.sender)
            .and_then(|v| v.history.latest());
        match latest {
            Some(at) => {
                let time_boot_ms = at.time_boot_ms;
                self.send_note(t_s, time_boot_ms, note);
            }
            None if self.held_notes.len() < HELD_NOTES => self.held_notes.push((t_s, note)),
            None => {}
        }
    }

    /// Show `note` to the observer at `t_s` and the vehicle's clock `time_boot_ms`.
    fn send_note(&mut self, t_s: f64, time_boot_ms: u32, note: Note) {
        let Some(observer) = &mut self.observer else {
            return;
        };
        observer.take(Frame::Note(Box::new(NoteFrame {
            tick: self.ticks,
            t_s,
            time_boot_ms,
            system_id: note.sender.system_id,
            severity: note.severity,
            text: note.text,
        })));
    }

    /// The notes `sender` said before its first position, shown at `time_boot_ms`.
    fn send_held_notes(&mut self, sender: SenderId, time_boot_ms: u32) {
        if self.held_notes.is_empty() {
            return;
        }
        let held = std::mem::take(&mut self.held_notes);
        let (mine, others): (Vec<_>, Vec<_>) =
            held.into_iter().partition(|(_, n)| n.sender == sender);
        self.held_notes = others;
        for (t_s, note) in mine {
            self.send_note(t_s, time_boot_ms, note);
        }
    }

    /// What the observer is shown of this tick (the events from `first_event` on were
    /// reported at it).
    pub(super) fn observe_tick(
        &mut self,
        scene: &Scene,
        tick: &TickInput,
        first_event: usize,
        report: TickReport,
        cost_ns: u64,
    ) {
        if self.observer.is_none() {
            return;
        }
        self.send_held_notes(tick.sender, tick.current.time_boot_ms);
        let (Some(observer), Some(pipeline)) = (&mut self.observer, &self.pipeline) else {
            return;
        };
        let (sender, key, current) = (tick.sender, tick.key, &tick.current);
        let sensing = pipeline
            .vehicle(key.vehicle, key.component_id)
            .map(|v| &v.sensing);
        observer.take(Frame::Tick(Box::new(TickFrame {
            tick: self.ticks,
            t_s: current.t_s,
            t0_s: self
                .ingestor
                .stats
                .time_span_s
                .map_or(current.t_s, |(first, _)| first),
            time_boot_ms: current.time_boot_ms,
            system_id: sender.system_id,
            pose: crate::pipeline::BodyPose::of(current),
            model: scene.vehicle_model(sender.system_id),
            rays: sensing.map_or_else(Vec::new, |s| {
                s.rays
                    .iter()
                    .map(|(dir, hit)| (*dir, hit.map(|h| h.distance_m)))
                    .collect()
            }),
            ray_length_m: pipeline.config().ray_length_m,
            feed: self
                .feed
                .as_ref()
                .map_or_else(Vec::new, |f| f.readings().to_vec()),
            feed_max_m: self.feed.as_ref().map_or(0.0, |f| f.config.range.max_m),
            adsb_sent: self
                .feed
                .as_ref()
                .map_or_else(Vec::new, |f| f.adsb_sent().to_vec()),
            captures: self
                .feed
                .as_ref()
                .map_or_else(Vec::new, |f| f.captures().to_vec()),
            node: sensing
                .and_then(|s| s.node())
                .map(|n| pipeline.octree().node_aabb(n)),
            colliders: sensing.map_or_else(Vec::new, |s| s.colliders().collect()),
            dynamic: self
                .dynamic
                .as_slice()
                .iter()
                .map(|d| (d.key, d.id.to_string(), d.kind, d.geometry_index, d.current))
                .collect(),
            events: self.events[first_event..]
                .iter()
                .filter(|e| {
                    matches!(
                        e.kind,
                        EventKind::Collision { .. }
                            | EventKind::NearMiss { .. }
                            | EventKind::WellClearLost { .. }
                            | EventKind::SeparationLost { .. }
                    )
                })
                .cloned()
                .collect(),
            well_clear_m: self.approaches.volume().map(|v| (v.dthr_m, v.zthr_m)),
            report,
            cost_us: cost_ns as f64 / 1e3,
        })));
    }

    /// The run's end, shown: every vehicle's closest approach to each moving body; then the
    /// observer finishes.
    pub(super) fn observe_end(&mut self) -> Result<()> {
        let Some(observer) = &mut self.observer else {
            return Ok(());
        };
        let approaches = self.approaches.pairs().into_iter().map(|(own, pair)| {
            let a = pair.approach;
            ApproachFrame {
                system_id: own.system_id,
                track: pair.id.to_string(),
                t_s: a.t_s,
                distance_m: a.distance_m,
                horizontal_m: a.horizontal_m,
                vertical_m: a.vertical_m,
                nmac: a.nmac,
            }
        });
        observer.take(Frame::Approaches(approaches.collect()));
        observer.finish()
    }
}
