//! Episodes: turning one interval's contacts and near distances into events. A collision is
//! the start of a contact; a near miss is a stay within the band without contact, reported when
//! the obstacle leaves it (on the same exact distance that opened it).
//!
//! Pure and synchronous; imports no I/O, no tokio, no rerun.

use std::sync::Arc;

use crate::collision::bodies::ObstacleRef;
use crate::collision::contact::Touch;
use crate::collision::events::{Event, EventKind};
use crate::collision::moving::MovingBodies;
use crate::collision::view::view;
use crate::scene::Scene;
use crate::world::TrackSample;

/// The sample an interval to `current` starts from, if the interval can be swept: none after a
/// gap longer than `max_gap_s` (reported as a `telemetry_gap`: a straight sweep across it
/// would invent a path), and none when `previous` is not earlier than `current`.
pub(crate) fn sweepable_from<'a>(
    previous: Option<&'a TrackSample>,
    current: &TrackSample,
    max_gap_s: f64,
    event: &dyn Fn(EventKind) -> Event,
    events: &mut Vec<Event>,
) -> Option<&'a TrackSample> {
    let t = current.t_s;
    match previous {
        Some(p) if t - p.t_s > max_gap_s => {
            events.push(event(EventKind::TelemetryGap {
                gap_s: t - p.t_s,
                moved_m: (current.position_enu_m - p.position_enu_m).length(),
            }));
            None
        }
        Some(p) if t > p.t_s => Some(p),
        _ => None,
    }
}

#[derive(Debug, Clone)]
struct Near {
    obstacle: ObstacleRef,
    /// The obstacle's id, kept so that a near miss can be reported after its track ended.
    id: Arc<str>,
    closest_m: f64,
    closest_t_s: f64,
    /// Touched while in the band: a collision, not a near miss.
    touched: bool,
}

/// One vehicle's open contacts and near misses.
#[derive(Debug, Clone, Default)]
pub struct Episodes {
    /// In contact at the last sample.
    touching: Vec<ObstacleRef>,
    near: Vec<Near>,
}

/// What the contact layer found over one interval.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Found<'a> {
    /// The contacts (every span of each), with where and when they began.
    pub touching: &'a [(ObstacleRef, Touch)],
    /// The obstacles within the near-miss band, with their gaps.
    pub near: &'a [(ObstacleRef, f64)],
}

impl Episodes {
    /// Obstacles in contact at the last sample.
    pub fn touching(&self) -> &[ObstacleRef] {
        &self.touching
    }

    /// Fold one interval (`t_before` to `t_s`) into the episodes, pushing what began or ended.
    pub(crate) fn update(
        &mut self,
        scene: &Scene,
        dynamic: &MovingBodies,
        found: Found<'_>,
        (t_before, t_s): (f64, f64),
        event: &dyn Fn(EventKind) -> Event,
        events: &mut Vec<Event>,
    ) {
        let (touching_now, near_now) = (found.touching, found.near);
        // Collisions: contacts that were not there at the last sample, and every further span
        // of contact with the same obstacle within the interval.
        for (k, (o, touch)) in touching_now.iter().enumerate() {
            let again = touching_now[..k].iter().any(|(p, _)| p == o);
            if self.touching.contains(o) && !again {
                continue;
            }
            let Some(v) = view(scene, dynamic, *o) else {
                continue;
            };
            events.push(event(EventKind::Collision {
                obstacle: v.id.to_owned(),
                obstacle_kind: v.kind.name(),
                point_enu_m: touch.point_enu_m.to_array(),
                normal_enu: touch.normal_enu.to_array(),
                time_of_impact: t_before + (t_s - t_before) * touch.fraction,
                swept: touch.swept,
            }));
        }
        self.touching.clear();
        self.touching.extend(
            touching_now
                .iter()
                .filter(|(_, touch)| touch.holds_now)
                .map(|(o, _)| *o),
        );
        self.touching.dedup();
        for &(o, d) in near_now {
            match self.near.iter_mut().find(|n| n.obstacle == o) {
                Some(n) if d < n.closest_m => {
                    n.closest_m = d;
                    n.closest_t_s = t_s;
                }
                Some(_) => {}
                None => {
                    if let Some(v) = view(scene, dynamic, o) {
                        self.near.push(Near {
                            obstacle: o,
                            id: Arc::from(v.id),
                            closest_m: d,
                            closest_t_s: t_s,
                            touched: false,
                        });
                    }
                }
            }
        }
        for (o, _) in touching_now {
            match self.near.iter_mut().find(|n| n.obstacle == *o) {
                Some(n) => n.touched = true,
                None => self.near.push(Near {
                    obstacle: *o,
                    id: Arc::from(""),
                    closest_m: 0.0,
                    closest_t_s: t_s,
                    touched: true,
                }),
            }
        }
        // A near miss ends when the obstacle is no longer within the band (or no longer there).
        let mut i = 0;
        while i < self.near.len() {
            let o = self.near[i].obstacle;
            let stays = near_now.iter().any(|n| n.0 == o) || touching_now.iter().any(|n| n.0 == o);
            if stays {
                i += 1;
                continue;
            }
            let n = self.near.swap_remove(i);
            if !n.touched {
                events.push(event(near_miss(&n)));
            }
        }
    }

    /// Close every open near miss (end of a run, or the vehicle's track restarted) and forget
    /// the contacts.
    pub(crate) fn close(&mut self, event: &dyn Fn(EventKind) -> Event, events: &mut Vec<Event>) {
        for n in self.near.drain(..) {
            if !n.touched {
                let mut e = event(near_miss(&n));
                e.t = n.closest_t_s;
                events.push(e);
            }
        }
        self.touching.clear();
    }
}

fn near_miss(n: &Near) -> EventKind {
    EventKind::NearMiss {
        obstacle: n.id.to_string(),
        closest_m: n.closest_m,
        closest_t: n.closest_t_s,
    }
}
