//! The companion protocol's messages (docs/companion.md): each is a 4-byte little-endian
//! length, a JSON header of that length, and the binary payload the header's `payload_bytes`
//! counts. savsim sends a `hello`, then a `frame` at each of the planner's instants (the
//! vehicle's state, its images and point clouds as arrays in the payload, the traffic it was
//! told); the planner answers each frame with `commands`. Pure: bytes in, bytes out.

use std::sync::Arc;

use glam::DVec3;
use serde::Deserialize;
use serde_json::{json, Value};

use crate::feed::capture::{Capture, CaptureData};
use crate::feed::AdsbSent;

/// The protocol's version, in `hello`.
pub const VERSION: u32 = 1;
/// The largest reply header a planner may send, bytes.
pub const MAX_REPLY_HEADER: usize = 1 << 20;
/// The largest reply payload (MAVLink frames), bytes.
pub const MAX_REPLY_PAYLOAD: usize = 1 << 16;
/// The most commands in one reply.
pub const MAX_COMMANDS: usize = 64;

/// A vehicle's state as the planner is told it: scene ENU metres and metres a second, its
/// attitude in degrees (roll, pitch, yaw clockwise from north).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Position, scene ENU metres.
    pub position_enu_m: DVec3,
    /// Velocity, ENU m/s.
    pub velocity_enu_mps: DVec3,
    /// Roll, pitch, yaw (clockwise from north), degrees.
    pub attitude_deg: [f64; 3],
}

/// Whose clock a planner runs on, as `hello` says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// savsim's lockstep clock: each frame waits for the planner; `truth` is savsim's own
    /// vehicle dynamics.
    Lockstep,
    /// The vehicle's own clock, running in wall time (SITL's physics, a live vehicle): frames
    /// are not waited for; `truth` is what savsim mirrors, the autopilot's own report.
    Wall,
}

impl Clock {
    /// Its name in `hello`.
    pub fn name(self) -> &'static str {
        match self {
            Clock::Lockstep => "lockstep",
            Clock::Wall => "wall",
        }
    }
}

/// What one frame tells the planner.
#[derive(Debug, Clone)]
pub struct FrameOut<'a> {
    /// The frame's number (from 0), which its reply names.
    pub seq: u64,
    /// The vehicle's clock, seconds.
    pub t_s: f64,
    /// The truth (marked as such).
    pub truth: State,
    /// The autopilot's own estimate of its position, scene ENU metres, and its age, seconds
    /// (none before the autopilot sent one).
    pub estimate: Option<(DVec3, f64)>,
    /// What the row's plan asks of the vehicle now: a velocity, ENU m/s (none while taking
    /// off or landing).
    pub intent_enu_mps: Option<DVec3>,
    /// Each device's newest image or cloud.
    pub captures: &'a [Arc<Capture>],
    /// The ADS-B reports it was sent since the last frame.
    pub traffic: &'a [AdsbSent],
}

/// A command from the planner.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// Fly this velocity (ENU m/s), facing `yaw_deg` (clockwise from north) when given.
    Velocity {
        /// Velocity, ENU m/s.
        enu_mps: DVec3,
        /// Heading, degrees clockwise from north.
        yaw_deg: Option<f64>,
    },
    /// Change to this flight mode (the autopilot's name for it).
    Mode(String),
    /// Send these bytes: one or more whole MAVLink frames as the planner made them.
    Mavlink(Vec<u8>),
}

/// Why a reply cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplyError {
    /// Not the JSON the protocol asks for.
    #[error("a reply that is not the protocol's JSON: {0}")]
    Json(String),
    /// A reply to another frame.
    #[error("a reply to frame {got} when frame {want} was asked")]
    Sequence {
        /// The frame it names.
        got: u64,
        /// The frame asked.
        want: u64,
    },
    /// A command that is not one.
    #[error("command {index}: {why}")]
    Command {
        /// Its place in the reply.
        index: usize,
        /// What is wrong.
        why: String,
    },
    /// More than the protocol allows.
    #[error("{0}")]
    TooMuch(String),
}

/// `header` and `payload` as one message: the length, the header, the payload.
pub fn message(header: &Value, payload: &[u8], out: &mut Vec<u8>) {
    let text = header.to_string();
    out.clear();
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    out.extend_from_slice(payload);
}

/// What `hello` tells the planner.
#[derive(Debug, Clone, Copy)]
pub struct Hello<'a> {
    /// The vehicle's system id.
    pub system_id: u8,
    /// Whether it is PX4 (else ArduPilot): whose mode names its `mode` commands use.
    pub px4: bool,
    /// Its devices' names.
    pub devices: &'a [String],
    /// The planner's instants a second of the vehicle's clock.
    pub hz: f64,
    /// Its modelled latency, seconds of the clock.
    pub latency_s: f64,
    /// Whose clock it runs on.
    pub clock: Clock,
}

