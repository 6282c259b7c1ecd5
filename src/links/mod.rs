//! The network side: where a MAVLink byte enters live. Sockets and their tasks, the addresses
//! they are named by, the framer over datagrams and byte streams, and what is decided about
//! each link's traffic (per-vehicle routes and stream requests, forwarding to ground
//! stations), the last two pure; MAVLink 2 signing is the codec's.
//!
//! - [`address`]: `--connect` addresses.
//! - [`sockets`]: tokio sockets: chunks in, addressed bytes out.
//! - [`stream`]: datagrams and byte streams (UDP, TCP) through the framer.
//! - [`supervisor`]: per-vehicle routes, stream requests and their supervision (pure).
//! - [`forward`]: `--forward`, routing between vehicles and ground stations (pure).

pub mod address;
pub mod forward;
pub mod sockets;
pub mod stream;
pub mod supervisor;
