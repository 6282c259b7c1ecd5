//! A row's vehicles started: each on its own SITL instance (ports, folder, MAVLink system id)
//! with its parameters and home, and its pilot connected.

use super::check::{Checked, Flier};
use super::ids::{autopilot_id, INSTANCE_OFFSET};
use super::session::home_of;
use super::{RowError, Setup};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::geo::LocalTangentPlane;
use crate::links::address::ConnectAddress;
use crate::links::sockets::Link;
use crate::scene::Scene;
use crate::study::pilot::{Pilot, PilotError};
use crate::study::sitl::{px4_gcs_port, px4_onboard_ports, Sitl, Start};
use crate::world::SenderId;

/// The row's vehicles started: vehicle `k` (from 0) on `instance + k x INSTANCE_OFFSET`, the
/// first in `dir`, the others in `dir/vehicle-K` (K from 2).
pub(super) fn start_vehicles(
    runtime: &tokio::runtime::Runtime,
    setup: &Setup,
    checked: &Checked,
    (instance, scene, dir): (u16, &Scene, &Path),
) -> Result<Vec<Vehicle>, RowError> {
    let fliers = std::iter::once(&checked.own).chain(&checked.others);
    let mut vehicles = Vec::with_capacity(1 + checked.others.len());
    for (k, flier) in fliers.enumerate() {
        let dir = match k {
            0 => dir.to_path_buf(),
            k => dir.join(format!("vehicle-{}", k + 1)),
        };
        let at = instance + k as u16 * INSTANCE_OFFSET;
        let start = (flier, k, at, checked.speedup);
        vehicles.push(Vehicle::start(runtime, setup, start, scene, &dir)?);
    }
    Ok(vehicles)
}

/// One vehicle of a row: its SITL, its identity, and its link for the session until the
/// session takes it. Its SITL stops when it is dropped.
pub(super) struct Vehicle {
    pub(super) sitl: Sitl,
    pub(super) id: SenderId,
    pub(super) px4: bool,
    pub(super) instance: u16,
    pub(super) link: Option<Link>,
}

impl Vehicle {
    /// Start `flier`'s SITL (the row's vehicle `k`) on `instance` at `speedup` in `dir`, at its
    /// home.
    fn start(
        runtime: &tokio::runtime::Runtime,
        setup: &Setup,
        (flier, k, instance, speedup): (&Flier, usize, u16, f64),
        scene: &Scene,
        dir: &Path,
    ) -> Result<Self, RowError> {
        let start = Start {
            instance,
            home: home_of(scene, flier.home_en_m),
            home_yaw_deg: 0.0,
            speedup,
            serial0: "",
            params: &flier.params,
            dir,
        };
        let (link, sitl) = start_autopilot(runtime, setup, flier.px4, &start)?;
        Ok(Vehicle {
            sitl,
            id: autopilot_id(flier.px4, instance, k),
            px4: flier.px4,
            instance,
            link: Some(link),
        })
    }
}

/// The row's link for savsim's session and its SITL, started. ArduCopter: savsim listens on a
/// port of its own and SITL's SERIAL0 sends to it. PX4: savsim sends to PX4's GCS link (PX4
/// then answers to savsim's address).
pub(super) fn start_autopilot(
    runtime: &tokio::runtime::Runtime,
    setup: &Setup,
    px4: bool,
    start: &Start<'_>,
) -> Result<(Link, Sitl), RowError> {
    let loopback = |port: u16| std::net::SocketAddr::from(([127, 0, 0, 1], port));
    if px4 {
        let px4 = setup.px4.as_ref().ok_or(RowError::NoAutopilot {
            autopilot: "PX4",
            flag: "px4",
            variable: "SAVSIM_PX4",
        })?;
        let sitl = px4.start_at_home(start)?;
        let address = ConnectAddress::UdpOut(loopback(px4_gcs_port(start.instance)).into());
        let link = runtime.block_on(Link::open(&address))?;
        return Ok((link, sitl));
    }
    let arducopter = setup.arducopter.as_ref().ok_or(RowError::NoAutopilot {
        autopilot: "ArduCopter",
        flag: "arducopter",
        variable: "SAVSIM_ARDUCOPTER",
    })?;
    let link = runtime.block_on(Link::open(&ConnectAddress::UdpIn(loopback(0).into())))?;
    let port = link
        .local_addr()
        .map(|a| a.port())
        .ok_or(RowError::NoLinkPort)?;
    let serial0 = format!("udpclient:127.0.0.1:{port}");
    let sitl = arducopter
        .start(&Start {
            serial0: &serial0,
            ..start.clone()
        })
        .map_err(|source| RowError::SitlStart {
            binary: arducopter.binary.clone(),
            source,
        })?;
    Ok((link, sitl))
}

/// The pilot on the vehicle's port, within a minute; an error at once if SITL ends first or
/// a signal stops the study.
pub(super) fn connect_pilot(
    vehicle: &mut Vehicle,
    plane: LocalTangentPlane,
    stop: &AtomicBool,
) -> Result<Result<Pilot, PilotError>, RowError> {
    if vehicle.px4 {
        // PX4's onboard link: the pilot listens where PX4 sends, and sends where it listens.
        let (listens, sends) = px4_onboard_ports(vehicle.instance);
        return Ok(Pilot::udp(sends, listens, vehicle.id, plane));
    }
    let sitl = &mut vehicle.sitl;
    let started = Instant::now();
    loop {
        if stop.load(Ordering::Relaxed) {
            return Err(RowError::Stopped);
        }
        if let Some(status) = sitl.exited() {
            return Err(RowError::SitlEnded {
                status,
                log: sitl.log_tail(3),
            });
        }
        let within = Duration::from_millis(500);
        match Pilot::connect(sitl.pilot_port, vehicle.id, plane, within) {
            Ok(pilot) => return Ok(Ok(pilot)),
            Err(e) if started.elapsed() > Duration::from_secs(60) => return Ok(Err(e)),
            Err(_) => {}
        }
    }
}
