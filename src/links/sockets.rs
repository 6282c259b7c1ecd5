//! Live links: sockets in, timestamped chunks out; addressed bytes in, datagrams and TCP
//! writes out. Nothing here frames, decodes or decides what to send: that is the session
//! thread's (`live`) with [`crate::links::supervisor`].
//!
//! Each link is one tokio task on the network runtime's worker. A datagram (or a TCP read)
//! goes, stamped with its receive time, over a bounded channel to the session thread; a full
//! channel drops the chunk and counts it, so a socket task never waits on the core. `tcpout`
//! connects with backoff until the autopilot is up and reconnects after a close; `tcpin`
//! accepts one connection at a time, again after a close. Every wait ends when the run stops.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;

use crate::error::{Error, Result};
use crate::links::address::{ConnectAddress, HostPort};
use crate::links::supervisor::{Endpoint, LinkId};

/// An open link.
pub enum Link {
    /// A UDP socket. `fixed_peer` is udpout's address; udpin answers whoever it heard.
    Udp {
        /// The socket (tests bind it to 127.0.0.1:0).
        socket: UdpSocket,
        /// Where everything goes on udpout.
        fixed_peer: Option<SocketAddr>,
    },
    /// A TCP client that connects (and reconnects) to this address.
    TcpOut(HostPort),
    /// A TCP server that accepts one connection at a time.
    TcpIn(TcpListener),
}

impl Link {
    /// Open the link an address names: bind, listen, or (tcpout) nothing yet: the link task
    /// connects.
    pub async fn open(address: &ConnectAddress) -> Result<Link> {
        let net = |what: String| move |source| Error::Net { what, source };
        Ok(match address {
            ConnectAddress::UdpIn(a) => {
                let at = a.resolve().await?;
                Link::Udp {
                    socket: udp_socket(at).map_err(net(format!("bind UDP {at}")))?,
                    fixed_peer: None,
                }
            }
            ConnectAddress::UdpOut(a) => {
                let peer = a.resolve().await?;
                let local: SocketAddr = if peer.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                Link::Udp {
                    socket: udp_socket(local).map_err(net(format!("bind UDP {local}")))?,
                    fixed_peer: Some(peer),
                }
            }
            ConnectAddress::TcpOut(a) => Link::TcpOut(a.clone()),
            ConnectAddress::TcpIn(a) => {
                let at = a.resolve().await?;
                Link::TcpIn(
                    TcpListener::bind(at)
                        .await
                        .map_err(net(format!("listen TCP {at}")))?,
                )
            }
        })
    }

    /// The local address of a bound socket or listener (tests read the port they got).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match self {
            Link::Udp { socket, .. } => socket.local_addr().ok(),
            Link::TcpIn(listener) => listener.local_addr().ok(),
            Link::TcpOut(_) => None,
        }
    }

    /// What the link is, for logs and the summary: `udpin:127.0.0.1:14550`, ...
    pub fn describe(&self) -> String {
        match self {
            Link::Udp {
                fixed_peer: Some(peer),
                ..
            } => format!("udpout:{peer}"),
            Link::Udp { socket, .. } => socket
                .local_addr()
                .map_or("udpin".into(), |a| format!("udpin:{a}")),
            Link::TcpOut(a) => format!("tcpout:{a}"),
            Link::TcpIn(l) => l
                .local_addr()
                .map_or("tcpin".into(), |a| format!("tcpin:{a}")),
        }
    }

    /// The endpoint that gets the GCS heartbeat before anything is heard on this link.
    pub fn fixed_endpoint(&self, link: LinkId) -> Option<Endpoint> {
        match self {
            Link::Udp {
                fixed_peer: Some(peer),
                ..
            } => Some(Endpoint {
                link,
                peer: Some(*peer),
            }),
            Link::Udp { .. } => None,
            Link::TcpOut(_) | Link::TcpIn(_) => Some(Endpoint { link, peer: None }),
        }
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

/// What a chunk holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChunkKind {
    /// A whole datagram.
    Datagram,
    /// The next piece of a TCP byte stream.
    Stream,
    /// A TCP connection (re)opened: a new byte stream starts (no bytes).
    Connected,
}

/// Bytes received at one instant on one link.
#[derive(Debug)]
pub struct Chunk {
    /// The link.
    pub link: LinkId,
    /// The sender's address on a UDP link.
    pub from: Option<SocketAddr>,
    /// Receive time, UNIX seconds ([`unix_now_s`]).
    pub t_s: f64,
    /// The bytes.
    pub bytes: Vec<u8>,
    /// What they are.
    pub kind: ChunkKind,
}

impl Chunk {
    /// Where the chunk came from, as the supervisor routes.
    pub fn endpoint(&self) -> Endpoint {
        Endpoint {
            link: self.link,
            peer: self.from,
        }
    }
}

