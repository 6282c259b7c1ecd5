//! A show's slots: where each vehicle is meant to be over the show (keyframes, linear between,
//! held before the first and after the last), and each vehicle's departures from its slot
//! beyond a tolerance, judged at each of its samples (`--slots`, `--slot-tolerance-m`).
//!
//! The slots are read from CSV text: a header `vehicle,t_s,east_m,north_m,up_m` (and an
//! optional `component` column, default 1), then one keyframe a line: the vehicle's MAVLink
//! system id, seconds after the run's first vehicle position, and scene ENU metres.

use std::collections::BTreeMap;

use glam::DVec3;

use crate::bounds::{MAX_DURATION_S, MAX_ENU_M};
use crate::world::SenderId;

/// The most keyframes a slots file may hold.
pub const MAX_KEYFRAMES: usize = 10_000_000;

/// Why slots cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SlotsError {
    /// The header is not the one asked for.
    #[error(
        "the header must be vehicle,t_s,east_m,north_m,up_m (and optionally component): got {0:?}"
    )]
    Header(String),
    /// A line that cannot be read.
    #[error("line {line}: {why}")]
    Line {
        /// Its number, from 1.
        line: usize,
        /// What is wrong.
        why: String,
    },
    /// No keyframe at all.
    #[error("no keyframe")]
    Empty,
    /// Too many keyframes.
    #[error("more than {MAX_KEYFRAMES} keyframes")]
    TooMany,
    /// A tolerance that is not a positive distance.
    #[error("the tolerance {0} m: give more than 0 and at most 1000")]
    Tolerance(f64),
}

/// One departure of a vehicle from its slot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Departure {
    /// When it was first seen out of its slot, seconds after the run's first vehicle position.
    pub start_t_s: f64,
    /// When it was first seen back (`None` while it lasts).
    pub end_t_s: Option<f64>,
    /// The farthest it was seen from its slot, metres.
    pub max_deviation_m: f64,
}

/// A change of a vehicle's state at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SlotChange {
    /// It was seen farther than the tolerance from its slot.
    Left {
        /// When, seconds after the run's first vehicle position.
        t_s: f64,
        /// How far, metres.
        deviation_m: f64,
        /// Where its slot was then, scene ENU metres.
        slot_enu_m: DVec3,
    },
    /// It was seen within the tolerance again.
    Back {
        /// When, seconds after the run's first vehicle position.
        t_s: f64,
        /// How long it was out, seconds.
        duration_s: f64,
        /// The farthest it was seen, metres.
        max_deviation_m: f64,
    },
}

/// Every vehicle's slot over the show, and their departures.
#[derive(Debug, Clone)]
pub struct Slots {
    /// Each vehicle's keyframes (time, position), in time order.
    plan: BTreeMap<SenderId, Vec<(f64, DVec3)>>,
    /// Farther than this from its slot, a vehicle has left it, metres.
    tolerance_m: f64,
    /// Each vehicle's departures, in time order (the last may be open).
    departures: BTreeMap<SenderId, Vec<Departure>>,
}

