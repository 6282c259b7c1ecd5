//! Live links: UDP and TCP sockets on tokio, the GCS heartbeat, and stream-rate requests.
//!
//! The socket task only moves bytes: each datagram (or TCP read) goes, stamped with its
//! receive time, over a bounded channel to the session thread, which frames, decodes, records
//! and runs the collision core. A full channel drops the chunk and counts it; the socket task
//! never waits on the core. Once a second the task sends a GCS HEARTBEAT and asks each vehicle
//! for GLOBAL_POSITION_INT and ATTITUDE at the requested rate with MAV_CMD_SET_MESSAGE_INTERVAL,
//! falling back to REQUEST_DATA_STREAM when a vehicle does not accept it (older ArduPilot).

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::Path;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

// REQUEST_DATA_STREAM is deprecated, and is exactly the fallback older ArduPilot needs.
#[allow(deprecated)]
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavDataStream, MavMessage, MavModeFlag, MavResult, MavState, MavType,
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, REQUEST_DATA_STREAM_DATA,
};
use mavlink::{MavHeader, MavlinkVersion, MessageData};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};

use crate::error::{Error, Result};
use crate::ingest::decode::{ID_GLOBAL_POSITION_INT, ID_HEARTBEAT};
use crate::ingest::frame::{FrameStatus, RawFrame};
use crate::ingest::stream::{frames_in_datagram, StreamFramer};
use crate::ingest::tlog::TlogWriter;
use crate::session::Session;

/// Where to connect, parsed from `udpin:`, `udpout:`, `tcpout:` or `tcpin:` strings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConnectAddress {
    /// Listen for UDP on this address (where PX4 SITL and MAVProxy send).
    UdpIn(SocketAddr),
    /// Send UDP to this address (and receive the replies).
    UdpOut(SocketAddr),
    /// Connect over TCP to this host:port (ArduPilot SITL: tcpout:127.0.0.1:5760).
    TcpOut(String),
    /// Accept one TCP connection on this address.
    TcpIn(SocketAddr),
}

impl FromStr for ConnectAddress {
    type Err = Error;

    /// ```
    /// use savsim::ingest::live::ConnectAddress;
    /// let a: ConnectAddress = "udpin:0.0.0.0:14550".parse().unwrap();
    /// assert_eq!(a, ConnectAddress::UdpIn("0.0.0.0:14550".parse().unwrap()));
    /// assert!("serial:/dev/ttyUSB0".parse::<ConnectAddress>().is_err());
    /// assert!("udpin:nowhere".parse::<ConnectAddress>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        let bad = |reason: &str| Error::Address {
            address: s.to_owned(),
            reason: reason.to_owned(),
        };
        let (scheme, rest) = s
            .split_once(':')
            .ok_or_else(|| bad("expected udpin:, udpout:, tcpout: or tcpin: then HOST:PORT"))?;
        let socket = || {
            rest.parse::<SocketAddr>()
                .map_err(|_| bad("expected an IP address and port, e.g. 127.0.0.1:14550"))
        };
        match scheme {
            "udpin" => Ok(ConnectAddress::UdpIn(socket()?)),
            "udpout" | "udp" => Ok(ConnectAddress::UdpOut(socket()?)),
            "tcpin" => Ok(ConnectAddress::TcpIn(socket()?)),
            "tcpout" | "tcp" => {
                if rest
                    .rsplit_once(':')
                    .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok())
                {
                    Ok(ConnectAddress::TcpOut(rest.to_owned()))
                } else {
                    Err(bad("expected HOST:PORT"))
                }
            }
            _ => Err(bad("unknown scheme: use udpin, udpout, tcpout or tcpin")),
        }
    }
}

/// How a live run behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveOptions {
    /// Where to connect.
    pub address: ConnectAddress,
    /// Rate asked for GLOBAL_POSITION_INT and ATTITUDE, Hz. Default 20.
    pub rate_hz: f64,
    /// Stop after this long (default: run until shutdown).
    pub duration: Option<Duration>,
    /// savsim's own system id as a GCS. Default 255.
    pub gcs_system_id: u8,
    /// savsim's own component id. Default 190 (MAV_COMP_ID_MISSIONPLANNER).
    pub gcs_component_id: u8,
    /// Chunks the channel to the session thread holds before dropping. Default 65536.
    pub queue_len: usize,
}

