//! Flying a plan with the pilot, on the vehicle's clock: arm in GUIDED at the first
//! `takeoff`, then each leg's velocity target at every position until the leg is done, the
//! row's time on the vehicle's clock is up, or the caller says stop.

use glam::DVec3;
use mavlink::dialects::ardupilotmega::MavCmd;

use crate::study::pilot::{goto_velocity, leg_done, mode, Fix, Pilot, PilotError};
use crate::study::plan::Leg;

/// How long an autopilot may take to arm, seconds of its clock (ArduCopter SITL's EKF and GPS
/// take about 20-30 s after boot).
pub const ARM_WITHIN_S: f64 = 180.0;
/// Mode and arm requests are repeated this often while waiting, seconds of the vehicle's clock.
const ASK_EVERY_S: f64 = 1.0;

/// How far a plan got.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Flown {
    /// Legs flown to their end.
    pub legs_completed: usize,
    /// The last position's clock, ms.
    pub last_ms: u32,
    /// When the vehicle first fell under half the commanded speed after reaching 80% of it,
    /// seconds of its clock.
    pub slowed_t_s: Option<f64>,
    /// Whether the caller stopped it (a collision, a signal, the wall limit).
    pub stopped: bool,
    /// When it was armed in GUIDED, seconds of its clock.
    pub armed_t_s: Option<f64>,
}

/// Seconds of the vehicle's clock (from its boot) at `fix`.
fn clock_s(fix: &Fix) -> f64 {
    f64::from(fix.time_boot_ms) / 1000.0
}

/// Watches for the vehicle slowing against its command (the sign of proximity avoidance).
#[derive(Debug, Default)]
struct SlowWatch {
    reached: bool,
}

impl SlowWatch {
    /// At one position with `command` (m/s) in force: whether the vehicle slowed now.
    fn slowed(&mut self, command: DVec3, fix: &Fix) -> bool {
        let speed = command.length();
        if speed < 0.5 {
            self.reached = false;
            return false;
        }
        let along = fix.velocity_enu_mps.dot(command / speed);
        if along >= 0.8 * speed {
            self.reached = true;
            return false;
        }
        self.reached && along < 0.5 * speed
    }
}

/// Fly `legs`, until `duration_s` of the vehicle's clock (from its boot).
pub fn fly(
    pilot: &mut Pilot,
    legs: &[Leg],
    duration_s: f64,
    stop: &dyn Fn() -> bool,
) -> Result<Flown, PilotError> {
    let Some(first) = pilot.next_fix(stop)? else {
        return Ok(Flown {
            stopped: true,
            ..Flown::default()
        });
    };
    pilot.ask_positions()?;
    let mut flown = Flown {
        last_ms: first.time_boot_ms,
        ..Flown::default()
    };
    let mut watch = SlowWatch::default();
    for leg in legs {
        if let Leg::Takeoff { .. } = leg {
            arm_guided(pilot, &mut flown, duration_s, stop)?;
        }
        // Where and when the leg begins: for a takeoff, where it armed.
        let began = pilot.fix.unwrap_or(first);
        start_leg(pilot, leg)?;
        loop {
            let Some(fix) = pilot.next_fix(stop)? else {
                flown.stopped = true;
                return Ok(flown);
            };
            flown.last_ms = fix.time_boot_ms;
            if clock_s(&fix) >= duration_s {
                return Ok(flown);
            }
            // Targets only in GUIDED: in a mode the autopilot chose (AVOID_ADSB, RTL, ...) it
            // flies itself, and a GUIDED-derived mode would take a target over its own.
            let (mode_now, armed) = pilot.state();
            let command = command_of(leg, &fix).filter(|_| mode_now == Some(mode::GUIDED));
            if let Some(v) = command {
                pilot.velocity(v)?;
            }
            if watch.slowed(command.unwrap_or(DVec3::ZERO), &fix) && flown.slowed_t_s.is_none() {
                flown.slowed_t_s = Some(clock_s(&fix));
            }
            if leg_done(leg, &fix, &began, armed) {
                break;
            }
        }
        flown.legs_completed += 1;
    }
    Ok(flown)
}

/// The velocity target a leg sends at `fix` (none while taking off or landing).
fn command_of(leg: &Leg, fix: &Fix) -> Option<DVec3> {
    match *leg {
        Leg::Goto { enu_m, speed_mps } => {
            Some(goto_velocity(fix.enu_m, DVec3::from(enu_m), speed_mps))
        }
        Leg::Velocity { enu_mps, .. } => Some(DVec3::from(enu_mps)),
        Leg::Hold { .. } => Some(DVec3::ZERO),
        Leg::Takeoff { .. } | Leg::Land => None,
    }
}

/// What a leg sends once, at its start.
fn start_leg(pilot: &mut Pilot, leg: &Leg) -> Result<(), PilotError> {
    match *leg {
        Leg::Takeoff { up_m } => pilot.command(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, up_m as f32],
        ),
        Leg::Land => pilot.command(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [1.0, mode::LAND as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
        ),
        _ => Ok(()),
    }
}

/// GUIDED and armed, asking once a second of the vehicle's clock, within [`ARM_WITHIN_S`] of it
/// (and within the row's time).
fn arm_guided(
    pilot: &mut Pilot,
    flown: &mut Flown,
    duration_s: f64,
    stop: &dyn Fn() -> bool,
) -> Result<(), PilotError> {
    let began_ms = flown.last_ms;
    let mut asked_ms: Option<u32> = None;
    loop {
        let (mode_now, armed) = pilot.state();
        if armed && mode_now == Some(mode::GUIDED) {
            flown.armed_t_s = Some(f64::from(flown.last_ms) / 1000.0);
            return Ok(());
        }
        let Some(fix) = pilot.next_fix(stop)? else {
            return Ok(());
        };
        flown.last_ms = fix.time_boot_ms;
        let waited_s = f64::from(fix.time_boot_ms.wrapping_sub(began_ms)) / 1000.0;
        if waited_s > ARM_WITHIN_S || clock_s(&fix) >= duration_s {
            let texts: Vec<String> = pilot
                .heard()
                .texts
                .iter()
                .rev()
                .take(5)
                .map(|t| t.2.clone())
                .collect();
            return Err(PilotError::NoArm {
                waited_s,
                texts: texts.join("; "),
            });
        }
        let due = asked_ms
            .is_none_or(|a| f64::from(fix.time_boot_ms.wrapping_sub(a)) / 1000.0 >= ASK_EVERY_S);
        if due {
            asked_ms = Some(fix.time_boot_ms);
            pilot.command(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [1.0, mode::GUIDED as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
            )?;
            pilot.command(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            )?;
        }
    }
}