impl Slots {
    /// The slots of `csv` (see the module's doc), left beyond `tolerance_m`.
    ///
    /// ```
    /// use glam::DVec3;
    /// use savsim_core::daa::slots::{SlotChange, Slots};
    /// use savsim_core::world::SenderId;
    /// let csv = "vehicle,t_s,east_m,north_m,up_m\n1,0,0,0,0\n1,10,0,0,20\n";
    /// let mut slots = Slots::parse(csv, 0.5).unwrap();
    /// let one = SenderId { system_id: 1, component_id: 1 };
    /// assert_eq!(slots.slot_at(one, 5.0), Some(DVec3::new(0.0, 0.0, 10.0)));
    /// assert_eq!(slots.observe(one, 5.0, DVec3::new(0.0, 0.3, 10.0)), None);
    /// let left = slots.observe(one, 6.0, DVec3::new(0.0, 2.0, 12.0));
    /// assert!(matches!(left, Some(SlotChange::Left { deviation_m, .. }) if (deviation_m - 2.0).abs() < 1e-12));
    /// ```
    pub fn parse(csv: &str, tolerance_m: f64) -> Result<Self, SlotsError> {
        if !(tolerance_m.is_finite() && tolerance_m > 0.0 && tolerance_m <= 1000.0) {
            return Err(SlotsError::Tolerance(tolerance_m));
        }
        let mut lines = csv.lines().enumerate();
        let header = lines.next().map(|(_, h)| h.trim()).unwrap_or_default();
        let columns: Vec<&str> = header.split(',').map(str::trim).collect();
        let component_column = match columns.as_slice() {
            ["vehicle", "t_s", "east_m", "north_m", "up_m"] => false,
            ["vehicle", "t_s", "east_m", "north_m", "up_m", "component"] => true,
            _ => return Err(SlotsError::Header(header.chars().take(200).collect())),
        };
        let mut plan: BTreeMap<SenderId, Vec<(f64, DVec3)>> = BTreeMap::new();
        let mut count = 0usize;
        for (index, text) in lines {
            let text = text.trim();
            if text.is_empty() {
                continue;
            }
            let line = index + 1;
            let (vehicle, t_s, at) =
                keyframe(text, component_column).map_err(|why| SlotsError::Line { line, why })?;
            let frames = plan.entry(vehicle).or_default();
            if frames.last().is_some_and(|(last, _)| *last >= t_s) {
                return Err(SlotsError::Line {
                    line,
                    why: format!(
                        "t_s {t_s}: not after vehicle {}'s last keyframe",
                        vehicle.system_id
                    ),
                });
            }
            frames.push((t_s, at));
            count += 1;
            if count > MAX_KEYFRAMES {
                return Err(SlotsError::TooMany);
            }
        }
        if count == 0 {
            return Err(SlotsError::Empty);
        }
        Ok(Self {
            plan,
            tolerance_m,
            departures: BTreeMap::new(),
        })
    }

    /// The tolerance, metres.
    pub fn tolerance_m(&self) -> f64 {
        self.tolerance_m
    }

    /// Where `vehicle`'s slot is at `t_s` (none for a vehicle the show does not name).
    pub fn slot_at(&self, vehicle: SenderId, t_s: f64) -> Option<DVec3> {
        let frames = self.plan.get(&vehicle)?;
        let after = frames.partition_point(|(t, _)| *t <= t_s);
        Some(
            match (after.checked_sub(1).map(|i| frames[i]), frames.get(after)) {
                (Some((t0, p0)), Some(&(t1, p1))) => p0.lerp(p1, (t_s - t0) / (t1 - t0)),
                (Some((_, p)), None) | (None, Some(&(_, p))) => p,
                (None, None) => return None,
            },
        )
    }

    /// `vehicle` seen at `enu_m` at `t_s`: whether it left its slot or came back.
    pub fn observe(&mut self, vehicle: SenderId, t_s: f64, enu_m: DVec3) -> Option<SlotChange> {
        let slot_enu_m = self.slot_at(vehicle, t_s)?;
        let deviation_m = enu_m.distance(slot_enu_m);
        let departures = self.departures.entry(vehicle).or_default();
        let open = departures.last_mut().filter(|d| d.end_t_s.is_none());
        match (open, deviation_m > self.tolerance_m) {
            (Some(d), true) => {
                d.max_deviation_m = d.max_deviation_m.max(deviation_m);
                None
            }
            (Some(d), false) => {
                d.end_t_s = Some(t_s);
                Some(SlotChange::Back {
                    t_s,
                    duration_s: t_s - d.start_t_s,
                    max_deviation_m: d.max_deviation_m,
                })
            }
            (None, true) => {
                departures.push(Departure {
                    start_t_s: t_s,
                    end_t_s: None,
                    max_deviation_m: deviation_m,
                });
                Some(SlotChange::Left {
                    t_s,
                    deviation_m,
                    slot_enu_m,
                })
            }
            (None, false) => None,
        }
    }

    /// Every vehicle that left its slot, with its departures, by vehicle.
    pub fn departures(&self) -> impl Iterator<Item = (SenderId, &[Departure])> + '_ {
        self.departures
            .iter()
            .filter(|(_, d)| !d.is_empty())
            .map(|(v, d)| (*v, d.as_slice()))
    }

    /// How many vehicles the show names.
    pub fn vehicles(&self) -> usize {
        self.plan.len()
    }
}