/// Bytes to send: one encoded message (or several) to one endpoint.
#[derive(Debug)]
pub struct Outgoing {
    /// Where.
    pub to: Endpoint,
    /// What.
    pub bytes: Vec<u8>,
}

/// Counters the link tasks keep.
#[derive(Debug, Default)]
pub struct LinkCounters {
    /// Chunks dropped because the session thread was behind.
    pub dropped_chunks: AtomicU64,
    /// Bytes in those.
    pub dropped_bytes: AtomicU64,
    /// Outgoing messages dropped (no connection, a full queue, a send error).
    pub unsent: AtomicU64,
    /// TCP connections made (tcpout) or accepted (tcpin).
    pub connects: AtomicU64,
    /// TCP connections the peer closed.
    pub closes: AtomicU64,
    /// Chunks queued for the session thread now (it takes one off with [`Network::taken`]).
    pub queued: AtomicU64,
    /// The most chunks ever queued at once.
    pub queue_peak: AtomicU64,
}

/// Receive time now, UNIX seconds, on a monotonic clock: the system clock read once, at the
/// first call, plus the monotonic time elapsed since. A system clock stepped by NTP or by hand
/// during a run moves no stamp backwards or forwards.
///
/// ```
/// let a = savsim::links::sockets::unix_now_s();
/// let b = savsim::links::sockets::unix_now_s();
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

/// A handle that queues bytes for the links, for a part of the session thread that sends
/// on its own (`--forward`); cloned from [`Network::sender`].
#[derive(Debug, Clone)]
pub struct Sender {
    outgoing: Vec<mpsc::Sender<Outgoing>>,
    counters: Arc<LinkCounters>,
}

