//! Datagrams and TCP pieces from several senders on two links, through the live session
//! thread exactly as `savsim live` runs it (`live::LiveSession`): routing and stream
//! supervision, sequence bookkeeping across reboots and silences, decode and world store;
//! `--forward` with a station on a third link, and signing (accepting or requiring) when the
//! input's first byte says so. The input chooses, per chunk, its link and sender address, the
//! time since the last chunk (up to 5 s: silences, stale streams, returns) and its bytes.
//! Checked: every request goes to a vehicle the supervisor routes, at the endpoint it was last
//! heard on.
#![no_main]

use std::net::SocketAddr;
use std::sync::Arc;

use libfuzzer_sys::fuzz_target;
use mavlink::dialects::ardupilotmega::MavMessage;
use savsim::live::LiveSession;
use savsim::pipeline::CollisionConfig;
use savsim::links::forward::Forwarder;
use savsim::links::sockets::{Chunk, ChunkKind};
use savsim::codec::signing::{Signing, SigningKey};
use savsim::links::supervisor::{Supervisor, SupervisorConfig, DEFAULT_GCS};
use savsim::session::Session;

fuzz_target!(|data: &[u8]| {
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let mut live = LiveSession::new(session, Supervisor::new(SupervisorConfig::default()), None);
    live.forward_with(Forwarder::new(2, Vec::new(), vec![DEFAULT_GCS]), Vec::new(), None);
    if let Some(mode) = data.first().filter(|m| *m & 1 == 1) {
        live.sign_with(Arc::new(Signing::new(&SigningKey([7; 32]), mode & 2 != 0)));
    }
    let mut t_s = 1.0e9;
    let mut rest = data;
    while let [who, step, len, tail @ ..] = rest {
        let len = usize::from(*len).min(tail.len());
        let (bytes, next) = tail.split_at(len);
        rest = next;
        t_s += f64::from(*step) * 0.02;
        // Link 0 is UDP with four senders; link 1 is a TCP stream, reconnected now and then;
        // link 2 a station's UDP link.
        let link = if who & 0x30 == 0x30 { 2 } else { u16::from(who >> 7) };
        let (from, kind) = if link != 1 {
            let port = 5000 + u16::from(who & 3);
            (
                Some(SocketAddr::from(([127, 0, 0, 1], port))),
                ChunkKind::Datagram,
            )
        } else if who & 0x40 != 0 {
            (None, ChunkKind::Connected)
        } else {
            (None, ChunkKind::Stream)
        };
        live.process(&Chunk {
            link,
            from,
            t_s,
            bytes: bytes.to_vec(),
            kind,
        });
        let routes: Vec<_> = live.supervisor().routes().collect();
        for (to, message) in live.supervisor().due(t_s) {
            let target = match &message {
                MavMessage::COMMAND_LONG(c) => Some((c.target_system, c.target_component)),
                #[allow(deprecated)]
                MavMessage::REQUEST_DATA_STREAM(r) => Some((r.target_system, r.target_component)),
                _ => None,
            };
            if let Some((system, component)) = target {
                assert!(
                    routes.iter().any(|(id, endpoint)| {
                        (id.system_id, id.component_id) == (system, component) && *endpoint == to
                    }),
                    "a request to {system}/{component} at {to} that the supervisor does not route"
                );
            }
        }
    }
    let _ = live.supervisor().vehicles();
    let _ = live.session().summary("fuzz", "fuzz");
});