impl Default for LiveOptions {
    fn default() -> Self {
        Self {
            address: ConnectAddress::UdpIn(SocketAddr::from(([0, 0, 0, 0], 14550))),
            rate_hz: 20.0,
            duration: None,
            gcs_system_id: 255,
            gcs_component_id: 190,
            queue_len: 65_536,
        }
    }
}

/// An open link.
pub enum Link {
    /// A UDP socket; `peer` is fixed for udpout, learned from the last sender for udpin.
    Udp {
        /// The socket (tests bind it to 127.0.0.1:0).
        socket: UdpSocket,
        /// Where replies go.
        peer: Option<SocketAddr>,
        /// True when `peer` is fixed (udpout).
        fixed_peer: bool,
    },
    /// A TCP connection.
    Tcp(TcpStream),
}

impl Link {
    /// Open the link an address names.
    pub async fn open(address: &ConnectAddress) -> Result<Link> {
        let net = |what: String| move |source| Error::Net { what, source };
        Ok(match address {
            ConnectAddress::UdpIn(a) => Link::Udp {
                socket: udp_socket(*a).map_err(net(format!("bind UDP {a}")))?,
                peer: None,
                fixed_peer: false,
            },
            ConnectAddress::UdpOut(a) => {
                let local: SocketAddr = if a.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                Link::Udp {
                    socket: udp_socket(local).map_err(net(format!("bind UDP {local}")))?,
                    peer: Some(*a),
                    fixed_peer: true,
                }
            }
            ConnectAddress::TcpOut(host) => Link::Tcp(
                TcpStream::connect(host.as_str())
                    .await
                    .map_err(net(format!("connect TCP {host}")))?,
            ),
            ConnectAddress::TcpIn(a) => {
                let listener = TcpListener::bind(a)
                    .await
                    .map_err(net(format!("listen TCP {a}")))?;
                let (stream, _) = listener
                    .accept()
                    .await
                    .map_err(net(format!("accept TCP {a}")))?;
                Link::Tcp(stream)
            }
        })
    }
}

/// Receive buffer asked of the OS for UDP links, bytes: about 0.1 s of a 100k messages/s burst
/// (Linux grants at most `net.core.rmem_max` unless raised).
const UDP_RECEIVE_BUFFER: usize = 4 << 20;

/// A non-blocking UDP socket bound to `address`, with a large receive buffer so that a burst
/// waits in the kernel rather than being dropped there.
fn udp_socket(address: SocketAddr) -> std::io::Result<UdpSocket> {
    let socket = socket2::Socket::new(
        socket2::Domain::for_address(address),
        socket2::Type::DGRAM,
        Some(socket2::Protocol::UDP),
    )?;
    // Best effort: a smaller buffer still works.
    let _ = socket.set_recv_buffer_size(UDP_RECEIVE_BUFFER);
    socket.set_nonblocking(true)?;
    socket.bind(&address.into())?;
    UdpSocket::from_std(socket.into())
}

/// Bytes received at one instant.
#[derive(Debug)]
pub struct Chunk {
    /// Receive time, UNIX seconds.
    pub t_s: f64,
    /// The bytes.
    pub bytes: Vec<u8>,
    /// True for a whole datagram, false for a piece of a TCP stream.
    pub datagram: bool,
}

#[derive(Debug, Default, Clone, Copy)]
struct RateRequest {
    component_id: u8,
    interval_requests: u32,
    accepted: bool,
    fallback_sent: bool,
}

/// What the socket task and the session thread share.
#[derive(Debug, Default)]
pub struct LinkState {
    vehicles: BTreeMap<u8, RateRequest>,
    /// Chunks dropped because the session thread was behind.
    pub dropped_chunks: u64,
    /// Bytes in those chunks.
    pub dropped_bytes: u64,
    /// Interval requests sent (SET_MESSAGE_INTERVAL commands).
    pub interval_requests: u64,
    /// REQUEST_DATA_STREAM fallbacks sent.
    pub stream_requests: u64,
}

