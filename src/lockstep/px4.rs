//! PX4's simulator_mavlink in the loop (`PX4_SIM_MODEL=none_iris`): PX4 connects to TCP
//! `4560 + N`; savsim sends HIL_SENSOR every step (its `time_usec` is PX4's clock) and HIL_GPS
//! at 10 Hz, and PX4 answers each HIL_SENSOR with HIL_ACTUATOR_CONTROLS (docs/lockstep.md).

use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{
    HilSensorUpdatedFlags, MavMessage, HIL_GPS_DATA, HIL_SENSOR_DATA,
};
use savsim_core::dynamics::{air, GRAVITY_MPS2};

use super::backend::{Backend, Outputs};
use super::hil_noise::HilNoise;
use super::port::PortError;
use super::vehicle::SimVehicle;
use crate::codec::frame::FrameStatus;
use crate::codec::outbox::Outbox;
use crate::geo::LocalTangentPlane;
use crate::links::stream::StreamFramer;
use crate::world::SenderId;

/// PX4 SITL instance `instance`'s simulator port.
pub fn simulator_port(instance: u16) -> u16 {
    4560u16.saturating_add(instance)
}

/// How long PX4 may take to answer a HIL_SENSOR before it has answered any (while it boots its
/// modules do not run yet: the loop goes on without its outputs), wall time.
const BOOT_WAIT: Duration = Duration::from_millis(20);
/// HIL_GPS every this many microseconds of the clock.
const GPS_EVERY_US: u64 = 100_000;
/// Every HIL_SENSOR field: accelerometer, gyro, compass, pressures, altitude, temperature.
const ALL_FIELDS: u32 = 0x1FFF;

/// One PX4 on its simulator port.
pub struct Px4Mavlink {
    listener: TcpListener,
    stream: Option<TcpStream>,
    port: u16,
    framer: StreamFramer,
    outbox: Outbox,
    plane: LocalTangentPlane,
    /// The Earth's field at home, NED gauss (the world magnetic model's).
    field_ned_gauss: DVec3,
    answered: bool,
    last_gps_us: Option<u64>,
    buf: Vec<u8>,
    /// The compass's and barometer's noise (without it PX4 takes them for dead at rest).
    noise: HilNoise,
}

impl Px4Mavlink {
    /// Listen on 127.0.0.1:`port` for PX4; positions in `plane`, the compass reading the
    /// world magnetic model's field at `home`.
    pub fn bind(
        port: u16,
        plane: LocalTangentPlane,
        home: crate::geo::Geodetic,
    ) -> Result<Self, PortError> {
        let listener = TcpListener::bind(("127.0.0.1", port))
            .map_err(|source| PortError::Bind { port, source })?;
        Ok(Px4Mavlink {
            listener,
            stream: None,
            port,
            framer: StreamFramer::default(),
            outbox: Outbox::new(SenderId {
                system_id: 1,
                component_id: 51,
            }),
            plane,
            field_ned_gauss: earth_field_ned_gauss(home),
            answered: false,
            last_gps_us: None,
            buf: vec![0; 4096],
            noise: HilNoise::for_port(port),
        })
    }

    /// The connection, accepted within `wait`.
    fn stream(&mut self, wait: Duration) -> Result<&mut TcpStream, PortError> {
        if self.stream.is_none() {
            let port = self.port;
            let io = |source| PortError::Io { port, source };
            self.listener.set_nonblocking(true).map_err(io)?;
            let started = Instant::now();
            let stream = loop {
                match self.listener.accept() {
                    Ok((s, _)) => break s,
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                        if started.elapsed() > wait {
                            return Err(PortError::Silent {
                                port,
                                waited_s: wait.as_secs_f64(),
                            });
                        }
                        std::thread::sleep(Duration::from_millis(2));
                    }
                    Err(e) => return Err(io(e)),
                }
            };
            stream.set_nonblocking(false).map_err(io)?;
            let _ = stream.set_nodelay(true);
            self.stream = Some(stream);
        }
        self.stream.as_mut().ok_or(PortError::Silent {
            port: self.port,
            waited_s: 0.0,
        })
    }

    fn send(&mut self, message: &MavMessage) -> Result<(), PortError> {
        let bytes = self.outbox.encode(message);
        let port = self.port;
        let stream = self.stream(Duration::from_secs(20))?;
        std::io::Write::write_all(stream, &bytes).map_err(|source| PortError::Io { port, source })
    }
}

/// The Earth's magnetic field at `at`, NED gauss: the world magnetic model (WMM2025) on
/// 2026-07-01 (a fixed date: the same field every run). Where the model cannot say (outside its
/// range), a field of 0.5 gauss pointing north.
fn earth_field_ned_gauss(at: crate::geo::Geodetic) -> DVec3 {
    use world_magnetic_model::time::Date;
    use world_magnetic_model::uom::si::angle::degree;
    use world_magnetic_model::uom::si::f32::{Angle, Length};
    use world_magnetic_model::uom::si::length::meter;
    use world_magnetic_model::uom::si::magnetic_flux_density::gauss;
    let field = Date::from_ordinal_date(2026, 182).ok().and_then(|date| {
        world_magnetic_model::GeomagneticField::new(
            Length::new::<meter>(at.alt_m as f32),
            Angle::new::<degree>(at.lat_deg as f32),
            Angle::new::<degree>(at.lon_deg as f32),
            date,
        )
        .ok()
    });
    match field {
        Some(f) => DVec3::new(
            f64::from(f.x().get::<gauss>()),
            f64::from(f.y().get::<gauss>()),
            f64::from(f.z().get::<gauss>()),
        ),
        None => DVec3::new(0.5, 0.0, 0.0),
    }
}

