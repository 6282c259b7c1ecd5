//! How one autopilot is in the loop: each step its outputs are taken (it has computed them and
//! now waits), and its new state is sent back (its clock moves on). One implementation per
//! protocol: ArduPilot's JSON backend ([`ArduPilotJson`]), PX4's simulator_mavlink
//! ([`super::px4::Px4Mavlink`]).

use std::time::Duration;

use super::json::{write_reply, JsonClock};
use super::port::{JsonPort, PortError, Servo};
use super::vehicle::SimVehicle;

/// An autopilot's outputs for a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outputs {
    /// Each output, 0..1, by output number.
    pub values: [f64; 32],
    /// Armed: an armed rotor turns at least at its idle.
    pub armed: bool,
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs {
            values: [0.0; 32],
            armed: false,
        }
    }
}

/// One autopilot's protocol in the loop.
pub trait Backend: Send {
    /// Wait (at most `silence` of wall time) for the autopilot's outputs for the step.
    fn take_outputs(
        &mut self,
        vehicle: &SimVehicle,
        silence: Duration,
    ) -> Result<Outputs, PortError>;
    /// Send the autopilot `vehicle`'s state at `time_us` of the clock.
    fn send_state(&mut self, time_us: u64, vehicle: &SimVehicle) -> Result<(), PortError>;
    /// The port it is reached on (its physics port).
    fn port(&self) -> u16;
}

/// ArduPilot SITL's JSON backend: a servo packet in, the state as JSON out.
#[derive(Debug)]
pub struct ArduPilotJson {
    json: JsonPort,
    clock: JsonClock,
    reply: String,
}

impl ArduPilotJson {
    /// On `json` (bound).
    pub fn new(json: JsonPort) -> Self {
        ArduPilotJson {
            json,
            clock: JsonClock::default(),
            reply: String::new(),
        }
    }
}

impl Backend for ArduPilotJson {
    /// The next servo packet (a re-sent one answered with the same reply again); PWM to 0..1
    /// through the frame's PWM range. ArduPilot's PWM says everything: always armed.
    fn take_outputs(
        &mut self,
        vehicle: &SimVehicle,
        silence: Duration,
    ) -> Result<Outputs, PortError> {
        loop {
            match self.json.recv(silence)? {
                Servo::New(packet) => {
                    let mut outputs = Outputs {
                        armed: true,
                        ..Outputs::default()
                    };
                    for (out, pwm) in outputs.values.iter_mut().zip(packet.pwm_us) {
                        *out = vehicle.frame.command_from_pwm_us(f64::from(pwm));
                    }
                    return Ok(outputs);
                }
                Servo::Repeat => self.json.reply(&self.reply)?,
            }
        }
    }

    fn send_state(&mut self, time_us: u64, vehicle: &SimVehicle) -> Result<(), PortError> {
        let t = self.clock.timestamp_for(time_us);
        write_reply(&mut self.reply, t, &vehicle.body, &vehicle.imu, &[]);
        self.json.reply(&self.reply)
    }

    fn port(&self) -> u16 {
        self.json.port()
    }
}
