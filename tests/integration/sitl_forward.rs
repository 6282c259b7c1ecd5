//! Ground stations and routers against ArduCopter SITL (`SAVSIM_ARDUCOPTER`; each test goes
//! through `sitl::sitl_test`, which skips it with a line that says so, or fails it under
//! `SAVSIM_REQUIRE_SITL`), inside a network namespace of its own:
//!
//! - through `--forward`: a pymavlink station reads a parameter, sets GUIDED and arms; real
//!   MAVProxy (`pip install MAVProxy`; .ci/run installs it) fetches every parameter (MAVFTP,
//!   both ways through savsim); the pymavlink station sees exactly what savsim received from
//!   the vehicle, message for message.
//! - behind a router: real MAVProxy in front of two ArduCopters, savsim on its one output with
//!   the feed: refused with the error that says what to do; both vehicles mirrored until then.
//! - signing: ArduCopter at speedup 10 given a key over SERIAL0 (SETUP_SIGNING, as MAVProxy's `signing
//!   setup` sends it); on SERIAL1 (which, unlike SERIAL0, drops unsigned frames) savsim with
//!   the key is answered, savsim without it is not.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use savsim::codec::signing::SigningKey;
use savsim::links::address::ConnectAddress;
use savsim::links::sockets::Link;
use savsim::links::supervisor::RequestState;
use savsim::live::{run_links, LiveOptions, LiveRun};
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

use crate::common::{python, python_code, root, runtime};
use crate::sitl::{sitl_test, start_sitl, start_sitl_at, Autopilot, Need, Netns, Sitl, Turn};

/// A child process killed (and reaped) when dropped.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn open(rt: &tokio::runtime::Runtime, address: &str) -> (ConnectAddress, Link) {
    let a: ConnectAddress = address.parse().unwrap();
    let link = rt.block_on(Link::open(&a)).unwrap();
    (a, link)
}

fn udpout(port: u16) -> String {
    format!("udpout:127.0.0.1:{port}")
}

/// savsim on `vehicles` links (then `stations`) until `shutdown` is raised or its duration
/// passes.
fn run(
    rt: &tokio::runtime::Runtime,
    vehicles: &[&str],
    stations: &[String],
    (options, shutdown): (LiveOptions, Arc<AtomicBool>),
    session: Session,
    record: Option<&Path>,
) -> LiveRun {
    let mut links = Vec::new();
    for v in vehicles {
        links.push(open(rt, v).1);
    }
    let mut forward = Vec::new();
    for s in stations {
        let (a, link) = open(rt, s);
        forward.push(a);
        links.push(link);
    }
    let options = LiveOptions { forward, ..options };
    run_links(rt.handle(), links, &options, session, record, shutdown).unwrap()
}

