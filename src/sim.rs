//! `savsim sim`: fly ArduCopter SITLs in savsim's world by hand. savsim flies the vehicles
//! (lockstep, at real time or any speed), each autopilot's SERIAL1 goes to a ground station
//! (QGroundControl, MAVProxy), savsim's session takes SERIAL0 (its feed, the autopilot's
//! estimate) and shows the world in the viewer when asked.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use glam::DVec3;

use crate::cli::SimArgs;
use crate::error::{Error, Result};
use crate::geo::LocalTangentPlane;
use crate::lockstep::driver::{run, Lockstepped, LoopConfig};
use crate::lockstep::physics::{frame_named, step_us, wind_ned_mps};
use crate::lockstep::vehicle::SimVehicle;
use crate::scene::Scene;
use crate::session::Session;
use crate::study::sitl::{ArduCopter, Sitl, Start};
use crate::study::sitl_lockstep::{frame_params, start_lockstepped, Serial1};
use crate::world::SenderId;

/// The most vehicles `savsim sim` flies.
pub const MAX_SIM_VEHICLES: usize = 64;

/// What `savsim sim` was asked, checked.
pub struct SimPlan {
    /// The ArduCopter to start.
    pub arducopter: ArduCopter,
    /// How many.
    pub count: usize,
    /// Their frame's name and the frame.
    pub frame: (String, savsim_core::dynamics::Frame),
    /// The loop.
    pub config: LoopConfig,
    /// The wind, NED m/s.
    pub wind_ned_mps: DVec3,
    /// Each SERIAL1's address.
    pub gcs: String,
    /// The first instance.
    pub instance: u16,
    /// The SITLs' folders' parent.
    pub work: PathBuf,
}

impl SimPlan {
    /// `args` checked: every number in range, the frame read, an ArduCopter named.
    pub fn from_args(args: &SimArgs) -> Result<SimPlan> {
        let usage = |flag: &str, e: &dyn std::fmt::Display| Error::Usage(format!("{flag}: {e}"));
        if !(1..=MAX_SIM_VEHICLES).contains(&args.count) {
            return Err(Error::Usage(format!(
                "--count {}: give 1 to {MAX_SIM_VEHICLES}",
                args.count
            )));
        }
        if !(args.speed == 0.0 || (0.01..=1000.0).contains(&args.speed)) {
            return Err(Error::Usage(format!(
                "--speed {}: give 0 (as fast as the autopilots go) or 0.01 to 1000",
                args.speed
            )));
        }
        if let Some(d) = args.duration_s {
            savsim_core::bounds::within(
                "--duration-s",
                d,
                0.0,
                savsim_core::bounds::MAX_DURATION_S,
            )?;
        }
        let arducopter =
            ArduCopter::from_flag_or_env(args.sitl.arducopter.as_deref()).ok_or_else(|| {
                Error::Usage("give --arducopter PATH or set SAVSIM_ARDUCOPTER".into())
            })?;
        let frame = frame_named(&args.frame).map_err(|e| usage("--frame", &e))?;
        let step = step_us(args.step_ms).map_err(|e| usage("--step-ms", &e))?;
        let wind = match &args.wind {
            Some(w) => wind_ned_mps(w).map_err(|e| usage("--wind", &e))?,
            None => DVec3::ZERO,
        };
        let last = u32::from(args.instance) + args.count as u32;
        if crate::lockstep::port::json_port_checked(last).is_none() {
            return Err(Error::Usage(format!(
                "--instance {}: the last vehicle's physics port is past 65535",
                args.instance
            )));
        }
        Ok(SimPlan {
            arducopter,
            count: args.count,
            frame: (args.frame.clone(), frame),
            config: LoopConfig {
                step_us: step,
                truth_every_us: 20_000,
                real_time: (args.speed > 0.0).then_some(args.speed),
                silence: Duration::from_secs(20),
                end_us: args.duration_s.map(|d| (d * 1e6) as u64),
                stop_on_collision: false,
                end_with_first_pilot: false,
            },
            wind_ned_mps: wind,
            gcs: args.gcs.clone(),
            instance: args.instance,
            work: args.work.clone(),
        })
    }
}

/// The vehicles of `plan` started over `scene` for `session` (which takes their truth).
fn start(
    plan: &SimPlan,
    scene: &Scene,
    session: &mut Session,
) -> Result<(Vec<Sitl>, Vec<Lockstepped>)> {
    let plane = LocalTangentPlane::new(scene.origin);
    let (mut sitls, mut vehicles) = (Vec::new(), Vec::new());
    let ids: Vec<SenderId> = (0..plan.count)
        .map(|k| SenderId {
            system_id: (k + 1) as u8,
            component_id: 1,
        })
        .collect();
    session.set_truth_fed(ids.clone());
    for (k, id) in ids.into_iter().enumerate() {
        let home = crate::study::row::home_on_ground(scene, [5.0 * k as f64, 0.0]);
        let mut params = vec![("SYSID_THISMAV".to_string(), f64::from(id.system_id))];
        frame_params(&plan.frame.0, &mut params);
        let dir = plan.work.join(format!("vehicle-{}", k + 1));
        let start = Start {
            instance: plan.instance + k as u16,
            home,
            home_yaw_deg: 0.0,
            speedup: 1.0,
            serial0: "",
            params: &params,
            dir: &dir,
        };
        let vehicle = SimVehicle::landed(
            id,
            plan.frame.1.clone(),
            (home, plane.enu_m_from_geodetic(&home)),
            0.0,
            plan.wind_ned_mps,
        );
        let (sitl, lockstepped, _) =
            start_lockstepped(&plan.arducopter, &start, vehicle, Serial1::To(&plan.gcs))
                .map_err(|e| Error::Runtime(format!("vehicle {}: {e}", k + 1)))?;
        println!(
            "vehicle {} (system id {}): SITL instance {}, SERIAL1 to {}, its folder {}",
            k + 1,
            id.system_id,
            start.instance,
            plan.gcs,
            dir.display()
        );
        sitls.push(sitl);
        vehicles.push(lockstepped);
    }
    Ok((sitls, vehicles))
}

/// Fly `plan` over `scene` through `session` until its duration or `shutdown`; the clock
/// reached, seconds.
pub fn fly(
    plan: &SimPlan,
    scene: &Scene,
    session: &mut Session,
    shutdown: &Arc<AtomicBool>,
) -> Result<f64> {
    let (mut sitls, mut vehicles) = start(plan, scene, session)?;
    let stop = |_: u64| shutdown.load(Ordering::Relaxed);
    let flown = run(&mut vehicles, scene, session, &plan.config, &stop);
    let ended_by_itself: Vec<String> = sitls
        .iter_mut()
        .enumerate()
        .filter_map(|(k, s)| {
            s.exited()
                .map(|status| format!("vehicle {}: {status}: {}", k + 1, s.log_tail(3)))
        })
        .collect();
    drop(sitls);
    match flown {
        Ok((time_us, _)) => Ok(time_us as f64 / 1e6),
        Err(e) if !ended_by_itself.is_empty() => Err(Error::Runtime(format!(
            "{e}; SITL ended by itself: {}",
            ended_by_itself.join("; ")
        ))),
        Err(e) => Err(Error::Runtime(e.to_string())),
    }
}
