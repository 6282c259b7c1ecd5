//! The sockets of one lockstepped autopilot: the physics port its servo packets come to (UDP
//! 9002 + 10 x instance on 127.0.0.1, ArduPilot's JSON backend), and the MAVLink ports savsim's
//! session and pilot hear it on (UDP, the autopilot's `udpclient` serial ports: savsim answers
//! to where each datagram came from).

use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use super::json::{PacketError, ServoPacket};

/// ArduPilot SITL instance `instance`'s physics port (`--model JSON`: it sends to 9002 + 10 N);
/// an instance past 6453 wraps (see [`json_port_checked`]).
pub fn json_port(instance: u16) -> u16 {
    json_port_checked(u32::from(instance)).unwrap_or(0)
}

/// [`json_port`], None past port 65535.
pub fn json_port_checked(instance: u32) -> Option<u16> {
    u16::try_from(9002 + 10 * u64::from(instance)).ok()
}

/// Why the physics port failed.
#[derive(Debug, thiserror::Error)]
pub enum PortError {
    /// The port could not be bound.
    #[error("bind UDP 127.0.0.1:{port}: {source}")]
    Bind {
        /// The port.
        port: u16,
        /// What the system said.
        source: std::io::Error,
    },
    /// No servo packet within the wait: the autopilot hung, died, or never started.
    #[error("no servo packet from the autopilot on UDP {port} within {waited_s:.0} s")]
    Silent {
        /// The port.
        port: u16,
        /// Wall seconds waited.
        waited_s: f64,
    },
    /// A datagram that is not a servo packet.
    #[error("UDP {port}: {source}")]
    Packet {
        /// The port.
        port: u16,
        /// What is wrong with it.
        source: PacketError,
    },
    /// The socket failed.
    #[error("UDP {port}: {source}")]
    Io {
        /// The port.
        port: u16,
        /// What the system said.
        source: std::io::Error,
    },
}

/// What arrived on the physics port.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Servo {
    /// A new step's outputs.
    New(ServoPacket),
    /// The last packet again (SITL heard no reply for a second): answer it again.
    Repeat,
}

/// How long [`JsonPort::bind`] tries a port that is in use.
pub const BIND_WITHIN: Duration = Duration::from_secs(3);

/// Bind 127.0.0.1:`port`, trying again every 50 ms for `within` while it is in use.
fn bind_within(port: u16, within: Duration) -> Result<UdpSocket, PortError> {
    let started = std::time::Instant::now();
    loop {
        match UdpSocket::bind(("127.0.0.1", port)) {
            Ok(socket) => return Ok(socket),
            Err(e) if e.kind() == std::io::ErrorKind::AddrInUse && started.elapsed() < within => {
                std::thread::sleep(Duration::from_millis(50));
            }
            Err(source) => return Err(PortError::Bind { port, source }),
        }
    }
}

/// One autopilot's physics port.
#[derive(Debug)]
pub struct JsonPort {
    socket: UdpSocket,
    port: u16,
    peer: Option<SocketAddr>,
    last_count: Option<u32>,
    wait: Option<Duration>,
    buf: [u8; 128],
}

impl JsonPort {
    /// Bind 127.0.0.1:`port`; a port in use is tried again for [`BIND_WITHIN`] (the row
    /// before on this instance may still be letting it go).
    pub fn bind(port: u16) -> Result<JsonPort, PortError> {
        let socket = bind_within(port, BIND_WITHIN)?;
        let port = socket.local_addr().map_or(port, |a| a.port());
        Ok(JsonPort {
            socket,
            port,
            peer: None,
            last_count: None,
            wait: None,
            buf: [0; 128],
        })
    }