/// One keyframe line: its vehicle, time and position.
fn keyframe(text: &str, component_column: bool) -> Result<(SenderId, f64, DVec3), String> {
    let cells: Vec<&str> = text.split(',').map(str::trim).collect();
    let wanted = if component_column { 6 } else { 5 };
    if cells.len() != wanted {
        return Err(format!("{} cells: give {wanted}", cells.len()));
    }
    let id = |name: &str, cell: &str, min: u8| -> Result<u8, String> {
        cell.parse::<u8>()
            .ok()
            .filter(|v| *v >= min)
            .ok_or_else(|| format!("{name} {cell:?}: give {min} to 255"))
    };
    let number = |name: &str, cell: &str, max: f64| -> Result<f64, String> {
        cell.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && v.abs() <= max)
            .ok_or_else(|| format!("{name} {cell:?}: give a number within +-{max}"))
    };
    let vehicle = SenderId {
        system_id: id("vehicle", cells[0], 1)?,
        component_id: if component_column {
            id("component", cells[5], 0)?
        } else {
            1
        },
    };
    let t_s = number("t_s", cells[1], MAX_DURATION_S)?;
    let at = DVec3::new(
        number("east_m", cells[2], MAX_ENU_M)?,
        number("north_m", cells[3], MAX_ENU_M)?,
        number("up_m", cells[4], MAX_ENU_M)?,
    );
    Ok((vehicle, t_s, at))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one() -> SenderId {
        SenderId {
            system_id: 1,
            component_id: 1,
        }
    }

    #[test]
    fn a_departure_opens_grows_and_closes() {
        let csv = "vehicle,t_s,east_m,north_m,up_m\n1,0,0,0,10\n1,100,100,0,10\n";
        let mut slots = Slots::parse(csv, 1.0).unwrap();
        assert_eq!(
            slots.observe(one(), 10.0, DVec3::new(10.5, 0.0, 10.0)),
            None
        );
        assert!(matches!(
            slots.observe(one(), 20.0, DVec3::new(20.0, 2.0, 10.0)),
            Some(SlotChange::Left { t_s, .. }) if t_s == 20.0
        ));
        assert_eq!(
            slots.observe(one(), 21.0, DVec3::new(21.0, 3.0, 10.0)),
            None
        );
        assert_eq!(
            slots.observe(one(), 25.0, DVec3::new(25.0, 0.0, 10.0)),
            Some(SlotChange::Back {
                t_s: 25.0,
                duration_s: 5.0,
                max_deviation_m: 3.0
            })
        );
        // Held after the last keyframe; a vehicle the show does not name is not judged.
        assert_eq!(
            slots.slot_at(one(), 500.0),
            Some(DVec3::new(100.0, 0.0, 10.0))
        );
        let two = SenderId {
            system_id: 2,
            component_id: 1,
        };
        assert_eq!(slots.observe(two, 1.0, DVec3::ZERO), None);
        let departed: Vec<_> = slots.departures().collect();
        assert_eq!(departed.len(), 1);
    }

    #[test]
    fn bad_slots_are_errors_naming_the_line() {
        let bad = [
            ("t,x\n", "header"),
            ("vehicle,t_s,east_m,north_m,up_m\n", "no keyframe"),
            (
                "vehicle,t_s,east_m,north_m,up_m\n1,0,0,0\n",
                "line 2: 4 cells",
            ),
            (
                "vehicle,t_s,east_m,north_m,up_m\n0,0,0,0,0\n",
                "line 2: vehicle \"0\"",
            ),
            (
                "vehicle,t_s,east_m,north_m,up_m\n1,nan,0,0,0\n",
                "line 2: t_s \"nan\"",
            ),
            ("vehicle,t_s,east_m,north_m,up_m\n1,0,1e99,0,0\n", "east_m"),
            (
                "vehicle,t_s,east_m,north_m,up_m\n1,1,0,0,0\n1,1,0,0,0\n",
                "line 3: t_s 1: not after",
            ),
        ];
        for (csv, says) in bad {
            let e = Slots::parse(csv, 1.0).unwrap_err().to_string();
            assert!(e.contains(says), "{csv:?}: {e}");
        }
        let fine = "vehicle,t_s,east_m,north_m,up_m\n1,0,0,0,0\n";
        for tolerance in [0.0, -1.0, f64::NAN, 1e9] {
            assert!(Slots::parse(fine, tolerance).is_err(), "{tolerance}");
        }
    }
}