impl Sender {
    /// Queue bytes for an endpoint; never waits (a full queue drops and counts).
    pub fn send(&self, out: Outgoing) {
        let sent = self
            .outgoing
            .get(usize::from(out.to.link))
            .is_some_and(|tx| tx.try_send(out).is_ok());
        if !sent {
            self.counters.unsent.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The running link tasks.
pub struct Network {
    sender: Sender,
    stop: watch::Sender<Phase>,
    tasks: Vec<JoinHandle<Result<()>>>,
    runtime: tokio::runtime::Handle,
    /// Their counters.
    pub counters: Arc<LinkCounters>,
    /// Per link, when it last received anything (queued or dropped): UNIX seconds' bits.
    heard: Arc<[AtomicU64]>,
}

/// What one link task owns.
struct Task {
    link: LinkId,
    /// Where received chunks go; `None` once the task stopped receiving, so that the queue
    /// disconnects when every task has.
    chunks: Option<SyncSender<Chunk>>,
    outgoing: mpsc::Receiver<Outgoing>,
    counters: Arc<LinkCounters>,
    heard: Arc<[AtomicU64]>,
    stop: watch::Receiver<Phase>,
}

/// Where a run's stop is. Stopping is in two steps so that nothing the session routed is
/// lost: the links stop receiving first, the session processes what they had queued (and
/// routes or answers it), then the links send what is queued for them and end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Running,
    /// Receive no more; go on sending.
    Closing,
    /// Send what is queued, then end.
    Stopped,
}

impl Network {
    /// Start one task per link on `runtime`; chunks come out of the receiver, which holds at
    /// most `queue_len` of them.
    pub fn start(
        runtime: &tokio::runtime::Handle,
        links: Vec<Link>,
        queue_len: usize,
    ) -> (Network, Receiver<Chunk>) {
        let (chunks, received) = sync_channel(queue_len.max(1));
        let (stop, stopped) = watch::channel(Phase::Running);
        let counters = Arc::new(LinkCounters::default());
        let started = unix_now_s().to_bits();
        let heard: Arc<[AtomicU64]> = links.iter().map(|_| AtomicU64::new(started)).collect();
        let mut outgoing = Vec::new();
        let mut tasks = Vec::new();
        for (index, link) in links.into_iter().enumerate() {
            let (tx, rx) = mpsc::channel(1024);
            outgoing.push(tx);
            let task = Task {
                link: index as LinkId,
                chunks: Some(chunks.clone()),
                outgoing: rx,
                counters: counters.clone(),
                heard: heard.clone(),
                stop: stopped.clone(),
            };
            tasks.push(runtime.spawn(async move {
                let result = match link {
                    Link::Udp { socket, fixed_peer } => task.udp(socket, fixed_peer).await,
                    Link::TcpOut(address) => task.tcp_out(address).await,
                    Link::TcpIn(listener) => task.tcp_in(listener).await,
                };
                if let Err(e) = &result {
                    tracing::error!("{e}");
                }
                result
            }));
        }
        let network = Network {
            sender: Sender {
                outgoing,
                counters: counters.clone(),
            },
            stop,
            tasks,
            runtime: runtime.clone(),
            counters,
            heard,
        };
        (network, received)
    }

    /// Note that the session thread took a chunk off the queue.
    pub fn taken(&self) {
        self.counters.queued.fetch_sub(1, Ordering::Relaxed);
    }

    /// When `link` last received anything, UNIX seconds (its start, before anything came). A
    /// backlog of queued chunks does not make a live link look silent.
    pub fn last_heard_s(&self, link: LinkId) -> f64 {
        self.heard
            .get(usize::from(link))
            .map_or(f64::NEG_INFINITY, |t| {
                f64::from_bits(t.load(Ordering::Relaxed))
            })
    }

    /// Queue bytes for an endpoint; never waits (a full queue drops and counts).
    pub fn send(&self, out: Outgoing) {
        self.sender.send(out);
    }

    /// A handle that sends as [`Network::send`] does.
    pub fn sender(&self) -> Sender {
        self.sender.clone()
    }

    /// True while every link task runs (a task ends early only on an error).
    pub fn running(&self) -> bool {
        self.tasks.iter().all(|t| !t.is_finished())
    }

    /// Stop receiving on every link; they go on sending until [`Network::stop`]. The chunk
    /// queue disconnects once every task has stopped receiving (or ended), after the last
    /// chunk any of them received.
    pub fn stop_receiving(&self) {
        let _ = self.stop.send(Phase::Closing);
    }

    /// Stop every link task and wait for them, each first sending what is queued for it (to a
    /// connected peer); the first error any of them had.
    pub fn stop(self) -> Result<()> {
        let _ = self.stop.send(Phase::Stopped);
        let mut result = Ok(());
        for task in self.tasks {
            let ended = self.runtime.block_on(task).unwrap_or_else(|e| {
                Err(Error::Net {
                    what: "a link task".into(),
                    source: std::io::Error::other(e.to_string()),
                })
            });
            result = result.and(ended);
        }
        result
    }
}

impl Task {
    fn forward(&self, from: Option<SocketAddr>, bytes: &[u8], kind: ChunkKind) {
        let t_s = unix_now_s();
        if let Some(heard) = self.heard.get(usize::from(self.link)) {
            heard.store(t_s.to_bits(), Ordering::Relaxed);
        }
        let chunk = Chunk {
            link: self.link,
            from,
            t_s,
            bytes: bytes.to_vec(),
            kind,
        };
        // Counted before the send, so the taker's decrement never comes first.
        let Some(chunks) = &self.chunks else {
            return;
        };
        let queued = self.counters.queued.fetch_add(1, Ordering::Relaxed) + 1;
        self.counters
            .queue_peak
            .fetch_max(queued, Ordering::Relaxed);
        if let Err(TrySendError::Full(c) | TrySendError::Disconnected(c)) = chunks.try_send(chunk) {
            self.counters.queued.fetch_sub(1, Ordering::Relaxed);
            self.counters.dropped_chunks.fetch_add(1, Ordering::Relaxed);
            self.counters
                .dropped_bytes
                .fetch_add(c.bytes.len() as u64, Ordering::Relaxed);
        }
    }

    fn unsent(&self) {
        self.counters.unsent.fetch_add(1, Ordering::Relaxed);
    }

    /// Send what is queued for the link before it stops (UDP).
    async fn flush_udp(&mut self, socket: &UdpSocket, fixed_peer: Option<SocketAddr>) {
        while let Ok(out) = self.outgoing.try_recv() {
            self.send_udp(socket, out, fixed_peer).await;
        }
    }

    /// Write what is queued for the link before it stops (TCP).
    async fn flush_tcp(&mut self, stream: &mut TcpStream) {
        while let Ok(out) = self.outgoing.try_recv() {
            if stream.write_all(&out.bytes).await.is_err() {
                self.unsent();
            }
        }
    }

    async fn udp(mut self, socket: UdpSocket, fixed_peer: Option<SocketAddr>) -> Result<()> {
        let mut buf = vec![0u8; 65_536];
        loop {
            let receiving = self.chunks.is_some();
            tokio::select! {
                changed = self.stop.changed() => if self.stopped(changed) {
                    self.flush_udp(&socket, fixed_peer).await;
                    return Ok(());
                },
                received = socket.recv_from(&mut buf), if receiving => match received {
                    Ok((n, from)) => self.forward(Some(from), &buf[..n], ChunkKind::Datagram),
                    // ICMP port unreachable on udpout before the vehicle is up: keep going.
                    Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                    Err(source) => {
                        return Err(Error::Net { what: format!("receive UDP on link {}", self.link), source })
                    }
                },
                Some(out) = self.outgoing.recv() => self.send_udp(&socket, out, fixed_peer).await,
            }
        }
    }

    async fn send_udp(&self, socket: &UdpSocket, out: Outgoing, fixed_peer: Option<SocketAddr>) {
        match out.to.peer.or(fixed_peer) {
            // A lost GCS message is sent again by the supervisor.
            Some(to) => {
                if socket.send_to(&out.bytes, to).await.is_err() {
                    self.unsent()
                }
            }
            None => self.unsent(),
        }
    }

    /// After the stop signal changed (or its sender went): stop receiving, and true once the
    /// task is to send what is queued and end.
    fn stopped(&mut self, changed: std::result::Result<(), watch::error::RecvError>) -> bool {
        self.chunks = None;
        changed.is_err() || *self.stop.borrow() == Phase::Stopped
    }

    async fn tcp_out(mut self, address: HostPort) -> Result<()> {
        let mut backoff = Duration::from_millis(200);
        let mut waiting_logged = false;
        loop {
            let connected = tokio::select! {
                // Not connected: nothing queued can be sent.
                _ = self.stop.changed() => return Ok(()),
                c = async {
                    let at = address.resolve().await?;
                    TcpStream::connect(at).await.map_err(|source| Error::Net {
                        what: format!("connect TCP {address}"),
                        source,
                    })
                } => c,
            };
            match connected {
                Ok(stream) => {
                    tracing::info!("connected to {address} (link {})", self.link);
                    backoff = Duration::from_millis(200);
                    waiting_logged = false;
                    if self.converse(stream).await? {
                        return Ok(());
                    }
                    tracing::warn!("{address} closed the connection; reconnecting");
                }
                Err(e) => {
                    if !waiting_logged {
                        tracing::info!("waiting for {address}: {e}");
                        waiting_logged = true;
                    }
                    if self.pause(backoff).await {
                        return Ok(());
                    }
                    backoff = (backoff * 2).min(Duration::from_secs(1));
                }
            }
        }
    }

    async fn tcp_in(mut self, listener: TcpListener) -> Result<()> {
        let local = listener.local_addr().ok();
        loop {
            let accepted = tokio::select! {
                _ = self.stop.changed() => return Ok(()),
                a = listener.accept() => a,
                // Nothing can be sent until someone connects.
                Some(_) = self.outgoing.recv() => { self.unsent(); continue }
            };
            match accepted {
                Ok((stream, from)) => {
                    tracing::info!("accepted {from} on {local:?} (link {})", self.link);
                    if self.converse(stream).await? {
                        return Ok(());
                    }
                    tracing::warn!("{from} closed the connection; waiting for the next one");
                }
                Err(e) => {
                    tracing::warn!("accept on {local:?}: {e}");
                    if self.pause(Duration::from_millis(200)).await {
                        return Ok(());
                    }
                }
            }
        }
    }

    /// Wait `d`, dropping what is queued to send; true if the run stopped meanwhile.
    async fn pause(&mut self, d: Duration) -> bool {
        let until = tokio::time::sleep(d);
        tokio::pin!(until);
        loop {
            tokio::select! {
                _ = self.stop.changed() => return true,
                _ = &mut until => return false,
                Some(_) = self.outgoing.recv() => self.unsent(),
            }
        }
    }

    /// Move bytes both ways on one connection until the peer closes (false) or the run stops
    /// (true).
    async fn converse(&mut self, mut stream: TcpStream) -> Result<bool> {
        self.counters.connects.fetch_add(1, Ordering::Relaxed);
        self.forward(None, &[], ChunkKind::Connected);
        let _ = stream.set_nodelay(true);
        let mut buf = vec![0u8; 65_536];
        loop {
            let receiving = self.chunks.is_some();
            tokio::select! {
                changed = self.stop.changed() => if self.stopped(changed) {
                    self.flush_tcp(&mut stream).await;
                    return Ok(true);
                },
                received = stream.read(&mut buf), if receiving => match received {
                    Ok(0) => break,
                    Ok(n) => self.forward(None, &buf[..n], ChunkKind::Stream),
                    Err(e) if peer_closed(&e) => break,
                    Err(source) => return Err(Error::Net { what: format!("receive TCP on link {}", self.link), source }),
                },
                Some(out) = self.outgoing.recv() => match stream.write_all(&out.bytes).await {
                    Ok(()) => {}
                    Err(e) if peer_closed(&e) => break,
                    Err(source) => return Err(Error::Net { what: format!("send TCP on link {}", self.link), source }),
                },
            }
        }
        self.counters.closes.fetch_add(1, Ordering::Relaxed);
        Ok(false)
    }
}

/// True for the errors that mean the TCP peer went away.
fn peer_closed(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset};
    matches!(e.kind(), ConnectionReset | ConnectionAborted | BrokenPipe)
}
