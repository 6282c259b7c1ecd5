//! A track of the world: a MAVLink vehicle's (its identity, generation, clock map, history,
//! what it said of itself) and an ADS-B aircraft's.

use crate::world::inputs::{self, SenderId};
use crate::world::samples::{Attitude, History};
use crate::world::{clock, timeline};

/// A MAVLink vehicle (a sender of GLOBAL_POSITION_INT).
#[derive(Debug, Clone)]
pub struct VehicleTrack {
    /// Its id as a moving obstacle to other vehicles (`vehicle:7`).
    pub label: std::sync::Arc<str>,
    /// Generation of the track: new at creation and at every reboot, so collision state kept
    /// for an earlier life of the same (sysid, compid) is detectably stale.
    pub generation: u32,
    /// Who it is.
    pub id: SenderId,
    /// MAV_TYPE and MAV_AUTOPILOT from its HEARTBEAT, if one came.
    pub heartbeat: Option<inputs::HeartbeatReport>,
    /// The latest ATTITUDE, converted; positions take it until the next one.
    pub latest_attitude: Option<Attitude>,
    /// Position history.
    pub history: History,
    /// Receive/tlog time of the last message of any kind, seconds.
    pub last_heard_t_s: f64,
    /// Times its `time_boot_ms` went back (reboots).
    pub boot_resets: u64,
    /// Its clock mapped onto the receive clock (this boot's).
    pub clock: clock::ClockMap,
    /// Positions accepted.
    pub positions: u64,
    /// On a timeline of several vehicles' clocks: its drift from the timeline's.
    pub skew: timeline::SkewWindow,
    /// On a timeline of several vehicles' clocks: its last readings, to place it.
    pub recent: timeline::RecentClock,
}

impl VehicleTrack {
    /// Where a position of this vehicle (not the timeline's reference) stamped
    /// `time_boot_ms` and arrived at `receive_t_s` lies on `timeline`: when its clock read
    /// that time ([`timeline::RecentClock::sent_at`]), and the timeline then; never before
    /// its last sample (`mapped_s`, its receive-clock time, until the timeline has a pace).
    /// Its skew takes the reading.
    pub(super) fn on_timeline(
        &mut self,
        time_boot_ms: u32,
        receive_t_s: f64,
        timeline: &timeline::Timeline,
        mapped_s: f64,
    ) -> f64 {
        let vehicle_s = f64::from(time_boot_ms) / 1000.0;
        self.recent.push(vehicle_s, receive_t_s);
        let rate = self
            .clock
            .fitted_rate()
            .or_else(|| self.recent.rate())
            .or(timeline.rate())
            .unwrap_or(1.0);
        let sent_s = self.recent.sent_at(vehicle_s, rate).unwrap_or(receive_t_s);
        let last_s = self.history.latest().map_or(f64::NEG_INFINITY, |s| s.t_s);
        let t_s = timeline.at(sent_s).unwrap_or(mapped_s).max(last_s + 1e-6);
        self.skew.take(vehicle_s, t_s);
        t_s
    }
}

/// An ADS-B aircraft.
#[derive(Debug, Clone)]
pub struct TrafficTrack {
    /// Its id as a moving obstacle (`icao:4840D6`).
    pub label: std::sync::Arc<str>,
    /// Generation of the track: new each time it is created (after an expiry too).
    pub generation: u32,
    /// ICAO 24-bit address.
    pub icao_address: u32,
    /// Callsign as sent (trimmed ASCII).
    pub callsign: String,
    /// ADSB_EMITTER_TYPE number.
    pub emitter_type: u8,
    /// Position history.
    pub history: History,
    /// Receive/tlog time of its last report, seconds.
    pub last_heard_t_s: f64,
    /// Its last report's altitude was barometric (QNH), not geometric.
    pub pressure_altitude: bool,
}
