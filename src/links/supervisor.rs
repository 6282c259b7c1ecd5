//! Per-vehicle link state, kept the way a MAVLink router keeps it: where each autopilot was
//! last heard (link and address), what it was asked for and what it answered, and when to ask
//! again. Pure: frames and receive times in, addressed messages out; the sockets are in
//! [`crate::links::sockets`], the wiring in `app`.
//!
//! - **Routing.** Every frame updates its sender's endpoint, so a link may carry many systems
//!   and each vehicle's replies (requests, later the sensor feed) go where it was last heard.
//!   The GCS heartbeat goes once a second to every fixed endpoint (udpout, TCP) and to every
//!   address heard in the last [`SupervisorConfig::endpoint_quiet_s`].
//! - **Autopilots only.** Streams are asked only of senders whose HEARTBEAT names a vehicle and
//!   an autopilot ([`HeartbeatReport::is_autopilot`]); a forwarded companion computer or GCS is
//!   never asked. Each message is asked on its own (COMMAND_ACK does not say which message it
//!   answers, so one request is outstanding per vehicle); REQUEST_DATA_STREAM is the fallback
//!   for ArduPilot only, after SET_MESSAGE_INTERVAL went unanswered.
//! - **Supervision.** A stream whose messages stop for [`SupervisorConfig::stale_periods`]
//!   periods (at least [`SupervisorConfig::stale_min_s`]) while the vehicle's heartbeats go on
//!   is asked again; a reboot (`time_boot_ms` going back) or a return after a heartbeat silence
//!   asks for everything again. A reboot is reported to the caller, which restarts that
//!   sender's sequence bookkeeping.

use std::collections::BTreeMap;
use std::net::SocketAddr;

use mavlink::dialects::ardupilotmega::{
    MavCmd, MavMessage, MavResult, COMMAND_ACK_DATA, COMMAND_LONG_DATA,
};
// REQUEST_DATA_STREAM is deprecated, and is exactly the fallback older ArduPilot needs.
#[allow(deprecated)]
use mavlink::dialects::ardupilotmega::{MavDataStream, REQUEST_DATA_STREAM_DATA};
use mavlink::MessageData;
use serde::Serialize;

use crate::codec::decode::{
    heartbeat_from, heartbeat_names, ID_ATTITUDE, ID_GLOBAL_POSITION_INT, ID_HEARTBEAT,
};
use crate::codec::frame::{message_info, FrameStatus, RawFrame};
use crate::codec::outbox::gcs_heartbeat;
use crate::world::clock::{self, ClockStep};
use crate::world::inputs::HeartbeatReport;
use crate::world::SenderId;

/// Index of a link among those a run opened (the order of `--connect`).
pub type LinkId = u16;

/// Where a frame came from and where a reply goes: a link, and on a UDP link the peer's address
/// (`None` on a TCP link, whose peer is the connection).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Endpoint {
    /// The link.
    pub link: LinkId,
    /// The peer on that link.
    pub peer: Option<SocketAddr>,
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.peer {
            Some(peer) => write!(f, "link {} ({peer})", self.link),
            None => write!(f, "link {}", self.link),
        }
    }
}

/// savsim's identity as a ground station by default: system 245, component 190
/// (MAV_COMP_ID_MISSIONPLANNER). Not system 255, which QGroundControl (255/190), Mission
/// Planner (255/190) and MAVProxy (255/230) use and which ArduPilot takes for its own GCS
/// (`SYSID_MYGCS`: its heartbeat would hold off the GCS failsafe while the real station is
/// gone); not 0 (broadcast) and not a vehicle's (1 and up in swarms). `--sysid`/`--compid`
/// set another.
pub const DEFAULT_GCS: SenderId = SenderId {
    system_id: 245,
    component_id: 190,
};