impl Backend for Px4Mavlink {
    /// The HIL_ACTUATOR_CONTROLS answering the last HIL_SENSOR: `controls` 0..1, armed by its
    /// mode's safety bit. Until PX4 has answered once (it is booting), at most
    /// [`BOOT_WAIT`] is waited and the outputs are zero, disarmed.
    fn take_outputs(
        &mut self,
        _vehicle: &SimVehicle,
        silence: Duration,
    ) -> Result<Outputs, PortError> {
        let wait = if self.answered { silence } else { BOOT_WAIT };
        let port = self.port;
        let started = Instant::now();
        // Accepting the connection is not the answer's wait: PX4 starts in its own time.
        self.stream(silence)?;
        loop {
            let left = wait.saturating_sub(started.elapsed());
            if left.is_zero() {
                if self.answered {
                    return Err(PortError::Silent {
                        port,
                        waited_s: wait.as_secs_f64(),
                    });
                }
                return Ok(Outputs::default());
            }
            let stream = self.stream.as_mut().ok_or(PortError::Silent {
                port,
                waited_s: 0.0,
            })?;
            let io = |source| PortError::Io { port, source };
            stream.set_read_timeout(Some(left)).map_err(io)?;
            let n = match stream.read(&mut self.buf) {
                Ok(0) => {
                    return Err(io(std::io::Error::new(
                        std::io::ErrorKind::UnexpectedEof,
                        "PX4 closed the simulator connection",
                    )))
                }
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue
                }
                Err(e) => return Err(io(e)),
            };
            let mut controls = None;
            self.framer.push(&self.buf[..n], |frame| {
                if frame.status != FrameStatus::Valid || frame.message_id != 93 {
                    return;
                }
                let mut reader = mavlink::MavlinkReader::new(frame.bytes);
                if let Ok((_, MavMessage::HIL_ACTUATOR_CONTROLS(c))) =
                    reader.read_any_message::<MavMessage>()
                {
                    controls = Some(c);
                }
            });
            if let Some(c) = controls {
                self.answered = true;
                let mut outputs = Outputs {
                    armed: c.mode.bits() & 128 != 0,
                    ..Outputs::default()
                };
                for (out, v) in outputs.values.iter_mut().zip(c.controls) {
                    *out = f64::from(v).clamp(0.0, 1.0);
                }
                return Ok(outputs);
            }
        }
    }

    fn send_state(&mut self, time_us: u64, vehicle: &SimVehicle) -> Result<(), PortError> {
        let body = &vehicle.body;
        let frd_from_ned = body.ned_from_frd.inverse();
        let mag = frd_from_ned * self.field_ned_gauss + self.noise.mag_gauss(time_us);
        let at = self.plane.geodetic_from_enu_m(vehicle.position_enu_m());
        let noise_pa = self.noise.baro_pa(time_us);
        let pressure_hpa = (air::pressure_pa(at.alt_m) + noise_pa) / 100.0;
        // The altitude the noisy pressure gives (PX4 reads the pressure, not this field).
        let pressure_alt_m = at.alt_m - noise_pa / (air::density_kgpm3(at.alt_m) * GRAVITY_MPS2);
        let (a, g) = (vehicle.imu.accel_frd_mps2, vehicle.imu.gyro_frd_radps);
        self.send(&MavMessage::HIL_SENSOR(HIL_SENSOR_DATA {
            time_usec: time_us,
            xacc: a.x as f32,
            yacc: a.y as f32,
            zacc: a.z as f32,
            xgyro: g.x as f32,
            ygyro: g.y as f32,
            zgyro: g.z as f32,
            xmag: mag.x as f32,
            ymag: mag.y as f32,
            zmag: mag.z as f32,
            abs_pressure: pressure_hpa as f32,
            diff_pressure: 0.0,
            pressure_alt: pressure_alt_m as f32,
            temperature: 25.0,
            fields_updated: HilSensorUpdatedFlags::from_bits_truncate(ALL_FIELDS),
            id: 0,
        }))?;
        if self
            .last_gps_us
            .is_none_or(|last| time_us >= last + GPS_EVERY_US)
        {
            self.last_gps_us = Some(time_us);
            let v = body.velocity_ned_mps;
            let ground_mps = v.truncate().length();
            let course_deg = v.y.atan2(v.x).to_degrees().rem_euclid(360.0);
            let cm = |mps: f64| (mps * 100.0).round().clamp(-32767.0, 32767.0) as i16;
            self.send(&MavMessage::HIL_GPS(HIL_GPS_DATA {
                time_usec: time_us,
                lat: (at.lat_deg * 1e7).round() as i32,
                lon: (at.lon_deg * 1e7).round() as i32,
                alt: (at.alt_m * 1000.0).round() as i32,
                eph: 100,
                epv: 100,
                vel: (ground_mps * 100.0).round().min(65534.0) as u16,
                vn: cm(v.x),
                ve: cm(v.y),
                vd: cm(v.z),
                cog: (course_deg * 100.0).round().min(35999.0) as u16,
                fix_type: 3,
                satellites_visible: 10,
                id: 0,
                yaw: 0,
            }))?;
        }
        Ok(())
    }

    fn port(&self) -> u16 {
        self.port
    }
}