/// Receive time now, UNIX seconds, on a monotonic clock: the system clock read once, at the
/// first call, plus the monotonic time elapsed since. A system clock stepped by NTP or by hand
/// during a run moves no stamp backwards or forwards.
///
/// ```
/// let a = savsim::ingest::live::unix_now_s();
/// let b = savsim::ingest::live::unix_now_s();
/// assert!(b >= a && a > 1.6e9);
/// ```
pub fn unix_now_s() -> f64 {
    static START: std::sync::OnceLock<(std::time::Instant, f64)> = std::sync::OnceLock::new();
    let (instant, unix_s) = START.get_or_init(|| {
        let unix_s = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        (std::time::Instant::now(), unix_s)
    });
    unix_s + instant.elapsed().as_secs_f64()
}

/// Encodes savsim's outgoing messages as a GCS.
struct Outbox {
    header: MavHeader,
    buf: Vec<u8>,
}

impl Outbox {
    fn encode(&mut self, message: &MavMessage) -> &[u8] {
        self.buf.clear();
        // Writing into a Vec cannot fail.
        let _ =
            mavlink::write_versioned_msg(&mut self.buf, MavlinkVersion::V2, self.header, message);
        self.header.sequence = self.header.sequence.wrapping_add(1);
        &self.buf
    }
}

/// The messages to send this second: the heartbeat and any rate requests.
#[allow(deprecated)]
fn due_messages(state: &Mutex<LinkState>, rate_hz: f64) -> Vec<MavMessage> {
    let mut out = vec![MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })];
    let Ok(mut state) = state.lock() else {
        return out;
    };
    let interval_us = (1e6 / rate_hz) as f32;
    let mut interval_requests = 0;
    let mut stream_requests = 0;
    for (&system_id, req) in state.vehicles.iter_mut() {
        if req.accepted {
            continue;
        }
        if req.interval_requests < 3 {
            req.interval_requests += 1;
            interval_requests += 1;
            for message_id in [ID_GLOBAL_POSITION_INT, crate::ingest::decode::ID_ATTITUDE] {
                out.push(MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
                    param1: message_id as f32,
                    param2: interval_us,
                    param3: 0.0,
                    param4: 0.0,
                    param5: 0.0,
                    param6: 0.0,
                    param7: 0.0,
                    command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                    target_system: system_id,
                    target_component: req.component_id,
                    confirmation: (req.interval_requests - 1) as u8,
                }));
            }
        } else if !req.fallback_sent {
            req.fallback_sent = true;
            stream_requests += 1;
            for stream in [
                MavDataStream::MAV_DATA_STREAM_POSITION,
                MavDataStream::MAV_DATA_STREAM_EXTRA1,
            ] {
                out.push(MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
                    req_message_rate: rate_hz.round().clamp(1.0, 65535.0) as u16,
                    target_system: system_id,
                    target_component: req.component_id,
                    req_stream_id: stream,
                    start_stop: 1,
                }));
            }
        }
    }
    state.interval_requests += interval_requests;
    state.stream_requests += stream_requests;
    out
}