/// The `hello` savsim sends first: the protocol's version, the vehicle and its autopilot, its
/// devices, the planner's rate, latency and clock.
pub fn hello(h: &Hello<'_>) -> Value {
    json!({
        "type": "hello",
        "version": VERSION,
        "system_id": h.system_id,
        "autopilot": if h.px4 { "px4" } else { "ardupilot" },
        "devices": h.devices,
        "hz": h.hz,
        "latency_s": h.latency_s,
        "clock": h.clock.name(),
        "payload_bytes": 0,
    })
}

fn state(s: &State) -> Value {
    json!({
        "position_enu_m": s.position_enu_m.to_array(),
        "velocity_enu_mps": s.velocity_enu_mps.to_array(),
        "attitude_deg": s.attitude_deg,
    })
}

/// An array in the payload: its name, element type (numpy's spelling), shape, and where;
/// `write` appends its bytes to the payload (once, straight from the reading).
fn array(
    (name, dtype, shape): (&str, &str, &[usize]),
    payload: &mut Vec<u8>,
    write: impl FnOnce(&mut Vec<u8>),
) -> Value {
    let offset = payload.len();
    write(payload);
    let bytes = payload.len() - offset;
    json!({ "name": name, "dtype": dtype, "shape": shape, "offset": offset, "bytes": bytes })
}

fn f32s(v: &[f32]) -> impl FnOnce(&mut Vec<u8>) + '_ {
    move |p| p.extend(v.iter().flat_map(|x| x.to_le_bytes()))
}

fn u32s(v: &[u32]) -> impl FnOnce(&mut Vec<u8>) + '_ {
    move |p| p.extend(v.iter().flat_map(|x| x.to_le_bytes()))
}

fn u8s(v: &[u8]) -> impl FnOnce(&mut Vec<u8>) + '_ {
    move |p| p.extend_from_slice(v)
}

fn capture(c: &Capture, payload: &mut Vec<u8>) -> Value {
    let q = c.enu_from_device;
    let (kind, extra, arrays) = match &c.data {
        CaptureData::Depth { image, fov_deg } => {
            let shape = [image.height_px as usize, image.width_px as usize];
            let arrays = vec![
                array(("depth_m", "<f4", &shape), payload, f32s(&image.depth_m)),
                array(
                    ("segment_id", "<u4", &shape),
                    payload,
                    u32s(&image.segment_id),
                ),
                array(("class", "|u1", &shape), payload, u8s(&image.class)),
            ];
            ("depth", json!({ "fov_deg": fov_deg }), arrays)
        }
        CaptureData::Points(cloud) => {
            let n = cloud.points_m.len();
            let points = cloud.points_m.as_flattened();
            let arrays = vec![
                array(("points_m", "<f4", &[n, 3]), payload, f32s(points)),
                array(
                    ("segment_id", "<u4", &[n]),
                    payload,
                    u32s(&cloud.segment_id),
                ),
                array(("class", "|u1", &[n]), payload, u8s(&cloud.class)),
            ];
            ("points", json!({}), arrays)
        }
    };
    json!({
        "device": c.device,
        "kind": kind,
        "instant_s": c.instant_s,
        "origin_enu_m": c.origin_enu_m.to_array(),
        "enu_from_device_xyzw": [q.x, q.y, q.z, q.w],
        "extra": extra,
        "arrays": arrays,
    })
}

