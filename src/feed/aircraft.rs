//! The aircraft a vehicle is told about, and what the feed calls them.

use glam::DVec3;

use super::{wire, FrameInput};
use crate::pipeline::{BodySource, DynamicBody};
use crate::scene::DynamicSource;

/// A moving body's velocity, ENU m/s: its speed along its motion in this interval (along its
/// nose when it did not move).
pub(super) fn body_velocity(d: &DynamicBody) -> DVec3 {
    let moved = d.current.position_enu_m - d.previous.position_enu_m;
    let along = moved
        .try_normalize()
        .unwrap_or_else(|| d.current.enu_from_body * DVec3::X);
    along * d.speed_mps
}

/// The ICAO addresses the feed gives the aircraft it sends: `0xF0xxxx` the scene's track
/// `xxxx`, `0xF1SSCC` MAVLink vehicle SS/CC. While `--feed adsb` is on, a real transponder
/// with such an address would be taken for an echo (docs/closed-loop.md, limits).
pub(super) const TRACK_ICAO: u32 = 0xF0_0000;
pub(super) const VEHICLE_ICAO: u32 = 0xF1_0000;

/// Whether `icao` is one the feed gives an aircraft.
pub(super) fn is_feed_icao(icao: u32) -> bool {
    matches!(icao & 0xFF_0000, TRACK_ICAO | VEHICLE_ICAO)
}

/// Whether a moving body carries a transponder: a scene track as its `[[dynamic]]` says
/// (default yes), every MAVLink vehicle.
pub(super) fn has_transponder(input: &FrameInput<'_>, body: &DynamicBody) -> bool {
    match body.key.source {
        BodySource::Scripted(i) => input
            .scene
            .dynamic
            .get(i as usize)
            .is_none_or(|d| d.transponder),
        _ => true,
    }
}

/// The aircraft a vehicle is told about: the scene's scripted tracks and declared vehicles, and
/// every other MAVLink vehicle savsim mirrors; not ADS-B traffic (the vehicle's own receiver
/// or its GCS already has it) and never the vehicle itself.
pub(super) fn aircraft<'a>(
    input: &'a FrameInput<'a>,
) -> impl Iterator<Item = (wire::Aircraft<'a>, &'a DynamicBody)> + 'a {
    input.dynamic.as_slice().iter().filter_map(move |d| {
        let icao_address = match d.key.source {
            BodySource::Scripted(i) => match input.scene.dynamic.get(i as usize)?.source {
                DynamicSource::Icao(_) => return None,
                DynamicSource::Waypoints(_) | DynamicSource::SystemId(_) => {
                    TRACK_ICAO | (i & 0xFFFF)
                }
            },
            BodySource::Vehicle {
                vehicle,
                component_id,
            } => {
                if (vehicle, component_id) == (input.key.vehicle, input.key.component_id) {
                    return None;
                }
                VEHICLE_ICAO | (u32::from(vehicle & 0xFF) << 8) | u32::from(component_id)
            }
            BodySource::Traffic(_) => return None,
        };
        let position = input.plane.geodetic_from_enu_m(d.current.position_enu_m);
        Some((
            wire::Aircraft {
                icao_address,
                callsign: &d.id,
                position,
                velocity_ned_mps: input.plane.ned_vector_at(&position, body_velocity(d)),
                kind: d.kind,
            },
            d,
        ))
    })
}