/// Move bytes between the link and the session thread until shutdown or the deadline.
pub async fn pump(
    link: Link,
    options: &LiveOptions,
    chunks: SyncSender<Chunk>,
    state: Arc<Mutex<LinkState>>,
    shutdown: Arc<AtomicBool>,
) -> Result<()> {
    let mut outbox = Outbox {
        header: MavHeader {
            system_id: u32::from(options.gcs_system_id),
            component_id: options.gcs_component_id,
            sequence: 0,
        },
        buf: Vec::with_capacity(300),
    };
    let mut ticker = tokio::time::interval(Duration::from_secs(1));
    let mut poll = tokio::time::interval(Duration::from_millis(50));
    let deadline = options.duration.map(|d| tokio::time::Instant::now() + d);
    let mut buf = vec![0u8; 65_536];
    let forward = |bytes: &[u8], datagram: bool, state: &Mutex<LinkState>| {
        let chunk = Chunk {
            t_s: unix_now_s(),
            bytes: bytes.to_vec(),
            datagram,
        };
        if let Err(TrySendError::Full(c) | TrySendError::Disconnected(c)) = chunks.try_send(chunk) {
            if let Ok(mut s) = state.lock() {
                s.dropped_chunks += 1;
                s.dropped_bytes += c.bytes.len() as u64;
            }
        }
    };
    match link {
        Link::Udp {
            socket,
            mut peer,
            fixed_peer,
        } => loop {
            tokio::select! {
                _ = ticker.tick() => {
                    if let Some(peer) = peer {
                        for m in due_messages(&state, options.rate_hz) {
                            // A lost GCS message is retried next second; not worth stopping for.
                            let _ = socket.send_to(outbox.encode(&m), peer).await;
                        }
                    }
                }
                received = socket.recv_from(&mut buf) => {
                    match received {
                        Ok((n, from)) => {
                            if !fixed_peer {
                                peer = Some(from);
                            }
                            forward(&buf[..n], true, &state);
                        }
                        // ICMP port unreachable on udpout before the vehicle is up: keep going.
                        Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                        Err(source) => return Err(Error::Net { what: "receive UDP".into(), source }),
                    }
                }
                _ = poll.tick() => {
                    if shutdown.load(Ordering::Relaxed) || deadline.is_some_and(|d| tokio::time::Instant::now() >= d) {
                        return Ok(());
                    }
                }
            }
        },
        Link::Tcp(mut stream) => loop {
            tokio::select! {
                _ = ticker.tick() => {
                    for m in due_messages(&state, options.rate_hz) {
                        match stream.write_all(outbox.encode(&m)).await {
                            Ok(()) => {}
                            Err(e) if peer_closed(&e) => return Ok(()),
                            Err(source) => return Err(Error::Net { what: "send TCP".into(), source }),
                        }
                    }
                }
                received = stream.read(&mut buf) => {
                    match received {
                        // The peer closed the connection (SITL stopped): the run ends normally.
                        Ok(0) => return Ok(()),
                        Ok(n) => forward(&buf[..n], false, &state),
                        Err(e) if peer_closed(&e) => {
                            tracing::warn!("TCP peer closed the connection: {e}");
                            return Ok(());
                        }
                        Err(source) => return Err(Error::Net { what: "receive TCP".into(), source }),
                    }
                }
                _ = poll.tick() => {
                    if shutdown.load(Ordering::Relaxed) || deadline.is_some_and(|d| tokio::time::Instant::now() >= d) {
                        return Ok(());
                    }
                }
            }
        },
    }
}

/// True for the errors that mean the TCP peer went away.
fn peer_closed(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset};
    matches!(e.kind(), ConnectionReset | ConnectionAborted | BrokenPipe)
}

/// What the session thread does with every frame besides decoding: note vehicles to ask for
/// rates, and their answers.
fn watch_frame(frame: &RawFrame<'_>, state: &Mutex<LinkState>) {
    if frame.status != FrameStatus::Valid {
        return;
    }
    let Ok(mut state) = state.lock() else { return };
    match frame.message_id {
        ID_HEARTBEAT | ID_GLOBAL_POSITION_INT => {
            let is_gcs = frame.message_id == ID_HEARTBEAT
                && frame.payload.get(4) == Some(&(MavType::MAV_TYPE_GCS as u8));
            if !is_gcs {
                state
                    .vehicles
                    .entry(frame.system_id)
                    .or_insert(RateRequest {
                        component_id: frame.component_id,
                        ..RateRequest::default()
                    });
            }
        }
        COMMAND_ACK_DATA::ID => {
            if let Ok(ack) = COMMAND_ACK_DATA::deser(frame.version, frame.payload) {
                if ack.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
                    && ack.result == MavResult::MAV_RESULT_ACCEPTED
                {
                    if let Some(v) = state.vehicles.get_mut(&frame.system_id) {
                        v.accepted = true;
                    }
                }
            }
        }
        _ => {}
    }
}

