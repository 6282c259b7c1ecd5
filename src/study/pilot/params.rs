//! Reading and setting the autopilot's parameters (PARAM_REQUEST_READ, PARAM_SET, PARAM_VALUE
//! heard by the reader thread), before flight and while it flies.

use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{
    MavMessage, MavParamType, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
};

use crate::study::pilot::{Pilot, PilotError};

impl Pilot {
    /// PX4's parameter `name` as last heard: its value (as PX4 encodes it: an integer's bits in
    /// the float) and MAV_PARAM_TYPE.
    fn param_heard(&self, name: &str) -> Option<(f32, u8)> {
        let heard = self.heard.lock().ok()?;
        heard.params.get(name).copied()
    }

    /// Forget what was heard of parameter `name`, then send `set` (PARAM_SET: its value on the
    /// wire and type) or, without it, PARAM_REQUEST_READ: the next PARAM_VALUE of `name` heard
    /// is the answer, never an older one.
    fn ask_param(
        &mut self,
        name: &str,
        set: Option<(f32, MavParamType)>,
    ) -> Result<(), PilotError> {
        if let Ok(mut heard) = self.heard.lock() {
            heard.params.remove(name);
        }
        let (target_system, target_component) = (self.target.system_id, self.target.component_id);
        self.send(&match set {
            Some((param_value, param_type)) => MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value,
                target_system,
                target_component,
                param_id: name.into(),
                param_type,
            }),
            None => MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: -1,
                target_system,
                target_component,
                param_id: name.into(),
            }),
        })
    }

    /// Ask for parameter `name` and wait (on the vehicle's clock, at most `within_s`) for its
    /// value and type.
    pub fn read_param(
        &mut self,
        name: &str,
        within_s: f64,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<(f32, u8)>, PilotError> {
        let asked_ms = self.fix.map_or(0, |f| f.time_boot_ms);
        self.ask_param(name, None)?;
        while let Some(fix) = self.next_fix(stop)? {
            if let Some(v) = self.param_heard(name) {
                return Ok(Some(v));
            }
            if f64::from(fix.time_boot_ms.wrapping_sub(asked_ms)) / 1000.0 > within_s {
                return Ok(None);
            }
        }
        Ok(None)
    }

    /// Set PX4 parameter `name` to `value` in its own type (read first; an integer's bits travel
    /// in the float, as PX4 encodes them) and wait for PX4 to echo it. An error when PX4 does
    /// not know the parameter or does not take the value.
    pub fn set_param(
        &mut self,
        name: &str,
        value: f64,
        stop: &dyn Fn() -> bool,
    ) -> Result<(), PilotError> {
        let refused = |why: &str| PilotError::Param {
            name: name.to_owned(),
            why: why.to_owned(),
        };
        let Some((_, kind)) = self.read_param(name, 5.0, stop)? else {
            return Err(refused("PX4 did not answer for it (no such parameter?)"));
        };
        let (wire, param_type) = param_on_wire(value, kind);
        for _ in 0..3 {
            self.ask_param(name, Some((wire, param_type)))?;
            let Some((now, _)) = self.read_param(name, 2.0, stop)? else {
                continue;
            };
            if now.to_bits() == wire.to_bits() {
                return Ok(());
            }
        }
        Err(refused(&format!("PX4 did not take {value}")))
    }

    /// Set parameter `name` (its type read first) before the autopilot sends positions,
    /// waiting on the wall clock (at most `within` for each answer): for set-up before the
    /// row's flight, e.g. PX4 SIH's home altitude.
    pub fn set_param_before_flight(
        &mut self,
        name: &str,
        value: f64,
        within: Duration,
    ) -> Result<(), PilotError> {
        let refused = |why: String| PilotError::Param {
            name: name.to_owned(),
            why,
        };
        let ask = |pilot: &mut Pilot, set: Option<(f32, MavParamType)>| {
            pilot.ask_param(name, set)?;
            let started = Instant::now();
            while started.elapsed() < within {
                if let Some(v) = pilot.param_heard(name) {
                    return Ok(Some(v));
                }
                let _ = pilot.news.recv_timeout(Duration::from_millis(50));
            }
            Ok::<_, PilotError>(None)
        };
        let mut answer = None;
        for _ in 0..20 {
            answer = ask(self, None)?;
            if answer.is_some() {
                break;
            }
        }
        let Some((_, kind)) = answer else {
            return Err(refused("the autopilot did not answer for it".into()));
        };
        let (wire, param_type) = param_on_wire(value, kind);
        match ask(self, Some((wire, param_type)))? {
            Some((now, _)) if now.to_bits() == wire.to_bits() => Ok(()),
            _ => Err(refused(format!("the autopilot did not take {value}"))),
        }
    }
}

/// `value` as PARAM_SET carries it for a parameter of MAV_PARAM_TYPE `kind`: an INT32's bits
/// in the float (PX4 encodes parameters bytewise), anything else as a REAL32.
fn param_on_wire(value: f64, kind: u8) -> (f32, MavParamType) {
    if kind == MavParamType::MAV_PARAM_TYPE_INT32 as u8 {
        (
            f32::from_bits(value.round() as i32 as u32),
            MavParamType::MAV_PARAM_TYPE_INT32,
        )
    } else {
        (value as f32, MavParamType::MAV_PARAM_TYPE_REAL32)
    }
}