    /// The port bound.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Wait up to `wait` for the next servo packet. A datagram that is not one is an error
    /// (the caller decides whether the row goes on).
    pub fn recv(&mut self, wait: Duration) -> Result<Servo, PortError> {
        let port = self.port;
        let io = |source| PortError::Io { port, source };
        // One system call less a step: the wait is set only when it changes.
        let wait = wait.max(Duration::from_millis(1));
        if self.wait != Some(wait) {
            self.socket.set_read_timeout(Some(wait)).map_err(io)?;
            self.wait = Some(wait);
        }
        let (n, from) = match self.socket.recv_from(&mut self.buf) {
            Ok(r) => r,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return Err(PortError::Silent {
                    port,
                    waited_s: wait.as_secs_f64(),
                })
            }
            Err(e) => return Err(io(e)),
        };
        // A datagram longer than the buffer arrives cut to it: still not 40 or 72 bytes.
        let packet = ServoPacket::parse(&self.buf[..n])
            .map_err(|source| PortError::Packet { port, source })?;
        self.peer = Some(from);
        if self.last_count == Some(packet.frame_count) {
            return Ok(Servo::Repeat);
        }
        self.last_count = Some(packet.frame_count);
        Ok(Servo::New(packet))
    }

    /// Send `reply` to where the last packet came from.
    pub fn reply(&self, reply: &str) -> Result<(), PortError> {
        let Some(peer) = self.peer else {
            return Ok(());
        };
        self.socket
            .send_to(reply.as_bytes(), peer)
            .map(|_| ())
            .map_err(|source| PortError::Io {
                port: self.port,
                source,
            })
    }
}

/// A MAVLink port of one autopilot (its `udpclient` serial port sends here): the datagrams
/// waiting, taken without blocking, and savsim's frames sent back to where they came from.
#[derive(Debug)]
pub struct MavPort {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    buf: Vec<u8>,
}

impl MavPort {
    /// A port on 127.0.0.1 (any free port: the autopilot is told which).
    pub fn bind() -> std::io::Result<MavPort> {
        Self::bind_at(0)
    }

    /// A port on 127.0.0.1:`port` (where an autopilot sends: PX4's onboard link).
    pub fn bind_at(port: u16) -> std::io::Result<MavPort> {
        let socket = UdpSocket::bind(("127.0.0.1", port))?;
        socket.set_nonblocking(true)?;
        Ok(MavPort {
            socket,
            peer: None,
            buf: vec![0; 65_536],
        })
    }

    /// This port sending to 127.0.0.1:`port` before it hears anything (an autopilot that
    /// answers whoever sends to it first: PX4's GCS link).
    pub fn sending_to(mut self, port: u16) -> MavPort {
        self.peer = Some(SocketAddr::from(([127, 0, 0, 1], port)));
        self
    }

    /// The port bound.
    pub fn port(&self) -> u16 {
        self.socket.local_addr().map_or(0, |a| a.port())
    }

    /// Hand every datagram waiting to `on_datagram`, in order.
    pub fn drain(&mut self, mut on_datagram: impl FnMut(&[u8])) -> std::io::Result<()> {
        loop {
            match self.socket.recv_from(&mut self.buf) {
                Ok((n, from)) => {
                    self.peer = Some(from);
                    on_datagram(&self.buf[..n]);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(()),
                Err(e) => return Err(e),
            }
        }
    }

    /// Send `bytes` to the autopilot (once it has been heard: before, it cannot be reached).
    pub fn send(&self, bytes: &[u8]) -> std::io::Result<()> {
        match self.peer {
            Some(peer) => self.socket.send_to(bytes, peer).map(|_| ()),
            None => Ok(()),
        }
    }

    /// Whether the autopilot has been heard.
    pub fn heard(&self) -> bool {
        self.peer.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_port_let_go_within_the_wait_is_bound_and_one_held_is_an_error() {
        let held = UdpSocket::bind(("127.0.0.1", 0)).unwrap();
        let port = held.local_addr().unwrap().port();
        let err = bind_within(port, Duration::from_millis(200)).unwrap_err();
        assert!(
            matches!(err, PortError::Bind { port: p, .. } if p == port),
            "{err}"
        );
        let release = std::thread::Builder::new()
            .name("port-holder".into())
            .spawn(move || {
                std::thread::sleep(Duration::from_millis(300));
                drop(held);
            })
            .unwrap();
        let bound = JsonPort::bind(port).unwrap();
        assert_eq!(bound.port(), port);
        release.join().unwrap();
    }
}
