//! `--connect` addresses: `udpin:`, `udpout:`, `tcpout:` and `tcpin:` followed by HOST:PORT,
//! parsed the same way for every scheme (host names, IPv4, `[IPv6]`), resolved when the link
//! opens.

use std::net::SocketAddr;
use std::str::FromStr;

use crate::error::{Error, Result};

/// A host (name or IP address) and a port.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HostPort {
    /// Host name or IP address (an IPv6 address without its brackets).
    pub host: String,
    /// Port.
    pub port: u16,
}

impl std::fmt::Display for HostPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.host.contains(':') {
            write!(f, "[{}]:{}", self.host, self.port)
        } else {
            write!(f, "{}:{}", self.host, self.port)
        }
    }
}

impl From<SocketAddr> for HostPort {
    fn from(a: SocketAddr) -> Self {
        Self {
            host: a.ip().to_string(),
            port: a.port(),
        }
    }
}

impl HostPort {
    /// The first address the host resolves to (IPv4 first, as MAVLink tools bind IPv4).
    pub async fn resolve(&self) -> Result<SocketAddr> {
        let net = |source| Error::Net {
            what: format!("resolve {self}"),
            source,
        };
        let found: Vec<SocketAddr> = tokio::net::lookup_host((self.host.as_str(), self.port))
            .await
            .map_err(net)?
            .collect();
        found
            .iter()
            .find(|a| a.is_ipv4())
            .or(found.first())
            .copied()
            .ok_or_else(|| net(std::io::Error::other("no address")))
    }
}

/// Where to connect.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConnectAddress {
    /// Listen for UDP here (where PX4 SITL and MAVProxy send); replies go to each vehicle's
    /// own address.
    UdpIn(HostPort),
    /// Send UDP here (and receive the replies).
    UdpOut(HostPort),
    /// Connect over TCP (ArduPilot SITL: tcpout:127.0.0.1:5760), retrying until it answers
    /// and reconnecting after a close.
    TcpOut(HostPort),
    /// Accept TCP connections here, one at a time.
    TcpIn(HostPort),
}

impl ConnectAddress {
    /// The host and port, whatever the scheme.
    pub fn host_port(&self) -> &HostPort {
        match self {
            Self::UdpIn(a) | Self::UdpOut(a) | Self::TcpOut(a) | Self::TcpIn(a) => a,
        }
    }
}

impl std::fmt::Display for ConnectAddress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let scheme = match self {
            Self::UdpIn(_) => "udpin",
            Self::UdpOut(_) => "udpout",
            Self::TcpOut(_) => "tcpout",
            Self::TcpIn(_) => "tcpin",
        };
        write!(f, "{scheme}:{}", self.host_port())
    }
}

impl FromStr for ConnectAddress {
    type Err = Error;

    /// ```
    /// use savsim::links::address::{ConnectAddress, HostPort};
    /// let a: ConnectAddress = "udpin:0.0.0.0:14550".parse().unwrap();
    /// assert_eq!(a, ConnectAddress::UdpIn(HostPort { host: "0.0.0.0".into(), port: 14550 }));
    /// let b: ConnectAddress = "udpin:localhost:14550".parse().unwrap();
    /// assert_eq!(b.host_port().host, "localhost");
    /// let c: ConnectAddress = "tcpout:[::1]:5760".parse().unwrap();
    /// assert_eq!(c.to_string(), "tcpout:[::1]:5760");
    /// assert!("serial:/dev/ttyUSB0".parse::<ConnectAddress>().is_err());
    /// assert!("udpin:nowhere".parse::<ConnectAddress>().is_err());
    /// assert!("tcpout::5760".parse::<ConnectAddress>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self> {
        let bad = |reason: &str| Error::Address {
            address: s.to_owned(),
            reason: reason.to_owned(),
        };
        let (scheme, rest) = s
            .split_once(':')
            .ok_or_else(|| bad("expected udpin:, udpout:, tcpout: or tcpin: then HOST:PORT"))?;
        let (host, port) = rest
            .rsplit_once(':')
            .ok_or_else(|| bad("expected HOST:PORT, e.g. 127.0.0.1:14550 or localhost:5760"))?;
        let host = host
            .strip_prefix('[')
            .and_then(|h| h.strip_suffix(']'))
            .unwrap_or(host);
        if host.is_empty() || host.contains(['[', ']', '/', ' ']) {
            return Err(bad("expected a host name or IP address before the port"));
        }
        let port = port
            .parse::<u16>()
            .map_err(|_| bad("expected a port number 0-65535 after the last ':'"))?;
        let hp = HostPort {
            host: host.to_owned(),
            port,
        };
        match scheme {
            "udpin" => Ok(Self::UdpIn(hp)),
            "udpout" | "udp" => Ok(Self::UdpOut(hp)),
            "tcpin" => Ok(Self::TcpIn(hp)),
            "tcpout" | "tcp" => Ok(Self::TcpOut(hp)),
            _ => Err(bad("unknown scheme: use udpin, udpout, tcpout or tcpin")),
        }
    }
}
