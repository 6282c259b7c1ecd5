//! ArduPilot SITL's JSON physics backend, as bytes: the servo packet SITL sends at every
//! physics step, and the state savsim answers with (ArduPilot's
//! `libraries/SITL/examples/JSON/readme.md`; docs/lockstep.md).

use std::fmt::Write as _;

use savsim_core::dynamics::{Body, Imu};

/// The magic of a 16-channel servo packet.
pub const MAGIC_16: u16 = 18458;
/// The magic of a 32-channel servo packet (`SERVO_32_ENABLE`).
pub const MAGIC_32: u16 = 29569;

/// One servo packet: SITL's outputs at one physics step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoPacket {
    /// SITL's physics rate, Hz (what it asks; savsim keeps its own step).
    pub frame_rate_hz: u16,
    /// SITL's count of accepted replies: the same count again is a re-sent packet.
    pub frame_count: u32,
    /// PWM of each output, microseconds (16 or 32 of them; the rest 0).
    pub pwm_us: [u16; 32],
    /// How many outputs the packet carried (16 or 32).
    pub channels: usize,
}

/// Why a datagram is not a servo packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// Neither 40 bytes (16 channels) nor 72 (32).
    #[error("a servo packet of {0} bytes (40 or 72)")]
    Size(usize),
    /// The magic does not say 16 or 32 channels as the size does.
    #[error("a servo packet whose magic is {magic} for {size} bytes (18458 for 40, 29569 for 72)")]
    Magic {
        /// The magic read.
        magic: u16,
        /// The packet's size.
        size: usize,
    },
}

impl ServoPacket {
    /// Read one datagram (little-endian: u16 magic, u16 frame rate, u32 frame count, u16 PWM
    /// each channel).
    ///
    /// ```
    /// use savsim::lockstep::json::ServoPacket;
    /// let mut bytes = vec![0u8; 40];
    /// bytes[0..2].copy_from_slice(&18458u16.to_le_bytes());
    /// bytes[2..4].copy_from_slice(&400u16.to_le_bytes());
    /// bytes[4..8].copy_from_slice(&7u32.to_le_bytes());
    /// bytes[8..10].copy_from_slice(&1500u16.to_le_bytes());
    /// let p = ServoPacket::parse(&bytes).unwrap();
    /// assert_eq!((p.frame_rate_hz, p.frame_count, p.pwm_us[0], p.channels), (400, 7, 1500, 16));
    /// assert!(ServoPacket::parse(&bytes[..39]).is_err());
    /// ```
    pub fn parse(bytes: &[u8]) -> Result<ServoPacket, PacketError> {
        let channels = match bytes.len() {
            40 => 16,
            72 => 32,
            n => return Err(PacketError::Size(n)),
        };
        let u16_at = |at: usize| u16::from_le_bytes([bytes[at], bytes[at + 1]]);
        let magic = u16_at(0);
        let expected = if channels == 16 { MAGIC_16 } else { MAGIC_32 };
        if magic != expected {
            return Err(PacketError::Magic {
                magic,
                size: bytes.len(),
            });
        }
        let mut pwm_us = [0u16; 32];
        for (k, pwm) in pwm_us.iter_mut().take(channels).enumerate() {
            *pwm = u16_at(8 + 2 * k);
        }
        Ok(ServoPacket {
            frame_rate_hz: u16_at(2),
            frame_count: u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]),
            pwm_us,
            channels,
        })
    }
}

/// SITL's clock, mirrored: SITL adds each reply's `timestamp` less the last, times 10^6, to
/// its clock in whole microseconds (truncating), so a timestamp whose difference from the last
/// reads back a hair short loses a microsecond. [`JsonClock::timestamp_for`] gives the
/// timestamp that moves SITL's clock exactly to a microsecond savsim chose.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct JsonClock {
    last_us: u64,
    last_s: f64,
}

