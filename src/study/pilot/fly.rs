//! Flying a plan with the pilot, on the vehicle's clock: arm in GUIDED at the first
//! `takeoff`, then each leg's velocity target at every position until the leg is done, the
//! row's time on the vehicle's clock is up, or the caller says stop.

use glam::DVec3;
use mavlink::dialects::ardupilotmega::MavCmd;

use crate::study::pilot::heard::Fix;
use crate::study::pilot::{mode, Pilot, PilotError};
use crate::study::plan::Leg;

/// A goto is done within this distance of its point, metres.
pub const GOTO_DONE_M: f64 = 1.0;
/// A takeoff is done within this height of its target, metres.
pub const TAKEOFF_DONE_M: f64 = 1.0;

/// How long an autopilot may take to arm, seconds of its clock: well beyond the time SITL's EKF
/// and GPS take to be ready after boot (docs/study.md, "Measured").
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

impl Flown {
    /// Stopped before the first position: nothing flown.
    fn stopped() -> Self {
        Flown {
            stopped: true,
            ..Flown::default()
        }
    }
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

/// Fly `legs` on ArduCopter (GUIDED velocity targets), until `duration_s` of the vehicle's
/// clock (from its boot).
pub fn fly(
    pilot: &mut Pilot,
    legs: &[Leg],
    duration_s: f64,
    stop: &dyn Fn() -> bool,
) -> Result<Flown, PilotError> {
    let Some(first) = first_fix(pilot, stop)? else {
        return Ok(Flown::stopped());
    };
    fly_legs(pilot, legs, first, duration_s, &mut Steer::Guided, stop)
}

/// The autopilot's first position, then positions asked at the pilot's rate; `None` when
/// `stop` came first.
fn first_fix(pilot: &mut Pilot, stop: &dyn Fn() -> bool) -> Result<Option<Fix>, PilotError> {
    let first = pilot.next_fix(stop)?;
    if first.is_some() {
        pilot.ask_positions()?;
    }
    Ok(first)
}

/// How a leg's velocity reaches the autopilot.
enum Steer {
    /// ArduCopter: GUIDED velocity targets.
    Guided,
    /// PX4: Position mode's sticks.
    Sticks {
        /// PX4's stick mapping.
        map: StickMap,
        /// Position mode was taken once (a mode PX4 chooses later is left to it).
        position_mode_taken: bool,
        /// When the leg's takeoff or Position mode was last asked for, its clock (ms).
        asked_ms: u32,
        /// PX4's traffic avoidance took over (RTL or LAND of its own): the plan is left to it.
        took_over: bool,
    },
}

impl Steer {
    /// What a leg sends once, at its start (`began`).
    fn start_leg(&mut self, pilot: &mut Pilot, leg: &Leg, began: &Fix) -> Result<(), PilotError> {
        match self {
            Steer::Guided => start_leg(pilot, leg),
            Steer::Sticks { asked_ms, .. } => {
                *asked_ms = began.time_boot_ms;
                start_leg_px4(pilot, leg)
            }
        }
    }

