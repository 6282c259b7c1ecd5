//! What surveillance devices' reports become when they arrive: ADSB_VEHICLE messages, and what
//! the vehicle was told of each aircraft.

use serde::Serialize;

use savsim_core::sensors::device::{Device, Model};
use savsim_core::sensors::surveillance::TargetReport;

use super::wire;
use super::Frame;
use crate::scene::Kind;

/// What the vehicle was told of one aircraft, for the summary and rows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Told {
    /// When the first report of it arrived, seconds of the vehicle's clock.
    pub first_detection_s: Option<f64>,
    /// Its true range then, metres.
    pub first_detection_range_m: Option<f64>,
    /// The closest it was reported (the vehicle's true position to the reported one), metres.
    pub sensed_closest_m: Option<f64>,
    /// Reports that did not get through while it was within the device's range.
    pub reports_lost: u64,
    /// Reports that did.
    pub reports_received: u64,
}

impl Told {
    /// Two aircraft's (or vehicles') together: the earlier detection, the closer approach, the
    /// reports summed.
    pub fn and(&self, other: &Told) -> Told {
        let earlier = match (self.first_detection_s, other.first_detection_s) {
            (Some(a), Some(b)) if b < a => other,
            (Some(_), _) | (None, None) => self,
            (None, Some(_)) => other,
        };
        Told {
            first_detection_s: earlier.first_detection_s,
            first_detection_range_m: earlier.first_detection_range_m,
            sensed_closest_m: match (self.sensed_closest_m, other.sensed_closest_m) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            },
            reports_lost: self.reports_lost + other.reports_lost,
            reports_received: self.reports_received + other.reports_received,
        }
    }
}

/// Whether a target `range_m` away is within a surveillance device's reach (for counting lost
/// reports).
pub(super) fn in_range(device: &Device, range_m: f64) -> bool {
    match &device.model {
        Model::Adsb(m) => m.reception.last().is_some_and(|r| range_m <= r.within_m),
        Model::Radar(m) => (m.range_m[0]..=m.range_m[1]).contains(&range_m),
        Model::EoIr(m) => range_m <= m.max_range_m,
        Model::Range(_) => false,
    }
}

/// ADSB_VEHICLE of a report, `age_s` after it was made, when it puts the aircraft within the
/// ADS-B radius.
pub(super) fn send_report(
    f: &mut Frame<'_, '_>,
    r: &TargetReport,
    icao: u32,
    kind: Kind,
    age_s: f64,
) {
    if !f.within_adsb_radius(r.position_enu_m) {
        return;
    }
    let plane = f.input.plane;
    let mut position = plane.geodetic_from_enu_m(r.position_enu_m);
    position.alt_m = r.altitude_m;
    let callsign = format!("{:06X}", icao & 0xFF_FFFF);
    let aircraft = wire::Aircraft {
        icao_address: icao,
        callsign: &callsign,
        position,
        velocity_ned_mps: plane.ned_vector_at(&position, r.velocity_enu_mps),
        kind,
    };
    f.push_adsb(&aircraft, age_s.max(0.0));
}
