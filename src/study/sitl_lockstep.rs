//! An ArduCopter started in lockstep: its physics port and its SERIAL0 port bound on
//! 127.0.0.1, its SITL started on them (`--model JSON`), and its place in savsim's loop.

use super::sitl::{px4_gcs_port, px4_onboard_ports, ArduCopter, Px4, Sitl, Start};
use crate::lockstep::driver::Lockstepped;
use crate::lockstep::port::{json_port, JsonPort, MavPort, PortError};
use crate::lockstep::vehicle::SimVehicle;

/// Why an ArduCopter could not be started in lockstep.
#[derive(Debug, thiserror::Error)]
pub enum LockstepStartError {
    /// Its physics port.
    #[error("physics port: {0}")]
    Port(#[from] PortError),
    /// A MAVLink port could not be bound, or SITL not started.
    #[error("{what}: {source}")]
    Io {
        /// What failed.
        what: String,
        /// What the system said.
        source: std::io::Error,
    },
}

/// Where an ArduCopter's SERIAL1 goes in lockstep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Serial1<'a> {
    /// A port of savsim's own for a pilot (returned).
    Pilot,
    /// This address (e.g. `udpclient:127.0.0.1:14550`, where a ground station listens).
    To(&'a str),
}

/// Start `arducopter` for `vehicle` as `start` says (its SERIAL0 on a port of savsim's, its
/// physics on `9002 + 10 x instance`), SERIAL1 as `serial1`: its process, its place in the
/// loop, and the pilot's port when [`Serial1::Pilot`].
pub fn start_lockstepped(
    arducopter: &ArduCopter,
    start: &Start<'_>,
    vehicle: SimVehicle,
    serial1: Serial1<'_>,
) -> Result<(Sitl, Lockstepped, Option<MavPort>), LockstepStartError> {
    let io = |what: &str| {
        let what = what.to_string();
        move |source| LockstepStartError::Io { what, source }
    };
    let json = JsonPort::bind(json_port(start.instance))?;
    let serial0 = MavPort::bind().map_err(io("bind SERIAL0's port"))?;
    let pilot = match serial1 {
        Serial1::Pilot => Some(MavPort::bind().map_err(io("bind the pilot's port"))?),
        Serial1::To(_) => None,
    };
    let serial1_address = match (&pilot, serial1) {
        (Some(port), _) => format!("udpclient:127.0.0.1:{}", port.port()),
        (None, Serial1::To(address)) => address.to_string(),
        (None, Serial1::Pilot) => String::new(),
    };
    let serial0_address = format!("udpclient:127.0.0.1:{}", serial0.port());
    let sitl = arducopter
        .start_lockstep(
            &Start {
                serial0: &serial0_address,
                ..start.clone()
            },
            &serial1_address,
        )
        .map_err(io(&format!("start {}", arducopter.binary.display())))?;
    let backend = Box::new(crate::lockstep::backend::ArduPilotJson::new(json));
    Ok((sitl, Lockstepped::new(vehicle, backend, serial0), pilot))
}

/// Start `px4` in lockstep for `vehicle` (system id `system_id`) as `start` says: its
/// simulator port (`4560 + instance`) listening, its GCS link answered on a port of savsim's,
/// its onboard link's port (`14540 + instance`) bound for a pilot: its process, its place in
/// the loop, the pilot's port.
pub fn start_lockstepped_px4(
    px4: &Px4,
    start: &Start<'_>,
    vehicle: SimVehicle,
    (system_id, plane): (u8, crate::geo::LocalTangentPlane),
) -> Result<(Sitl, Lockstepped, MavPort), LockstepStartError> {
    let io = |what: &str| {
        let what = what.to_string();
        move |source| LockstepStartError::Io { what, source }
    };
    let simulator = crate::lockstep::px4::Px4Mavlink::bind(
        crate::lockstep::px4::simulator_port(start.instance),
        plane,
        start.home,
    )?;
    let serial0 = MavPort::bind()
        .map_err(io("bind the GCS link's port"))?
        .sending_to(px4_gcs_port(start.instance));
    let pilot = MavPort::bind_at(px4_onboard_ports(start.instance).1)
        .map_err(io("bind the onboard link's port"))?;
    let sitl = px4
        .start_lockstep(start, system_id)
        .map_err(io(&format!("start {}", px4.binary.display())))?;
    Ok((
        sitl,
        Lockstepped::new(vehicle, Box::new(simulator), serial0),
        pilot,
    ))
}

/// The parameters a preset frame needs of ArduCopter (its FRAME_TYPE: plus or X), after
/// `params`.
pub fn frame_params(frame_name: &str, params: &mut Vec<(String, f64)>) {
    match frame_name {
        "arducopter-quad" => params.push(("FRAME_TYPE".into(), 0.0)),
        "arducopter-quad-x" => params.push(("FRAME_TYPE".into(), 1.0)),
        _ => {}
    }
}