/// How the supervisor asks and when it asks again.
#[derive(Debug, Clone, PartialEq)]
pub struct SupervisorConfig {
    /// savsim's own identity as a GCS.
    pub gcs: SenderId,
    /// Rate asked for each message, Hz.
    pub rate_hz: f64,
    /// Messages asked for: GLOBAL_POSITION_INT and ATTITUDE.
    pub messages: Vec<u32>,
    /// A request with no COMMAND_ACK after this long is sent again, s.
    pub answer_timeout_s: f64,
    /// SET_MESSAGE_INTERVAL attempts per message before it counts as unanswered.
    pub attempts: u8,
    /// A vehicle whose heartbeat is older than this is not asked anything (it is away), s.
    pub alive_s: f64,
    /// A heartbeat after a silence this long asks for everything again, s.
    pub return_after_s: f64,
    /// A stream is stale after this many of its periods without a message...
    pub stale_periods: f64,
    /// ... and at least this long, s.
    pub stale_min_s: f64,
    /// A heard address gets heartbeats until it has been quiet this long, s.
    pub endpoint_quiet_s: f64,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self {
            gcs: DEFAULT_GCS,
            rate_hz: 20.0,
            messages: vec![ID_GLOBAL_POSITION_INT, ID_ATTITUDE],
            answer_timeout_s: 1.0,
            attempts: 3,
            alive_s: 3.0,
            return_after_s: 3.0,
            stale_periods: 5.0,
            stale_min_s: 2.0,
            endpoint_quiet_s: 10.0,
        }
    }
}

/// Where one message's request stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RequestState {
    /// To be asked (again).
    Pending,
    /// Accepted by COMMAND_ACK.
    Accepted,
    /// Refused by COMMAND_ACK (denied, unsupported, failed); not asked again until a reboot.
    Refused,
    /// No answer after every attempt.
    Unanswered,
}

#[derive(Debug, Clone)]
struct Stream {
    message_id: u32,
    state: RequestState,
    attempts: u8,
    /// When the state last changed.
    since_t_s: f64,
    last_message_t_s: Option<f64>,
}

impl Stream {
    /// To be asked again from `t_s`, with every attempt.
    fn ask_again(&mut self, t_s: f64) {
        self.state = RequestState::Pending;
        self.attempts = 0;
        self.since_t_s = t_s;
    }
}

/// What the supervisor knows of one autopilot.
#[derive(Debug, Clone)]
struct Autopilot {
    endpoint: Endpoint,
    heartbeat: HeartbeatReport,
    last_heartbeat_t_s: f64,
    last_time_boot_ms: Option<u32>,
    streams: Vec<Stream>,
    /// The stream whose request awaits its COMMAND_ACK, and when it was sent.
    outstanding: Option<(usize, f64)>,
    fallback_sent: bool,
    reboots: u64,
    returns: u64,
    re_requests: u64,
}

impl Autopilot {
    fn ask_again(&mut self, t_s: f64) {
        for stream in &mut self.streams {
            stream.ask_again(t_s);
        }
        self.outstanding = None;
        self.fallback_sent = false;
    }
}

/// What one frame told the caller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Observed {
    /// The sender is an autopilot that rebooted: restart its sequence bookkeeping.
    pub rebooted: bool,
}

/// Counters over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SupervisorCounts {
    /// SET_MESSAGE_INTERVAL commands sent.
    pub interval_requests: u64,
    /// REQUEST_DATA_STREAM fallbacks sent (each covers position and attitude).
    pub stream_requests: u64,
    /// Times a stale stream was asked for again.
    pub re_requests: u64,
    /// Reboots seen (`time_boot_ms` going back).
    pub reboots: u64,
    /// Requests refused by COMMAND_ACK.
    pub refused: u64,
    /// Requests that got no answer after every attempt.
    pub unanswered: u64,
    /// GCS heartbeats sent (one per endpoint per second).
    pub heartbeats: u64,
}

/// One vehicle's link state, as the summary reports it.
#[derive(Debug, Clone, Serialize)]
pub struct VehicleLink {
    /// "sysid/compid".
    pub vehicle: String,
    /// Where it was last heard.
    pub endpoint: String,
    /// MAV_AUTOPILOT as the heartbeat names it.
    pub autopilot: String,
    /// MAV_TYPE.
    pub vehicle_type: String,
    /// Per message asked for: where its request stands.
    pub streams: BTreeMap<&'static str, RequestState>,
    /// Reboots seen.
    pub reboots: u64,
    /// Returns after a heartbeat silence.
    pub returns: u64,
    /// Stale streams asked again.
    pub re_requests: u64,
}