/// A frame as a message into `out` (`payload` is scratch).
pub fn frame(f: &FrameOut<'_>, payload: &mut Vec<u8>, out: &mut Vec<u8>) {
    payload.clear();
    let captures: Vec<Value> = f.captures.iter().map(|c| capture(c, payload)).collect();
    let traffic: Vec<Value> = f
        .traffic
        .iter()
        .map(|t| {
            json!({
                "icao_address": t.icao_address,
                "label": t.label,
                "position_enu_m": t.position_enu_m.to_array(),
            })
        })
        .collect();
    let header = json!({
        "type": "frame",
        "seq": f.seq,
        "t_s": f.t_s,
        "truth": state(&f.truth),
        "estimate": f.estimate.map(|(p, age)| json!({
            "position_enu_m": p.to_array(),
            "age_s": age,
        })),
        "intent_enu_mps": f.intent_enu_mps.map(|v| v.to_array()),
        "captures": captures,
        "traffic": traffic,
        "payload_bytes": payload.len(),
    });
    message(&header, payload, out);
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Reply {
    #[serde(rename = "type")]
    kind: String,
    seq: u64,
    #[serde(default)]
    commands: Vec<Value>,
    #[serde(default)]
    payload_bytes: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Span {
    offset: usize,
    bytes: usize,
}

/// The payload's length a reply header announces (checked before it is read).
pub fn reply_payload_len(header: &[u8]) -> Result<usize, ReplyError> {
    let reply: Reply =
        serde_json::from_slice(header).map_err(|e| ReplyError::Json(e.to_string()))?;
    if reply.payload_bytes > MAX_REPLY_PAYLOAD {
        return Err(ReplyError::TooMuch(format!(
            "a payload of {} bytes: at most {MAX_REPLY_PAYLOAD}",
            reply.payload_bytes
        )));
    }
    Ok(reply.payload_bytes)
}

/// The commands of a reply to frame `seq`.
///
/// ```
/// use savsim::companion::protocol::{commands, Command};
/// let header = br#"{"type": "commands", "seq": 3, "commands": [
///     {"velocity_enu_mps": [1.0, 2.0, 0.0], "yaw_deg": 90.0}, {"mode": "GUIDED"}]}"#;
/// let got = commands(header, &[], 3).unwrap();
/// assert_eq!(got[1], Command::Mode("GUIDED".into()));
/// assert!(commands(header, &[], 4).is_err());
/// assert!(commands(br#"{"type": "commands", "seq": 3, "commands": [{"fly": 1}]}"#, &[], 3).is_err());
/// ```
pub fn commands(header: &[u8], payload: &[u8], seq: u64) -> Result<Vec<Command>, ReplyError> {
    let reply: Reply =
        serde_json::from_slice(header).map_err(|e| ReplyError::Json(e.to_string()))?;
    if reply.kind != "commands" {
        return Err(ReplyError::Json(format!(
            "type {:?}: a reply is of type \"commands\"",
            reply.kind
        )));
    }
    if reply.seq != seq {
        return Err(ReplyError::Sequence {
            got: reply.seq,
            want: seq,
        });
    }
    if reply.commands.len() > MAX_COMMANDS {
        return Err(ReplyError::TooMuch(format!(
            "{} commands in one reply: at most {MAX_COMMANDS}",
            reply.commands.len()
        )));
    }
    reply
        .commands
        .iter()
        .enumerate()
        .map(|(index, c)| command(c, payload).map_err(|why| ReplyError::Command { index, why }))
        .collect()
}

fn command(c: &Value, payload: &[u8]) -> Result<Command, String> {
    let obj = c.as_object().ok_or("not an object")?;
    let finite = |v: &Value| v.as_f64().filter(|x| x.is_finite());
    if let Some(v) = obj.get("velocity_enu_mps") {
        let xs: Vec<f64> = v
            .as_array()
            .filter(|a| a.len() == 3)
            .and_then(|a| a.iter().map(finite).collect())
            .ok_or("velocity_enu_mps: give three finite numbers")?;
        let enu_mps = DVec3::new(xs[0], xs[1], xs[2]);
        if enu_mps.length() > 100.0 {
            return Err(format!(
                "velocity_enu_mps: {:.1} m/s, at most 100",
                enu_mps.length()
            ));
        }
        let yaw_deg = match obj.get("yaw_deg") {
            None | Some(Value::Null) => None,
            Some(y) => Some(finite(y).ok_or("yaw_deg: give a finite number")?),
        };
        return only(obj, &["velocity_enu_mps", "yaw_deg"])
            .map(|()| Command::Velocity { enu_mps, yaw_deg });
    }
    if let Some(m) = obj.get("mode") {
        let name = m.as_str().filter(|s| !s.is_empty() && s.len() <= 32);
        let name = name.ok_or("mode: give the mode's name")?;
        return only(obj, &["mode"]).map(|()| Command::Mode(name.to_string()));
    }
    if let Some(span) = obj.get("mavlink") {
        let span: Span = serde_json::from_value(span.clone())
            .map_err(|e| format!("mavlink: {e} (give offset and bytes in the payload)"))?;
        let bytes = span
            .offset
            .checked_add(span.bytes)
            .and_then(|end| payload.get(span.offset..end))
            .ok_or("mavlink: beyond the payload")?;
        return only(obj, &["mavlink"]).map(|()| Command::Mavlink(bytes.to_vec()));
    }
    Err("give velocity_enu_mps, mode or mavlink".into())
}

fn only(obj: &serde_json::Map<String, Value>, keys: &[&str]) -> Result<(), String> {
    match obj.keys().find(|k| !keys.contains(&k.as_str())) {
        Some(k) => Err(format!("{k:?} is not a field of this command")),
        None => Ok(()),
    }
}
