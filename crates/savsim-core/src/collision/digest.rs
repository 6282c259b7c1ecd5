//! What a run's events add up to, kept as they happen: the first collision, the closest
//! approach to each obstacle (0 for one touched), the closest near miss, and counts. Figures
//! drawn from a run come from here, never from a capped list of its events.

use std::collections::BTreeMap;

use crate::collision::events::{Event, EventKind};

/// Running figures over every event given to [`EventDigest::take`].
///
/// ```
/// use savsim_core::collision::digest::EventDigest;
/// use savsim_core::collision::events::{Event, EventKind};
/// let near = |obstacle: &str, closest_m| Event {
///     t: 0.0, time_boot_ms: 0, vehicle: 1, compid: 1,
///     kind: EventKind::NearMiss { obstacle: obstacle.into(), closest_m, closest_t: 0.0 },
/// };
/// let mut digest = EventDigest::default();
/// for k in 0..5000 {
///     digest.take(&near("tower", 3.0 + f64::from(k % 7)));
/// }
/// digest.take(&near("mast", 2.5));
/// assert_eq!(digest.closest_near_miss_m(), Some(2.5));
/// assert_eq!(digest.closest_m("tower"), Some(3.0));
/// assert_eq!(digest.near_misses(), 5001);
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EventDigest {
    /// The first collision: when contact began (`time_of_impact`) and the obstacle.
    first_collision: Option<(f64, String)>,
    /// Per obstacle, the closest the run came: 0 m where it collided.
    closest: BTreeMap<String, f64>,
    /// The closest near miss, metres.
    closest_near_miss_m: Option<f64>,
    collisions: u64,
    near_misses: u64,
    well_clear_lost: u64,
    separation_lost: u64,
}

impl EventDigest {
    /// Take one event into the figures.
    pub fn take(&mut self, event: &Event) {
        match &event.kind {
            EventKind::Collision {
                obstacle,
                time_of_impact,
                ..
            } => {
                self.collisions += 1;
                if self.first_collision.is_none() {
                    self.first_collision = Some((*time_of_impact, obstacle.clone()));
                }
                self.closer(obstacle, 0.0);
            }
            EventKind::NearMiss {
                obstacle,
                closest_m,
                ..
            } => {
                self.near_misses += 1;
                self.closest_near_miss_m = Some(
                    self.closest_near_miss_m
                        .map_or(*closest_m, |m| m.min(*closest_m)),
                );
                self.closer(obstacle, *closest_m);
            }
            EventKind::WellClearLost { .. } => self.well_clear_lost += 1,
            EventKind::SeparationLost { .. } => self.separation_lost += 1,
            _ => {}
        }
    }

    fn closer(&mut self, obstacle: &str, m: f64) {
        match self.closest.get_mut(obstacle) {
            Some(c) => *c = c.min(m),
            None => {
                self.closest.insert(obstacle.to_owned(), m);
            }
        }
    }

    /// The first collision's time of impact (on the events' clock) and obstacle.
    pub fn first_collision(&self) -> Option<(f64, &str)> {
        self.first_collision.as_ref().map(|(t, o)| (*t, o.as_str()))
    }

    /// The closest the run came to `obstacle` (0 m if it collided), if it collided with it
    /// or passed it within the near-miss distance.
    pub fn closest_m(&self, obstacle: &str) -> Option<f64> {
        self.closest.get(obstacle).copied()
    }

    /// Every obstacle collided with or nearly missed, with the closest approach, in id order.
    pub fn closest_by_obstacle(&self) -> impl Iterator<Item = (&str, f64)> {
        self.closest.iter().map(|(o, m)| (o.as_str(), *m))
    }

    /// The closest near miss (collisions not counted), metres.
    pub fn closest_near_miss_m(&self) -> Option<f64> {
        self.closest_near_miss_m
    }

    /// Collisions taken.
    pub fn collisions(&self) -> u64 {
        self.collisions
    }

    /// Near misses taken.
    pub fn near_misses(&self) -> u64 {
        self.near_misses
    }

    /// Losses of well clear taken.
    pub fn well_clear_lost(&self) -> u64 {
        self.well_clear_lost
    }

    /// Losses of the separation minimum.
    pub fn separation_lost(&self) -> u64 {
        self.separation_lost
    }
}
