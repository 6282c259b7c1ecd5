//! MAVLink 2 signing against pymavlink's (tests/python/signing_peer.py, independent of savsim):
//! a vehicle sends signed, unsigned, wrongly signed, replayed and stale frames; savsim drops
//! every bad one and counts it, loses no valid one, and signs what it sends so that
//! pymavlink's checks accept it. On 127.0.0.1, a port bound to 0; each run stops by itself.

use std::process::Command;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use savsim::codec::signing::SigningKey;
use savsim::live::{run_links, LiveOptions, LiveRun};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{have_pymavlink, root, runtime, udp_link};

const PASSPHRASE: &str = "savsim test passphrase";

/// savsim with signing on one udpin link, and the peer sending to it; both results.
fn run_with_peer(require: bool) -> (LiveRun, serde_json::Value) {
    let rt = runtime();
    let (link, at) = udp_link(&rt);
    let peer = Command::new("python3")
        .arg(root().join("tests/python/signing_peer.py"))
        .args(["--to", &at.to_string(), "--passphrase", PASSPHRASE])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let options = LiveOptions {
        duration: Some(Duration::from_secs(7)),
        signing_key: Some(SigningKey::from_passphrase(PASSPHRASE)),
        signing_require: require,
        ..Default::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let shutdown = Arc::new(AtomicBool::new(false));
    let run = run_links(rt.handle(), vec![link], &options, session, None, shutdown).unwrap();
    let out = peer.wait_with_output().unwrap();
    assert!(out.status.success(), "the peer failed");
    let text = String::from_utf8(out.stdout).unwrap();
    let seen = serde_json::from_str(text.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("{e}: {text}"));
    (run, seen)
}

fn n(v: &serde_json::Value) -> u64 {
    v.as_u64().unwrap_or(0)
}

#[test]
fn signing_require_drops_every_bad_frame_and_keeps_every_good_one() {
    if !have_pymavlink() {
        return;
    }
    let (run, seen) = run_with_peer(true);
    let counts = run.report.signing.expect("signing counts");
    let sent = &seen["sent"];
    assert_eq!(counts.signed, n(&sent["signed"]), "{counts:?} {seen}");
    assert_eq!(
        counts.unsigned_dropped,
        n(&sent["unsigned"]),
        "{counts:?} {seen}"
    );
    assert_eq!(
        counts.bad_signature,
        n(&sent["wrong_key"]),
        "{counts:?} {seen}"
    );
    assert_eq!(
        counts.replayed,
        n(&sent["replayed"]) + n(&sent["stale"]),
        "{counts:?} {seen}"
    );
    assert_eq!(counts.unsigned_accepted, 0);
    // Every valid position reached the session, and nothing else did.
    assert_eq!(
        run.session.stats().count_of(33),
        n(&seen["signed_positions"]),
        "{seen}"
    );
    // What savsim sent was signed, and pymavlink's check took every frame of it.
    let back = &seen["from_savsim"];
    assert!(n(&back["good"]) >= 2, "{seen}");
    assert_eq!(n(&back["bad"]), 0, "{seen}");
    assert_eq!(n(&back["unsigned"]), 0, "{seen}");
    assert!(n(&back["types"]["245/190 HEARTBEAT"]) >= 1, "{seen}");
    assert!(counts.sent_signed >= n(&back["good"]), "{counts:?}");
}

#[test]
fn signing_accept_takes_unsigned_frames_but_never_bad_ones() {
    if !have_pymavlink() {
        return;
    }
    let (run, seen) = run_with_peer(false);
    let counts = run.report.signing.expect("signing counts");
    let sent = &seen["sent"];
    assert_eq!(counts.unsigned_accepted, n(&sent["unsigned"]), "{counts:?}");
    assert_eq!(counts.unsigned_dropped, 0);
    assert_eq!(counts.bad_signature, n(&sent["wrong_key"]), "{counts:?}");
    assert_eq!(
        counts.replayed,
        n(&sent["replayed"]) + n(&sent["stale"]),
        "{counts:?}"
    );
    assert_eq!(
        run.session.stats().count_of(33),
        n(&seen["signed_positions"]) + n(&sent["unsigned"]),
        "{seen}"
    );
}

#[test]
fn signing_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let out = crate::cli::savsim()
        .args([
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--signing",
            "require",
            "--duration-s",
            "1",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--signing-key"), "{err}");

    let empty = dir.path().join("empty.key");
    std::fs::write(&empty, "\n").unwrap();
    let out = crate::cli::savsim()
        .args([
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--duration-s",
            "1",
            "--signing-key",
        ])
        .arg(&empty)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("empty"), "{err}");

    // An endless file is refused after 64 KiB, not read to its end.
    let out = crate::cli::savsim()
        .args([
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--duration-s",
            "1",
            "--signing-key",
        ])
        .arg("/dev/zero")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a key or a passphrase"), "{err}");
}

#[test]
fn a_key_file_is_the_key_or_a_passphrase_hashed_as_mavproxy_does() {
    let raw = [7u8; 32];
    assert_eq!(SigningKey::from_file_bytes(&raw).unwrap().0, raw);
    // MAVProxy: hashlib.sha256(passphrase.encode('utf-8')).digest()
    let from_file = SigningKey::from_file_bytes(b"secret\n").unwrap();
    assert_eq!(from_file, SigningKey::from_passphrase("secret"));
    let python =
        crate::common::python_code("import hashlib; print(hashlib.sha256(b'secret').hexdigest())");
    let hex: String = from_file.0.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(python.trim(), hex);
    assert!(SigningKey::from_file_bytes(&[0xff, 0xfe, 0x00]).is_err());
}