fn sitl_dir(root: &Path, name: &str) -> std::path::PathBuf {
    let d = root.join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn stations_through_forward_arm_set_mode_and_read_parameters_of_arducopter() {
    let needs = [Need::Python("pymavlink"), Need::Program("mavproxy.py")];
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &needs) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let _sitl: Sitl = start_sitl(&bin, 0, 1, "tcp:0", &sitl_dir(dir.path(), "sitl"));
    let rt = runtime();

    // The pymavlink station listens first and says where; it runs until told to stop (SIGTERM,
    // once savsim has stopped), 300 s at most.
    let mut station = Command::new("python3")
        .arg(root().join("tests/python/station.py"))
        .args(["--mode", "4", "--arm", "--force-arm", "--run-s", "300"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let mut out = BufReader::new(station.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let station_port: u16 = line.trim().trim_start_matches("PORT ").parse().unwrap();
    let mut stations = vec![udpout(station_port)];

    // MAVProxy: a second station, which fetches every parameter.
    let mavproxy = {
        let port = free_udp_port();
        stations.push(udpout(port));
        let mp_dir = sitl_dir(dir.path(), "mavproxy");
        Killed(
            Command::new("mavproxy.py")
                .current_dir(&mp_dir)
                .arg(format!("--master=udpin:127.0.0.1:{port}"))
                .args(["--non-interactive", "--logfile", "mavproxy.tlog"])
                .arg(format!("--state-basedir={}", mp_dir.display()))
                .stdin(Stdio::null())
                .stdout(std::fs::File::create(mp_dir.join("out.log")).unwrap())
                .stderr(Stdio::null())
                .spawn()
                .expect("start MAVProxy"),
        )
    };

    // savsim runs until the station has heard 300 positions through it and has read the
    // parameter, seen GUIDED and seen the copter armed, and MAVProxy has written every
    // parameter it fetched through it (mav.parm), 180 s at most; then the station is
    // stopped, after savsim, so that it has seen all savsim forwarded.
    let stop = Arc::new(AtomicBool::new(false));
    let listener = std::thread::spawn({
        let (stop, mp_dir) = (stop.clone(), dir.path().join("mavproxy"));
        move || {
            let mut text = String::new();
            for line in out.lines().map_while(Result::ok) {
                let progress = line.strip_prefix("POSITIONS ").unwrap_or_default();
                let mut words = progress.split_whitespace();
                let positions: u64 = words.next().and_then(|n| n.parse().ok()).unwrap_or(0);
                let done = words.next() == Some("DONE");
                if positions >= 300 && done && find_file(&mp_dir, "mav.parm").is_some() {
                    stop.store(true, Ordering::Relaxed);
                }
                text.push_str(&line);
                text.push('\n');
            }
            text
        }
    });
    let record = dir.path().join("savsim.tlog");
    let options = LiveOptions {
        duration: Some(Duration::from_secs(180)),
        ..Default::default()
    };
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let live = run(
        &rt,
        &["tcpout:127.0.0.1:5760"],
        &stations,
        (options, stop.clone()),
        session,
        Some(&record),
    );
    assert!(
        stop.load(Ordering::Relaxed),
        "in 180 s the station never heard 300 positions or saw its commands take, or MAVProxy \
         never had every parameter"
    );
    drop(mavproxy);
    let ended = crate::common::signal_and_wait(&mut station, "TERM");
    assert!(ended.success(), "the station: {ended:?}");
    let text = listener.join().unwrap();
    let seen: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    eprintln!("station: {seen}\nforward: {:?}", live.report.forward);
    live.ended.unwrap();

    assert_eq!(
        seen["param"].as_f64(),
        Some(1.0),
        "SYSID_THISMAV read: {seen}"
    );
    assert_eq!(seen["mode_set"], true, "GUIDED set: {seen}");
    assert_eq!(seen["armed"], true, "armed: {seen}");

    // The station saw every message savsim received from the vehicle (but the ACKs for
    // savsim's own requests, which are not forwarded), as often.
    let recorded: serde_json::Value = serde_json::from_str(&python(
        &root().join("tests/fixtures/count_tlog.py"),
        &[record.to_str().unwrap(), "1"],
    ))
    .unwrap();
    let mut station_counts = serde_json::Map::new();
    for (sender, counts) in seen["counts"].as_object().unwrap() {
        if sender.starts_with("1/") {
            for (name, n) in counts.as_object().unwrap() {
                let total = station_counts
                    .get(name)
                    .and_then(|v| v.as_u64())
                    .unwrap_or(0);
                station_counts.insert(name.clone(), (total + n.as_u64().unwrap()).into());
            }
        }
    }
    for (name, n) in recorded.as_object().unwrap() {
        if name == "COMMAND_ACK" {
            continue;
        }
        assert_eq!(
            station_counts.get(name),
            Some(n),
            "{name}: station {station_counts:?}"
        );
    }
    assert!(
        recorded["GLOBAL_POSITION_INT"].as_u64() > Some(200),
        "{recorded}"
    );

    // MAVProxy fetched every parameter (over MAVFTP, through savsim both ways: it writes
    // them to mav.parm once it has them all).
    let parm = find_file(&dir.path().join("mavproxy"), "mav.parm")
        .map(|p| std::fs::read_to_string(p).unwrap_or_default())
        .unwrap_or_default();
    assert!(
        parm.lines().count() > 500,
        "MAVProxy's mav.parm: {} lines",
        parm.lines().count()
    );
}

/// The first file called `name` under `dir`.
fn find_file(dir: &Path, name: &str) -> Option<std::path::PathBuf> {
    for entry in std::fs::read_dir(dir).ok()?.flatten() {
        let path = entry.path();
        if path.is_dir() {
            if let Some(found) = find_file(&path, name) {
                return Some(found);
            }
        } else if path.file_name().is_some_and(|n| n == name) {
            return Some(path);
        }
    }
    None
}

#[test]
fn the_feed_is_refused_behind_mavproxy_in_front_of_two_arducopters() {
    let needs = [Need::Program("mavproxy.py")];
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &needs) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let _a = start_sitl(&bin, 0, 1, "tcp:0", &sitl_dir(dir.path(), "a"));
    let _b = start_sitl(&bin, 1, 2, "tcp:0", &sitl_dir(dir.path(), "b"));
    let out_port = free_udp_port();
    let mp_dir = sitl_dir(dir.path(), "mavproxy");
    let _mavproxy = Killed(
        Command::new("mavproxy.py")
            .current_dir(&mp_dir)
            .args(["--master=tcp:127.0.0.1:5760", "--master=tcp:127.0.0.1:5770"])
            .arg(format!("--out=udpin:127.0.0.1:{out_port}"))
            .args(["--non-interactive", "--logfile", "mavproxy.tlog"])
            .arg(format!("--state-basedir={}", mp_dir.display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start MAVProxy"),
    );
    let rt = runtime();
    let scene = Arc::new(crate::common::scene_at(
        savsim::geo::Geodetic::new(-35.363261, 149.165230, 584.0),
        "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [2.0, 20.0, 30.0] }\nposition_enu_m = [15.0, 0.0, 0.0]\n",
    ));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    session
        .start_feed(savsim::feed::FeedConfig {
            kinds: savsim::feed::FeedKinds::parse("proximity").unwrap(),
            ..Default::default()
        })
        .unwrap();
    let options = LiveOptions {
        duration: Some(Duration::from_secs(60)),
        ..Default::default()
    };
    // savsim sends first to MAVProxy's udpin output.
    let live = run(
        &rt,
        &[&format!("udpout:127.0.0.1:{out_port}")],
        &[],
        (options, Arc::default()),
        session,
        None,
    );
    eprintln!("{:?}", live.report.vehicles);
    let err = live.ended.expect_err("the feed is refused").to_string();
    assert!(
        err.contains("one endpoint") && err.contains("its own link"),
        "{err}"
    );
}

/// SETUP_SIGNING for vehicle 1/1 with `key`, sent on its SERIAL0 (TCP 5760) as MAVProxy's
/// `signing setup` does; true once the vehicle's frames there come signed.
fn set_up_signing(passphrase: &str) -> bool {
    python_code(&format!(
        "import os, time, hashlib\n\
         os.environ['MAVLINK20'] = '1'\n\
         from pymavlink import mavutil\n\
         m = mavutil.mavlink_connection('tcp:127.0.0.1:5760', source_system=255, source_component=190)\n\
         m.wait_heartbeat(timeout=60)\n\
         key = hashlib.sha256({passphrase:?}.encode('utf-8')).digest()\n\
         ts = int((time.time() - 1420070400) * 100 * 1000)\n\
         m.mav.setup_signing_send(1, 1, key, ts)\n\
         m.setup_signing(key, sign_outgoing=True)\n\
         end = time.time() + 20\n\
         ok = False\n\
         while time.time() < end and not ok:\n\
         \x20   msg = m.recv_match(type='HEARTBEAT', blocking=True, timeout=1)\n\
         \x20   ok = msg is not None and getattr(msg, '_signed', False)\n\
         print(ok)"
    ))
    .trim()
        == "True"
}

#[test]
fn a_signing_arducopter_answers_savsim_with_the_key_and_ignores_it_without() {
    let needs = [Need::Python("pymavlink")];
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &needs) else {
        return;
    };
    const PASSPHRASE: &str = "savsim sitl signing";
    let dir = tempfile::tempdir().unwrap();
    // At 10x: the vehicle's clock runs ahead of the wall; its signing clock starts a minute
    // ahead of the wall (seen: 59.9 s); savsim's own timestamps follow the newest it accepted.
    let _sitl = start_sitl_at(&bin, 0, 1, "tcp:0", &sitl_dir(dir.path(), "sitl"), 10);
    assert!(
        set_up_signing(PASSPHRASE),
        "ArduCopter signs once given the key"
    );
    let rt = runtime();
    let streams_accepted = |run: &LiveRun| {
        run.report
            .vehicles
            .iter()
            .find(|v| v.vehicle == "1/1")
            .map(|v| {
                v.streams
                    .values()
                    .filter(|s| **s == RequestState::Accepted)
                    .count()
            })
            .unwrap_or(0)
    };
    // Without the key: SERIAL1 (TCP 5762) drops savsim's unsigned requests.
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let options = LiveOptions {
        duration: Some(Duration::from_secs(8)),
        ..Default::default()
    };
    let unsigned = run(
        &rt,
        &["tcpout:127.0.0.1:5762"],
        &[],
        (options, Arc::default()),
        session,
        None,
    );
    eprintln!("without the key: {:?}", unsigned.report.vehicles);
    assert_eq!(
        streams_accepted(&unsigned),
        0,
        "{:?}",
        unsigned.report.vehicles
    );

    // With it, and requiring it: answered, every frame from the vehicle signed, also after
    // 20 s (200 s of the vehicle's clock).
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let options = LiveOptions {
        duration: Some(Duration::from_secs(20)),
        signing_key: Some(SigningKey::from_passphrase(PASSPHRASE)),
        signing_require: true,
        ..Default::default()
    };
    let signed = run(
        &rt,
        &["tcpout:127.0.0.1:5762"],
        &[],
        (options, Arc::default()),
        session,
        None,
    );
    let counts = signed.report.signing.unwrap();
    eprintln!("with the key: {:?} {counts:?}", signed.report.vehicles);
    assert_eq!(streams_accepted(&signed), 2, "{:?}", signed.report.vehicles);
    assert!(counts.signed > 100, "{counts:?}");
    assert_eq!(
        counts.unsigned_dropped + counts.bad_signature + counts.replayed,
        0,
        "{counts:?}"
    );
    let positions = signed.session.stats().count_of(33);
    assert!(positions > 100, "{positions} positions");
}