    /// At one position of `leg` (begun at `began`, the autopilot in `mode_now`): send what the
    /// leg asks; the velocity asked (zero when none).
    fn at(
        &mut self,
        pilot: &mut Pilot,
        leg: &Leg,
        fix: &Fix,
        began: &Fix,
        mode_now: Option<u32>,
    ) -> Result<DVec3, PilotError> {
        let command = command_of(leg, fix);
        match self {
            Steer::Guided if pilot.companion_intent.is_some() => {
                // A companion flies: it is told what the plan asks.
                if let Some(Ok(mut intent)) = pilot.companion_intent.as_ref().map(|i| i.lock()) {
                    *intent = command;
                }
                Ok(command.unwrap_or(DVec3::ZERO))
            }
            Steer::Guided => {
                // Targets only in GUIDED: in a mode the autopilot chose (AVOID_ADSB, RTL, ...)
                // it flies itself, and a GUIDED-derived mode would take a target over its own.
                let command = command.filter(|_| mode_now == Some(mode::GUIDED));
                if let Some(v) = command {
                    pilot.velocity(v)?;
                }
                Ok(command.unwrap_or(DVec3::ZERO))
            }
            Steer::Sticks {
                map,
                position_mode_taken,
                asked_ms,
                took_over,
            } => {
                // PX4 took over (its traffic avoidance returns or lands): from then on sticks
                // centred, no takeoff or mode asked again, whatever the leg.
                *took_over |= mode_now.is_some_and(px4_avoiding) && !matches!(leg, Leg::Land);
                if *took_over {
                    pilot.sticks(0.0, 0.0, 0.0)?;
                    return Ok(DVec3::ZERO);
                }
                // PX4 may refuse a takeoff sent the moment it armed: asked again every 3 s of
                // its clock while it has not left the ground.
                let low = fix.enu_m.z - began.enu_m.z < 1.0;
                let since_ms = fix.time_boot_ms.wrapping_sub(*asked_ms);
                if matches!(leg, Leg::Takeoff { .. }) && low && since_ms >= 3000 {
                    *asked_ms = fix.time_boot_ms;
                    start_leg_px4(pilot, leg)?;
                }
                if let Some(intent) = pilot.companion_intent.as_ref() {
                    // A companion flies (in OFFBOARD, which it asks for): it is told what the
                    // plan asks; the sticks stay centred, so PX4 never loses its manual
                    // control (nor follows it: OFFBOARD ignores the sticks).
                    if let Ok(mut intent) = intent.lock() {
                        *intent = command;
                    }
                    pilot.sticks(0.0, 0.0, 0.0)?;
                    return Ok(command.unwrap_or(DVec3::ZERO));
                }
                let in_position_mode = mode_now.is_some_and(|m| (m >> 16) & 0xff == PX4_POSCTL);
                // Position mode once, at the first leg after the takeoff (asked until PX4
                // takes it); a mode PX4 chose later (its traffic avoidance's) is left to it.
                if command.is_some() && in_position_mode {
                    *position_mode_taken = true;
                } else if command.is_some()
                    && !*position_mode_taken
                    && fix.time_boot_ms.wrapping_sub(*asked_ms) >= 1000
                {
                    *asked_ms = fix.time_boot_ms;
                    pilot.command(
                        MavCmd::MAV_CMD_DO_SET_MODE,
                        [1.0, PX4_POSCTL as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
                    )?;
                }
                let wanted = command.filter(|_| in_position_mode).unwrap_or(DVec3::ZERO);
                let (forward, right, up) = map.sticks(wanted, fix.heading_deg.unwrap_or(0.0));
                pilot.sticks(forward, right, up)?;
                Ok(wanted)
            }
        }
    }
}

/// Fly `legs` from the first position `first` until `duration_s` of the vehicle's clock:
/// armed at a takeoff, each leg started, then steered at every position until it is done.
fn fly_legs(
    pilot: &mut Pilot,
    legs: &[Leg],
    first: Fix,
    duration_s: f64,
    steer: &mut Steer,
    stop: &dyn Fn() -> bool,
) -> Result<Flown, PilotError> {
    let mut flown = Flown {
        last_ms: first.time_boot_ms,
        ..Flown::default()
    };
    let px4 = matches!(steer, Steer::Sticks { .. });
    let mut watch = SlowWatch::default();
    for leg in legs {
        if let Leg::Takeoff { .. } = leg {
            arm(pilot, &mut flown, duration_s, px4, stop)?;
        }
        // Where and when the leg begins: for a takeoff, where it armed.
        let began = pilot.fix.unwrap_or(first);
        steer.start_leg(pilot, leg, &began)?;
        loop {
            let Some(fix) = pilot.next_fix(stop)? else {
                flown.stopped = true;
                return Ok(flown);
            };
            flown.last_ms = fix.time_boot_ms;
            if clock_s(&fix) >= duration_s {
                return Ok(flown);
            }
            let (mode_now, armed) = pilot.state();
            let wanted = steer.at(pilot, leg, &fix, &began, mode_now)?;
            if watch.slowed(wanted, &fix) && flown.slowed_t_s.is_none() {
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
        Leg::Hold { .. } | Leg::Until { .. } => Some(DVec3::ZERO),
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

/// Armed (and, for ArduCopter, in GUIDED), asking once a second of the vehicle's clock, within
/// [`ARM_WITHIN_S`] of it and the row's time. PX4's sticks are centred at every position
/// meanwhile: it wants its manual input alive.
fn arm(
    pilot: &mut Pilot,
    flown: &mut Flown,
    duration_s: f64,
    px4: bool,
    stop: &dyn Fn() -> bool,
) -> Result<(), PilotError> {
    let began_ms = flown.last_ms;
    let mut asked_ms: Option<u32> = None;
    loop {
        let (mode_now, armed) = pilot.state();
        if armed && (px4 || mode_now == Some(mode::GUIDED)) {
            flown.armed_t_s = Some(f64::from(flown.last_ms) / 1000.0);
            return Ok(());
        }
        let Some(fix) = pilot.next_fix(stop)? else {
            return Ok(());
        };
        flown.last_ms = fix.time_boot_ms;
        if px4 {
            pilot.sticks(0.0, 0.0, 0.0)?;
        }
        let waited_s = f64::from(fix.time_boot_ms.wrapping_sub(began_ms)) / 1000.0;
        if waited_s > ARM_WITHIN_S || clock_s(&fix) >= duration_s {
            return Err(PilotError::NoArm {
                waited_s,
                texts: pilot.heard().last_texts(),
            });
        }
        let due = asked_ms
            .is_none_or(|a| f64::from(fix.time_boot_ms.wrapping_sub(a)) / 1000.0 >= ASK_EVERY_S);
        if due {
            asked_ms = Some(fix.time_boot_ms);
            if !px4 {
                pilot.command(
                    MavCmd::MAV_CMD_DO_SET_MODE,
                    [1.0, mode::GUIDED as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
                )?;
            }
            pilot.command(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            )?;
        }
    }
}

/// PX4's main mode POSCTL (custom_mode's third byte).
const PX4_POSCTL: u32 = 3;

/// Whether PX4's `custom_mode` is AUTO.RTL or AUTO.LAND: what its traffic avoidance switches to
/// (main mode 4, AUTO, in the third byte; sub mode 5 RTL or 6 LAND in the fourth).
///
/// ```
/// use savsim::study::pilot::fly::px4_avoiding;
/// assert!(px4_avoiding((4 << 16) | (5 << 24)) && px4_avoiding((4 << 16) | (6 << 24)));
/// assert!(!px4_avoiding(3 << 16) && !px4_avoiding((4 << 16) | (2 << 24)));
/// ```
pub fn px4_avoiding(custom_mode: u32) -> bool {
    (custom_mode >> 16) & 0xff == 4 && matches!(custom_mode >> 24, 5 | 6)
}

/// PX4's Position-mode stick mapping, from its parameters (their defaults when unread).
#[derive(Debug, Clone, Copy)]
struct StickMap {
    vel_xy: f64,
    vel_up: f64,
    vel_down: f64,
    dz: f64,
    expo_xy: f64,
    expo_z: f64,
}

impl StickMap {
    /// The map from PX4's defaults, overridden by `params` (what its launcher set at boot).
    fn from_params(params: &[(String, f64)]) -> StickMap {
        let get = |name: &str, default: f64| {
            params
                .iter()
                .rev()
                .find(|(n, _)| n == name)
                .map_or(default, |(_, v)| *v)
                .max(0.0)
        };
        StickMap {
            vel_xy: get("MPC_VEL_MANUAL", 10.0).max(0.1),
            vel_up: get("MPC_Z_VEL_MAX_UP", 3.0).max(0.1),
            vel_down: get("MPC_Z_VEL_MAX_DN", 1.5).max(0.1),
            dz: get("MPC_HOLD_DZ", 0.1).min(0.9),
            expo_xy: get("MPC_XY_MAN_EXPO", 0.6).min(1.0),
            expo_z: get("MPC_Z_MAN_EXPO", 0.6).min(1.0),
        }
    }

    fn read(pilot: &mut Pilot, stop: &dyn Fn() -> bool) -> Result<StickMap, PilotError> {
        let mut get = |name: &str, default: f64| -> Result<f64, PilotError> {
            Ok(pilot
                .read_param(name, 3.0, stop)?
                .map_or(default, |(v, _)| f64::from(v))
                .max(0.0))
        };
        Ok(StickMap {
            vel_xy: get("MPC_VEL_MANUAL", 10.0)?.max(0.1),
            vel_up: get("MPC_Z_VEL_MAX_UP", 3.0)?.max(0.1),
            vel_down: get("MPC_Z_VEL_MAX_DN", 1.5)?.max(0.1),
            dz: get("MPC_HOLD_DZ", 0.1)?.min(0.9),
            expo_xy: get("MPC_XY_MAN_EXPO", 0.6)?.min(1.0),
            expo_z: get("MPC_Z_MAN_EXPO", 0.6)?.min(1.0),
        })
    }

    /// Sticks (forward, right, up) asking for `velocity` (ENU m/s) of a vehicle heading
    /// `heading_deg` (clockwise from north).
    fn sticks(&self, velocity: DVec3, heading_deg: f64) -> (f64, f64, f64) {
        let (s, c) = heading_deg.to_radians().sin_cos();
        let forward = velocity.x * s + velocity.y * c;
        let right = velocity.x * c - velocity.y * s;
        let vertical = if velocity.z >= 0.0 {
            velocity.z / self.vel_up
        } else {
            velocity.z / self.vel_down
        };
        let xy =
            |v: f64| crate::study::pilot::fly::stick_for(v / self.vel_xy, self.dz, self.expo_xy);
        (
            xy(forward),
            xy(right),
            crate::study::pilot::fly::stick_for(vertical, self.dz, self.expo_z),
        )
    }
}

/// Fly `legs` on PX4 (SIH) until `duration_s` of its clock: the row's parameters and
/// MIS_TAKEOFF_ALT set over MAVLink, armed, AUTO takeoff, then Position mode with the sticks
/// (MANUAL_CONTROL at every position) asking for each leg's velocity: Position mode is where
/// PX4's Collision Prevention (CP_DIST) acts.
pub fn fly_px4(
    pilot: &mut Pilot,
    legs: &[Leg],
    params: &[(String, f64)],
    duration_s: f64,
    stop: &dyn Fn() -> bool,
) -> Result<Flown, PilotError> {
    let Some(first) = first_fix(pilot, stop)? else {
        return Ok(Flown::stopped());
    };
    // In lockstep the launcher set them at boot (PX4's MAVLink runs outside its lockstep: an
    // exchange over it is not on the clock).
    let map = if pilot.in_lockstep() {
        StickMap::from_params(params)
    } else {
        for (name, value) in params {
            pilot.set_param(name, *value, stop)?;
        }
        if let Some(up_m) = takeoff_m(legs) {
            pilot.set_param("MIS_TAKEOFF_ALT", up_m, stop)?;
        }
        StickMap::read(pilot, stop)?
    };
    let mut steer = Steer::Sticks {
        map,
        position_mode_taken: false,
        asked_ms: first.time_boot_ms,
        took_over: false,
    };
    fly_legs(pilot, legs, first, duration_s, &mut steer, stop)
}

/// The height of a plan's (first) takeoff, metres: PX4's MIS_TAKEOFF_ALT for it.
pub fn takeoff_m(legs: &[Leg]) -> Option<f64> {
    legs.iter().find_map(|l| match l {
        Leg::Takeoff { up_m } => Some(*up_m),
        _ => None,
    })
}

/// What a PX4 leg sends once, at its start: AUTO takeoff (to MIS_TAKEOFF_ALT), or land.
fn start_leg_px4(pilot: &mut Pilot, leg: &Leg) -> Result<(), PilotError> {
    let nan = f32::NAN;
    match leg {
        Leg::Takeoff { .. } => pilot.command(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [nan, 0.0, 0.0, nan, nan, nan, nan],
        ),
        Leg::Land => pilot.command(
            MavCmd::MAV_CMD_NAV_LAND,
            [0.0, 0.0, 0.0, nan, nan, nan, nan],
        ),
        _ => Ok(()),
    }
}

/// The stick (-1..1) that makes PX4's Position mode ask for `fraction` (-1..1) of its
/// maximum, through its deadzone `dz` (MPC_HOLD_DZ) and expo `e` (MPC_XY_MAN_EXPO):
/// PX4 maps a stick `s` to `expo(deadzone(s))`, `deadzone(s) = (|s| - dz) / (1 - dz)`,
/// `expo(u) = (1 - e) u + e u^3`; this inverts it (Newton on the cubic).
///
/// ```
/// use savsim::study::pilot::fly::stick_for;
/// let s = stick_for(0.5, 0.1, 0.6);
/// let u = (s - 0.1) / 0.9;
/// assert!(((1.0 - 0.6) * u + 0.6 * u * u * u - 0.5).abs() < 1e-9);
/// assert_eq!(stick_for(0.0, 0.1, 0.6), 0.0);
/// ```
pub fn stick_for(fraction: f64, dz: f64, e: f64) -> f64 {
    let f = fraction.clamp(-1.0, 1.0);
    if f == 0.0 {
        return 0.0;
    }
    let target = f.abs();
    let mut u = target;
    for _ in 0..50 {
        let value = (1.0 - e) * u + e * u * u * u - target;
        let slope = (1.0 - e) + 3.0 * e * u * u;
        if slope.abs() < 1e-12 {
            break;
        }
        u = (u - value / slope).clamp(0.0, 1.0);
    }
    f.signum() * (u * (1.0 - dz) + dz).min(1.0)
}

/// The velocity a `goto` commands from `at` towards `to` at `speed_mps`, slowing within two
/// seconds of the point (at most half the distance per second), scene ENU m/s.
///
/// ```
/// use glam::DVec3;
/// let v = savsim::study::pilot::fly::goto_velocity(DVec3::ZERO, DVec3::new(100.0, 0.0, 0.0), 5.0);
/// assert_eq!(v, DVec3::new(5.0, 0.0, 0.0));
/// let near = savsim::study::pilot::fly::goto_velocity(DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0), 5.0);
/// assert_eq!(near, DVec3::new(1.0, 0.0, 0.0));
/// ```
pub fn goto_velocity(at: DVec3, to: DVec3, speed_mps: f64) -> DVec3 {
    let away = to - at;
    let distance = away.length();
    if distance < 1e-6 {
        return DVec3::ZERO;
    }
    away / distance * speed_mps.min(0.5 * distance)
}

/// Whether `leg` is done at `fix`, given where and when it began (a takeoff's height is
/// above where it began: home).
pub fn leg_done(leg: &Leg, fix: &Fix, began: &Fix, armed: bool) -> bool {
    let elapsed_s = f64::from(fix.time_boot_ms.wrapping_sub(began.time_boot_ms)) / 1000.0;
    match *leg {
        Leg::Takeoff { up_m } => fix.enu_m.z - began.enu_m.z >= up_m - TAKEOFF_DONE_M,
        Leg::Goto { enu_m, .. } => fix.enu_m.distance(DVec3::from(enu_m)) <= GOTO_DONE_M,
        Leg::Velocity { seconds, .. } | Leg::Hold { seconds } => elapsed_s >= seconds,
        Leg::Until { t_s } => fix.row_s >= t_s,
        Leg::Land => !armed && elapsed_s > 1.0,
    }
}