impl JsonClock {
    /// The timestamp (seconds) that moves SITL's clock from the last one sent to `time_us`
    /// (at least the last): the smallest double whose difference from the last, times 10^6
    /// in SITL's double arithmetic, is the microseconds between them or more.
    ///
    /// ```
    /// use savsim::lockstep::json::JsonClock;
    /// let mut clock = JsonClock::default();
    /// let mut sitl_us = 0u64;
    /// let mut last = 0.0f64;
    /// for k in 1..=200_000u64 {
    ///     let t = clock.timestamp_for(k * 2_500);
    ///     // SITL: time_now_us += (t - last) * 1e6, truncated.
    ///     sitl_us = (sitl_us as f64 + (t - last) * 1e6) as u64;
    ///     last = t;
    ///     assert_eq!(sitl_us, k * 2_500);
    /// }
    /// ```
    pub fn timestamp_for(&mut self, time_us: u64) -> f64 {
        let time_us = time_us.max(self.last_us);
        let delta_us = (time_us - self.last_us) as f64;
        let mut t = time_us as f64 / 1e6;
        while (t - self.last_s) * 1e6 < delta_us {
            t = t.next_up();
        }
        self.last_us = time_us;
        self.last_s = t;
        t
    }
}

/// Write the reply for `body` at `timestamp_s` ([`JsonClock::timestamp_for`]) into `out`
/// (cleared): one JSON object between newlines, compact (SITL's parser reads `"key":[` with
/// no space), every number as the shortest decimal that reads back to the same double, each
/// `rangefinders_m` reading as `rng_1`, `rng_2`, ... (None: left out).
///
/// ```
/// use savsim::lockstep::json::write_reply;
/// use savsim_core::dynamics::{presets::preset, Body, Imu};
/// let frame = preset("arducopter-quad").unwrap();
/// let body = Body::landed(&frame, 0.0, 0.0);
/// let imu = Imu { accel_frd_mps2: glam::DVec3::new(0.0, 0.0, -9.80665), gyro_frd_radps: glam::DVec3::ZERO };
/// let mut out = String::new();
/// write_reply(&mut out, 0.0025, &body, &imu, &[Some(4.5)]);
/// assert!(out.starts_with("\n{\"timestamp\":0.0025,"));
/// assert!(out.contains("\"accel_body\":[0,0,-9.80665]"));
/// assert!(out.contains("\"rng_1\":4.5") && out.ends_with("}\n"));
/// ```
pub fn write_reply(
    out: &mut String,
    timestamp_s: f64,
    body: &Body,
    imu: &Imu,
    rangefinders_m: &[Option<f64>],
) {
    out.clear();
    let v3 = |v: glam::DVec3| [v.x, v.y, v.z];
    let q = body.ned_from_frd;
    // Writing to a String cannot fail.
    let _ = write!(
        out,
        "\n{{\"timestamp\":{},\"imu\":{{\"gyro\":{},\"accel_body\":{}}},\
         \"position\":{},\"velocity\":{},\"quaternion\":[{},{},{},{}]",
        Num(timestamp_s),
        Triple(v3(imu.gyro_frd_radps)),
        Triple(v3(imu.accel_frd_mps2)),
        Triple(v3(body.position_ned_m)),
        Triple(v3(body.velocity_ned_mps)),
        Num(q.w),
        Num(q.x),
        Num(q.y),
        Num(q.z),
    );
    for (k, reading) in rangefinders_m.iter().enumerate().take(6) {
        if let Some(m) = reading {
            let _ = write!(out, ",\"rng_{}\":{}", k + 1, Num(*m));
        }
    }
    out.push_str("}\n");
}

/// A number as SITL's parser reads it: finite decimal (a non-finite one as 0: never sent, the
/// dynamics keep every state finite).
struct Num(f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.is_finite() {
            write!(f, "{}", self.0)
        } else {
            f.write_str("0")
        }
    }
}

struct Triple([f64; 3]);

impl std::fmt::Display for Triple {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [a, b, c] = self.0;
        write!(f, "[{},{},{}]", Num(a), Num(b), Num(c))
    }
}
