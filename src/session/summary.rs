//! The summary a run writes (`--summary-json`): ingest, vehicles, approaches, well clear, the
//! collision layers, the feed and the viewer, one section each. Every figure in it comes from
//! the run's counters and every event, never from the capped list of notable events.

use serde_json::{json, Value};

use super::Session;
use crate::daa::approach::Pair;
use crate::pipeline::Pipeline;
use crate::world::SenderId;

/// Each of the summary's lists of pairs (`approaches`, `well_clear.pairs`, `separation.pairs`)
/// holds at most this many by default (`--summary-pairs`, `Session::set_summary_pairs`): the
/// pairs with the least closest approach, in the list's usual order; its count beside it is of
/// every pair. A fleet of thousands has millions of pairs: listing them all made a summary of
/// gigabytes, written after the signal to stop.
pub const LISTED_PAIRS_MAX: usize = 1000;

/// The pairs of `pairs` that `keep` keeps, at most `max` of them (`None`: all): those with the
/// least closest approach, in `pairs`' order; and how many `keep` kept in all.
fn listed<'p>(
    pairs: &[(SenderId, &'p Pair)],
    max: Option<usize>,
    keep: impl Fn(&Pair) -> bool,
) -> (Vec<(SenderId, &'p Pair)>, usize) {
    let mut kept: Vec<(SenderId, &Pair)> = pairs.iter().filter(|(_, p)| keep(p)).copied().collect();
    let all = kept.len();
    if let Some(max) = max.filter(|&m| all > m) {
        let mut order: Vec<usize> = (0..all).collect();
        let distance = |i: usize| kept[i].1.approach.distance_m;
        order.select_nth_unstable_by(max, |&a, &b| {
            distance(a).total_cmp(&distance(b)).then(a.cmp(&b))
        });
        order.truncate(max);
        order.sort_unstable();
        kept = order.into_iter().map(|i| kept[i]).collect();
    }
    (kept, all)
}

impl Session {
    /// The summary object `--summary-json` writes.
    pub fn summary(&self, command: &str, input: &str) -> Value {
        let pairs = self.approaches.pairs();
        let (closest, approached) = listed(&pairs, self.summary_pairs, |_| true);
        json!({
            "savsim": env!("CARGO_PKG_VERSION"),
            "command": command,
            "input": input,
            "scene": self.scene.as_ref().map(|s| s.name.clone()),
            "ingest": self.ingestor.stats.to_summary(),
            "log": self.log,
            "vehicles": self.vehicles_summary(),
            "traffic_aircraft": self.world.traffic().len(),
            "traffic_pressure_altitude": self.world.traffic().filter(|(_, t)| t.pressure_altitude).count(),
            "approaches": self.approaches_summary(&closest),
            "approach_pairs": approached,
            "well_clear": self.well_clear_summary(&pairs),
            "separation": self.separation_summary(&pairs),
            "slots": self.slots_summary(),
            "tracks_expired": self.world.expired,
            "collision": self.pipeline.as_ref().map(|p| self.collision_summary(p)),
            "feed": self.feed_summary(),
            "rerun": self.rerun_summary(),
            "interrupted": self.interrupted,
            "wall_time_s": self.started.elapsed().as_secs_f64(),
        })
    }

    /// Each vehicle heard: its messages, sequence, positions, restarts and returns.
    fn vehicles_summary(&self) -> Vec<Value> {
        let stats = &self.ingestor.stats;
        self.world
            .seen
            .iter()
            .map(|(id, seen)| {
                json!({
                    "sysid": id.system_id,
                    "compid": id.component_id,
                    "messages": stats.by_sender.get(id).copied().unwrap_or(0),
                    "sequence": stats.sequence.get(id),
                    "positions": seen.positions,
                    "boot_resets": seen.boot_resets,
                    "returns": seen.returns,
                    "clock_reanchors": seen.clock_reanchors,
                })
            })
            .collect()
    }

    /// The closest approach of each vehicle to each moving body.
    fn approaches_summary(&self, pairs: &[(SenderId, &Pair)]) -> Vec<Value> {
        pairs
            .iter()
            .map(|(vehicle, pair)| {
                let a = &pair.approach;
                json!({
                    "vehicle": vehicle.system_id,
                    "component": vehicle.component_id,
                    "track": &*pair.id,
                    "distance_m": a.distance_m,
                    "horizontal_m": a.horizontal_m,
                    "vertical_m": a.vertical_m,
                    "t_s": self.elapsed_s(a.t_s),
                    "nmac": a.nmac,
                })
            })
            .collect()
    }

    /// The well-clear volume, and each pair that lost well clear: when, how long, how close.
    fn well_clear_summary(&self, pairs: &[(SenderId, &Pair)]) -> Value {
        let (lost, pairs_lost) = listed(pairs, self.summary_pairs, |p| {
            !p.well_clear.episodes.is_empty()
        });
        json!({
            "volume": self.approaches.volume().map(|v| json!({
                "dthr_m": v.dthr_m,
                "zthr_m": v.zthr_m,
                "tthr_s": v.tthr_s,
                "tcoa_s": v.tcoa_s,
            })),
            "pairs_lost": pairs_lost,
            "pairs": lost
                .iter()
                .map(|(vehicle, pair)| {
                    let log = &pair.well_clear;
                    json!({
                        "vehicle": vehicle.system_id,
                        "component": vehicle.component_id,
                        "track": &*pair.id,
                        "lowc_first_t_s": log.episodes.first().map(|e| self.elapsed_s(e.start_t_s)),
                        "lowc_duration_s": log.duration_s(),
                        "episodes": log.episodes.len(),
                        "min_tau_mod_s": log.min_tau_mod_s,
                        "min_horizontal_m": log.episodes.iter().map(|e| e.min_horizontal_m).reduce(f64::min),
                        "min_vertical_m": log.episodes.iter().map(|e| e.min_vertical_m).reduce(f64::min),
                    })
                })
                .collect::<Vec<_>>(),
        })
    }

    /// The separation minimum (`--separation-m`), and each pair that came nearer: when first,
    /// how long in all, how many times, and their closest approach (3D, with the moment).
    fn separation_summary(&self, pairs: &[(SenderId, &Pair)]) -> Value {
        let Some(separation) = self.approaches.separation() else {
            return Value::Null;
        };
        let (under, pairs_under) = listed(pairs, self.summary_pairs, |p| {
            !p.separation.episodes.is_empty()
        });
        let under: Vec<Value> = under
            .iter()
            .map(|(vehicle, pair)| {
                let log = &pair.separation;
                json!({
                    "vehicle": vehicle.system_id,
                    "component": vehicle.component_id,
                    "track": &*pair.id,
                    "first_t_s": log.episodes.first().map(|e| self.elapsed_s(e.start_t_s)),
                    "duration_s": log.duration_s(),
                    "episodes": log.episodes.len(),
                    "closest_m": pair.approach.distance_m,
                    "closest_t_s": self.elapsed_s(pair.approach.t_s),
                })
            })
            .collect();
        json!({
            "minimum_m": separation.minimum_m,
            "losses": self.digest.separation_lost(),
            "pairs_under": pairs_under,
            "pairs": under,
        })
    }

    /// A show's slots (`--slots`): the tolerance, how many vehicles the show names, and each
    /// vehicle that left its slot: when first, how long in all, how many times, how far.
    fn slots_summary(&self) -> Value {
        let Some(slots) = &self.slots else {
            return Value::Null;
        };
        // An open departure lasts to the run's last message.
        let last_t_s = self
            .ingestor
            .stats
            .time_span_s
            .map(|(_, last)| last - self.flight_start_t_s.unwrap_or(last));
        let left: Vec<Value> = slots
            .departures()
            .map(|(vehicle, departures)| {
                json!({
                    "vehicle": vehicle.system_id,
                    "component": vehicle.component_id,
                    "first_t_s": departures.first().map(|d| d.start_t_s),
                    "duration_s": departures
                        .iter()
                        .map(|d| d.end_t_s.or(last_t_s).unwrap_or(d.start_t_s) - d.start_t_s)
                        .sum::<f64>(),
                    "departures": departures.len(),
                    "max_deviation_m": departures.iter().map(|d| d.max_deviation_m).fold(0.0, f64::max),
                })
            })
            .collect();
        json!({
            "tolerance_m": slots.tolerance_m(),
            "vehicles": slots.vehicles(),
            "vehicles_left": left.len(),
            "left": left,
        })
    }

    /// The collision layers: the pipeline's totals, per-tick means and cost, the mesh cache,
    /// the octree and the AHP weights.
    fn collision_summary(&self, p: &Pipeline) -> Value {
        let totals = p.totals();
        let ticks = totals.ticks.max(1) as f64;
        let (median_us, p99_us) = self.tick_costs.percentiles_us();
        let meshes = p.meshes().counts();
        json!({
            "mode": p.config().mode.name(),
            "ticks": totals.ticks,
            "collisions": totals.collisions,
            "collider_swaps": totals.swaps,
            "sensing_frames": totals.sensing_frames,
            "state_resets": totals.state_resets,
            "near_misses": totals.near_misses,
            "telemetry_gaps": totals.telemetry_gaps,
            "notable_not_listed": self.notable_not_kept,
            "terrain_clearance_min_m": totals.terrain_clearance_min_m,
            "implausible_samples": totals.implausible_samples,
            "reference_capped": totals.reference_capped,
            "per_tick": {
                "active_box_mean": totals.active_box_sum as f64 / ticks,
                "active_box_max": totals.active_box_max,
                "active_mesh_mean": totals.active_mesh_sum as f64 / ticks,
                "active_mesh_max": totals.active_mesh_max,
                "active_triangles_mean": totals.active_triangles_sum as f64 / ticks,
                "active_triangles_max": totals.active_triangles_max,
                "narrow_tests_mean": totals.narrow_tests as f64 / ticks,
                "cost_us_median": median_us,
                "cost_us_p99": p99_us,
            },
            "meshes_built": meshes.built,
            "meshes_built_on_contact": meshes.built_on_contact,
            "meshes_evicted": meshes.evicted,
            "meshes_prefetch_refused": meshes.prefetch_refused,
            "meshes_worker_failures": meshes.worker_failures,
            "mesh_budget_bytes": p.meshes().budget(),
            "mesh_bytes_peak": meshes.peak_bytes,
            "mesh_triangles_built": meshes.triangles,
            "mesh_bytes_built": meshes.bytes,
            "mesh_build_s": meshes.build_time.as_secs_f64(),
            "octree": { "nodes": p.octree().node_count(), "depth": p.octree().depth() },
            "ahp": p.config().ahp,
        })
    }

    /// The closed-loop feed, when on: what it sends, and each vehicle's frames and rate.
    fn feed_summary(&self) -> Option<Value> {
        self.feed.as_ref().map(|f| json!({
            "kinds": f.config.kinds,
            "hz": f.config.hz,
            "adsb_echoes": f.adsb_echoes,
            "sensors": f.config.sensors,
            "sensor_seed": f.config.sensor_seed,
            "told": f.told().map(|(id, icao, t)| json!({
                "sysid": id.system_id,
                "compid": id.component_id,
                "icao": icao,
                "told": t,
            })).collect::<Vec<_>>(),
            "vehicles": f.counts().map(|(id, c)| json!({
                "sysid": id.system_id,
                "compid": id.component_id,
                "counts": c,
                "rate_hz": (c.span_ms > 0).then(|| (c.frames - 1) as f64 * 1000.0 / c.span_ms as f64),
            })).collect::<Vec<_>>(),
        }))
    }

    /// Frames handed to the viewer and dropped, when the run is watched (`--rerun`).
    fn rerun_summary(&self) -> Option<Value> {
        self.observer.as_ref().map(|o| {
            let (sent, dropped) = o.counts();
            json!({ "sent": sent, "dropped": dropped })
        })
    }
}