/// Routing, requests and supervision for every vehicle on every link.
#[derive(Debug, Clone)]
pub struct Supervisor {
    config: SupervisorConfig,
    autopilots: BTreeMap<SenderId, Autopilot>,
    /// Endpoints that always get the heartbeat (udpout, TCP).
    fixed: Vec<Endpoint>,
    /// Addresses heard, with the last time.
    heard: BTreeMap<Endpoint, f64>,
    next_heartbeat_t_s: f64,
    /// Counters.
    pub counts: SupervisorCounts,
}

/// Reads a little-endian field of a payload that MAVLink 2 may have truncated (trailing zeros).
fn field<const N: usize>(payload: &[u8], offset: usize) -> [u8; N] {
    let mut out = [0u8; N];
    for (i, b) in out.iter_mut().enumerate() {
        *b = payload.get(offset + i).copied().unwrap_or(0);
    }
    out
}

impl Supervisor {
    /// A supervisor with no vehicles yet.
    pub fn new(config: SupervisorConfig) -> Self {
        Self {
            config,
            autopilots: BTreeMap::new(),
            fixed: Vec::new(),
            heard: BTreeMap::new(),
            next_heartbeat_t_s: f64::NEG_INFINITY,
            counts: SupervisorCounts::default(),
        }
    }

    /// An endpoint that gets the heartbeat whether or not anything was heard on it (udpout's
    /// address, a TCP connection): the vehicle may wait to hear a GCS first.
    pub fn add_fixed(&mut self, endpoint: Endpoint) {
        if !self.fixed.contains(&endpoint) {
            self.fixed.push(endpoint);
        }
    }