/// The session thread: frame, watch, record and process every chunk until the channel closes.
pub fn consume(
    chunks: Receiver<Chunk>,
    mut session: Session,
    mut recorder: Option<TlogWriter<BufWriter<std::fs::File>>>,
    state: Arc<Mutex<LinkState>>,
) -> (Session, Result<()>) {
    let mut framer = StreamFramer::default();
    let mut result = Ok(());
    for chunk in chunks {
        let t_us = (chunk.t_s * 1e6) as u64;
        let mut on_frame = |frame: &RawFrame<'_>| {
            watch_frame(frame, &state);
            if let Some(rec) = recorder.as_mut() {
                if let Err(e) = rec.write_record(t_us, frame.bytes) {
                    result = Err(Error::file("recording", e));
                }
            }
            if let Err(e) = session.on_frame(chunk.t_s, frame) {
                result = Err(e);
            }
        };
        let skipped = if chunk.datagram {
            frames_in_datagram(&chunk.bytes, &mut on_frame)
        } else {
            let mut skipped = crate::ingest::stream::Skipped::default();
            let mut rest = &chunk.bytes[..];
            while !rest.is_empty() {
                let spare = framer.spare();
                let n = spare.len().min(rest.len());
                spare[..n].copy_from_slice(&rest[..n]);
                rest = &rest[n..];
                let s = framer.commit(n, &mut on_frame);
                skipped.bytes += s.bytes;
                skipped.runs += s.runs;
            }
            skipped
        };
        skipped.count_into(&mut session.ingestor.stats);
        if result.is_err() {
            break;
        }
    }
    if let Some(rec) = recorder.as_mut() {
        if let Err(e) = rec.flush() {
            result = result.and(Err(Error::file("recording", e)));
        }
    }
    (session, result)
}

/// Run a live link to the end (shutdown, duration, or the peer closing TCP) on a tokio runtime,
/// with the session on its own thread. Returns the session for its summary.
pub fn run_blocking(
    options: LiveOptions,
    session: Session,
    record: Option<&Path>,
    shutdown: Arc<AtomicBool>,
) -> Result<Session> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("savsim-net")
        .enable_all()
        .build()
        .map_err(|source| Error::Net {
            what: "start the network runtime".into(),
            source,
        })?;
    let link = runtime.block_on(Link::open(&options.address))?;
    run_link(&runtime, link, options, session, record, shutdown)
}

/// [`run_blocking`] on an already open link (tests pass a socket bound to port 0).
pub fn run_link(
    runtime: &tokio::runtime::Runtime,
    link: Link,
    options: LiveOptions,
    session: Session,
    record: Option<&Path>,
    shutdown: Arc<AtomicBool>,
) -> Result<Session> {
    let recorder = record
        .map(|p| {
            std::fs::File::create(p)
                .map(|f| TlogWriter::new(BufWriter::new(f)))
                .map_err(|e| Error::file(p, e))
        })
        .transpose()?;
    let state = Arc::new(Mutex::new(LinkState::default()));
    let (tx, rx) = sync_channel(options.queue_len.max(1));
    let consumer_state = state.clone();
    let consumer = std::thread::Builder::new()
        .name("savsim-session".into())
        .spawn(move || consume(rx, session, recorder, consumer_state))
        .map_err(|source| Error::Net {
            what: "start the session thread".into(),
            source,
        })?;
    let pumped = runtime.block_on(pump(link, &options, tx, state.clone(), shutdown.clone()));
    // The sender is dropped: the session drains what is queued, then ends.
    let (mut session, consumed) = consumer.join().map_err(|_| Error::Net {
        what: "the session thread".into(),
        source: std::io::Error::other("panicked"),
    })?;
    if let Ok(s) = state.lock() {
        session.ingestor.stats.dropped_chunks = s.dropped_chunks;
        session.ingestor.stats.dropped_bytes = s.dropped_bytes;
        session.ingestor.stats.interval_requests = s.interval_requests;
        session.ingestor.stats.stream_requests = s.stream_requests;
    }
    session.interrupted = shutdown.load(Ordering::Relaxed);
    pumped.and(consumed).map(|()| session)
}