    /// The autopilots known, with where each was last heard.
    pub fn routes(&self) -> impl Iterator<Item = (SenderId, Endpoint)> + '_ {
        self.autopilots.iter().map(|(id, a)| (*id, a.endpoint))
    }

    /// Note one frame received from `from` at `t_s` (receive clock, seconds).
    pub fn observe(&mut self, from: Endpoint, t_s: f64, frame: &RawFrame<'_>) -> Observed {
        if frame.status != FrameStatus::Valid {
            return Observed::default();
        }
        let sender = SenderId {
            system_id: frame.system_id,
            component_id: frame.component_id,
        };
        if sender == self.config.gcs {
            // Our own messages echoed back by a router: not a sender to route to.
            return Observed::default();
        }
        self.heard.insert(from, t_s);
        if frame.message_id == ID_HEARTBEAT {
            self.heartbeat(sender, from, t_s, frame.payload);
            return Observed::default();
        }
        let Some(autopilot) = self.autopilots.get_mut(&sender) else {
            return Observed::default();
        };
        autopilot.endpoint = from;
        let mut observed = Observed::default();
        match frame.message_id {
            ID_GLOBAL_POSITION_INT | ID_ATTITUDE => {
                let time_boot_ms = u32::from_le_bytes(field(frame.payload, 0));
                let step = autopilot
                    .last_time_boot_ms
                    .map(|last| clock::step(last, time_boot_ms));
                if step != Some(ClockStep::Reordered) {
                    autopilot.last_time_boot_ms = Some(time_boot_ms);
                }
                if step == Some(ClockStep::Restart) {
                    autopilot.reboots += 1;
                    self.counts.reboots += 1;
                    autopilot.ask_again(t_s);
                    tracing::info!(
                        "vehicle {sender} rebooted (time_boot_ms went back): asking for its streams again"
                    );
                    observed.rebooted = true;
                }
                if let Some(stream) = autopilot
                    .streams
                    .iter_mut()
                    .find(|s| s.message_id == frame.message_id)
                {
                    stream.last_message_t_s = Some(t_s);
                }
            }
            COMMAND_ACK_DATA::ID => {
                let command = u16::from_le_bytes(field(frame.payload, 0));
                let result = frame.payload.get(2).copied().unwrap_or(0);
                // Its target (extension fields; 0 when truncated or broadcast): our system and
                // our component, so that another GCS's acknowledgement is not taken for ours.
                let target_system = frame.payload.get(8).copied().unwrap_or(0);
                let target_component = frame.payload.get(9).copied().unwrap_or(0);
                let ours = (target_system == 0 || target_system == self.config.gcs.system_id)
                    && (target_component == 0 || target_component == self.config.gcs.component_id);
                if ours && command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL as u16 {
                    self.answer(sender, t_s, result);
                }
            }
            _ => {}
        }
        observed
    }

    fn heartbeat(&mut self, sender: SenderId, from: Endpoint, t_s: f64, payload: &[u8]) {
        let report = heartbeat_from(payload);
        if !report.is_autopilot() {
            return;
        }
        let messages = &self.config.messages;
        let return_after_s = self.config.return_after_s;
        let autopilot = self.autopilots.entry(sender).or_insert_with(|| {
            let (mav_type, autopilot) = heartbeat_names(&report);
            tracing::info!("vehicle {sender} ({autopilot}, {mav_type}) heard on {from}");
            Autopilot {
                endpoint: from,
                heartbeat: report,
                last_heartbeat_t_s: t_s,
                last_time_boot_ms: None,
                streams: messages
                    .iter()
                    .map(|&message_id| Stream {
                        message_id,
                        state: RequestState::Pending,
                        attempts: 0,
                        since_t_s: t_s,
                        last_message_t_s: None,
                    })
                    .collect(),
                outstanding: None,
                fallback_sent: false,
                reboots: 0,
                returns: 0,
                re_requests: 0,
            }
        });
        if t_s - autopilot.last_heartbeat_t_s > return_after_s {
            autopilot.returns += 1;
            autopilot.ask_again(t_s);
            tracing::info!(
                "vehicle {sender} is back after {:.1} s of silence: asking for its streams again",
                t_s - autopilot.last_heartbeat_t_s
            );
        }
        autopilot.endpoint = from;
        autopilot.heartbeat = report;
        autopilot.last_heartbeat_t_s = autopilot.last_heartbeat_t_s.max(t_s);
    }

    fn answer(&mut self, sender: SenderId, t_s: f64, result: u8) {
        let Some(autopilot) = self.autopilots.get_mut(&sender) else {
            return;
        };
        let Some((index, _)) = autopilot.outstanding else {
            return;
        };
        let stream = &mut autopilot.streams[index];
        let name = message_info(stream.message_id).map_or("?", |m| m.name);
        use MavResult::*;
        let state = match result {
            r if r == MAV_RESULT_ACCEPTED as u8 => RequestState::Accepted,
            r if r == MAV_RESULT_DENIED as u8
                || r == MAV_RESULT_UNSUPPORTED as u8
                || r == MAV_RESULT_FAILED as u8 =>
            {
                self.counts.refused += 1;
                tracing::warn!(
                    "vehicle {sender} refused {name} at {} Hz",
                    self.config.rate_hz
                );
                RequestState::Refused
            }
            // Temporarily rejected, in progress: the timeout asks again.
            _ => return,
        };
        stream.state = state;
        stream.since_t_s = t_s;
        autopilot.outstanding = None;
    }

    /// The messages due at `t_s`: the GCS heartbeat once a second, and each vehicle's next
    /// request. Call it often (every 50-100 ms); it sends nothing twice.
    pub fn due(&mut self, t_s: f64) -> Vec<(Endpoint, MavMessage)> {
        let mut out = Vec::new();
        if t_s >= self.next_heartbeat_t_s {
            self.next_heartbeat_t_s = t_s + 1.0;
            let quiet_s = self.config.endpoint_quiet_s;
            self.heard.retain(|_, last| t_s - *last <= quiet_s);
            let mut endpoints: Vec<Endpoint> = self.fixed.clone();
            endpoints.extend(
                self.heard
                    .keys()
                    .copied()
                    .filter(|e| !self.fixed.contains(e)),
            );
            for endpoint in endpoints {
                self.counts.heartbeats += 1;
                out.push((endpoint, gcs_heartbeat()));
            }
        }
        let config = &self.config;
        let stale_s = (config.stale_periods / config.rate_hz).max(config.stale_min_s);
        for (&id, autopilot) in &mut self.autopilots {
            if t_s - autopilot.last_heartbeat_t_s > config.alive_s {
                continue;
            }
            let ardupilot = autopilot.heartbeat.autopilot == HeartbeatReport::AUTOPILOT_ARDUPILOT;
            // An unanswered ArduPilot stream waits for the fallback before it can be stale.
            let fallback_pending = ardupilot && !autopilot.fallback_sent;
            for stream in &mut autopilot.streams {
                let waiting = match stream.state {
                    RequestState::Accepted => true,
                    RequestState::Unanswered => !fallback_pending,
                    RequestState::Pending | RequestState::Refused => false,
                };
                let last = stream.last_message_t_s.unwrap_or(f64::NEG_INFINITY);
                let quiet_s = t_s - last.max(stream.since_t_s);
                if waiting && quiet_s > stale_s {
                    stream.ask_again(t_s);
                    autopilot.re_requests += 1;
                    self.counts.re_requests += 1;
                    autopilot.fallback_sent = false;
                    tracing::info!(
                        "vehicle {id}: no {} for {quiet_s:.1} s while its heartbeats go on: asking again",
                        message_info(stream.message_id).map_or("?", |m| m.name),
                    );
                }
            }
            if let Some((index, sent_t_s)) = autopilot.outstanding {
                if t_s - sent_t_s < config.answer_timeout_s {
                    continue;
                }
                autopilot.outstanding = None;
                let stream = &mut autopilot.streams[index];
                if stream.attempts >= config.attempts {
                    stream.state = RequestState::Unanswered;
                    stream.since_t_s = t_s;
                    self.counts.unanswered += 1;
                }
            }
            if let Some(index) = autopilot
                .streams
                .iter()
                .position(|s| s.state == RequestState::Pending)
            {
                let stream = &mut autopilot.streams[index];
                out.push((
                    autopilot.endpoint,
                    set_message_interval(id, stream.message_id, config.rate_hz, stream.attempts),
                ));
                stream.attempts += 1;
                autopilot.outstanding = Some((index, t_s));
                self.counts.interval_requests += 1;
                continue;
            }
            let unanswered = autopilot
                .streams
                .iter()
                .any(|s| s.state == RequestState::Unanswered);
            if unanswered && ardupilot && !autopilot.fallback_sent {
                autopilot.fallback_sent = true;
                self.counts.stream_requests += 1;
                for stream in &mut autopilot.streams {
                    stream.since_t_s = t_s;
                }
                for message in request_data_streams(id, config.rate_hz) {
                    out.push((autopilot.endpoint, message));
                }
            }
        }
        out
    }

    /// Every vehicle's link state, for the summary.
    pub fn vehicles(&self) -> Vec<VehicleLink> {
        self.autopilots
            .iter()
            .map(|(id, a)| VehicleLink {
                vehicle: id.to_string(),
                endpoint: a.endpoint.to_string(),
                autopilot: heartbeat_names(&a.heartbeat).1,
                vehicle_type: heartbeat_names(&a.heartbeat).0,
                streams: a
                    .streams
                    .iter()
                    .map(|s| (message_info(s.message_id).map_or("?", |m| m.name), s.state))
                    .collect(),
                reboots: a.reboots,
                returns: a.returns,
                re_requests: a.re_requests,
            })
            .collect()
    }
}

fn set_message_interval(to: SenderId, message_id: u32, rate_hz: f64, attempt: u8) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: message_id as f32,
        param2: (1e6 / rate_hz) as f32,
        param3: 0.0,
        param4: 0.0,
        param5: 0.0,
        param6: 0.0,
        param7: 0.0,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        target_system: to.system_id,
        target_component: to.component_id,
        confirmation: attempt,
    })
}

/// ArduPilot's older way to ask for position (POSITION: GLOBAL_POSITION_INT) and attitude
/// (EXTRA1: ATTITUDE). Deprecated in MAVLink, and what ArduPilot before 4.0 understands.
#[allow(deprecated)]
fn request_data_streams(to: SenderId, rate_hz: f64) -> [MavMessage; 2] {
    [
        MavDataStream::MAV_DATA_STREAM_POSITION,
        MavDataStream::MAV_DATA_STREAM_EXTRA1,
    ]
    .map(|stream| {
        MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
            req_message_rate: rate_hz.round().clamp(1.0, 65535.0) as u16,
            target_system: to.system_id,
            target_component: to.component_id,
            req_stream_id: stream,
            start_stop: 1,
        })
    })
}
