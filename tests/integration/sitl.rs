//! Against ArduCopter SITL built from ArduPilot's public sources (docs/live.md). The binary's
//! path comes from `SAVSIM_ARDUCOPTER` (and a defaults file, e.g. ArduPilot's
//! Tools/autotest/default_params/copter.parm, from `SAVSIM_ARDUCOPTER_DEFAULTS`); without it the
//! test says so and passes.
//!
//! SITL binds some sockets to every interface (its RC input port, TCP serial ports), so the
//! test runs itself again inside a network namespace of its own (`unshare -n`, loopback only)
//! and everything, savsim, both SITLs and the test's GCS, talks over 127.0.0.1 there. Two
//! copters send to one savsim `udpin` link from their own source ports; the first is rebooted
//! by the test's GCS (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN over its SERIAL1, TCP 5762) at 20 s.
//! Bounded: 75 s.

use std::io::Write;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{MavCmd, MavMessage, COMMAND_LONG_DATA};
use savsim::live::LiveRun;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;
use savsim::world::SenderId;

const INSIDE: &str = "SAVSIM_SITL_INSIDE_NETNS";
/// Set (to anything) in CI: a SITL test that cannot run fails instead of skipping.
const REQUIRE: &str = "SAVSIM_REQUIRE_SITL";

/// The autopilot a SITL test flies, and the variable that names its binary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Autopilot {
    /// ArduCopter SITL (`SAVSIM_ARDUCOPTER`; `SAVSIM_ARDUCOPTER_DEFAULTS` its defaults file).
    ArduCopter,
    /// PX4 SITL with SIH (`SAVSIM_PX4`: `build/px4_sitl_default/bin/px4`).
    Px4,
}

impl Autopilot {
    fn variable(self) -> &'static str {
        match self {
            Autopilot::ArduCopter => "SAVSIM_ARDUCOPTER",
            Autopilot::Px4 => "SAVSIM_PX4",
        }
    }
}

/// Where a SITL test's autopilots run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Netns {
    /// The test runs itself again inside a network namespace of its own (`unshare -n`,
    /// loopback up) and everything it starts talks over 127.0.0.1 there.
    Own,
    /// The test runs `savsim study`, which makes a namespace of its own for its SITLs.
    Study,
}

/// What else a SITL test needs.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Need {
    /// A Python module (`python3 -c "import NAME"`).
    Python(&'static str),
    /// A program on the PATH that answers `NAME --version`.
    Program(&'static str),
    /// The other autopilot too (a row of two): its variable names its binary.
    Autopilot(Autopilot),
}

/// A SITL test's turn: its autopilot's binary, and the turn held while it flies.
pub(crate) struct Turn {
    pub(crate) bin: PathBuf,
    _turn: Option<Held>,
}

/// A turn of [`sitl_test`]'s: shared by light tests, alone for a heavy one.
enum Held {
    Shared(#[allow(dead_code)] std::sync::RwLockReadGuard<'static, ()>),
    Alone(#[allow(dead_code)] std::sync::RwLockWriteGuard<'static, ()>),
}

/// The one gate of every SITL test: the autopilot's binary (and what else the test needs),
/// once the test may fly it. When something is missing it writes `SKIP: <test>: <why> [SITL]`
/// to stderr and returns None, or, with `SAVSIM_REQUIRE_SITL` set (CI), panics. When it can
/// run it writes `SITL-RAN: <test>` (both past the test harness's capture, so that CI's log
/// has them) and then:
///
/// - [`Netns::Own`]: runs the test again inside a network namespace of its own, waits for it
///   and returns None (the caller returns at once); inside, returns the binary.
/// - [`Netns::Study`]: returns the binary (`savsim study` makes the namespace; the gate has
///   checked that one can be made).
///
/// Heavy tests fly alone (the returned [`Turn`] holds the turn), light ones beside each other:
/// the PX4 tests are heavy because PX4 SITL's instance N keeps a lock and a server socket in
/// /tmp (`px4_lock-N`, `px4-sock-N`), which a network namespace does not separate; the study
/// tests because they fly several SITLs at once, or PX4, at speedups whose results depend on
/// savsim keeping up (on two cores, two studies at once starved a PX4 row to 0.3x of its
/// speedup, and a row beside an ArduCopter test ended 1 m nearer its box). Single ArduCopter
/// tests are light. The turn is taken before the namespace, where the tests share one process.
pub(crate) fn sitl_test(autopilot: Autopilot, netns: Netns, needs: &[Need]) -> Option<Turn> {
    static TURNS: std::sync::RwLock<()> = std::sync::RwLock::new(());
    let test = test_name();
    let variable = autopilot.variable();
    if std::env::var_os(INSIDE).is_some() {
        let bin = std::env::var_os(variable).map(PathBuf::from);
        return Some(Turn {
            bin: bin.expect("the variable the test was started with"),
            _turn: None,
        });
    }
    let bin = match std::env::var_os(variable).map(PathBuf::from) {
        None => {
            return skip(
                &test,
                &format!("set {variable} to its SITL binary (docs/live.md)"),
            )
        }
        Some(b) if !b.is_file() => {
            return skip(&test, &format!("{variable}={}: no such file", b.display()))
        }
        Some(b) => b,
    };
    for need in needs {
        if let Some(why) = missing(*need) {
            return skip(&test, &why);
        }
    }
    let Some(unshare) = unshare_flags() else {
        return skip(
            &test,
            "no network namespace can be made here (`unshare -n`, `unshare -rn`)",
        );
    };
    say(&format!("SITL-RAN: {test}\n"));
    let heavy = autopilot == Autopilot::Px4 || netns == Netns::Study;
    let turn = Some(if heavy {
        Held::Alone(
            TURNS
                .write()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        )
    } else {
        Held::Shared(
            TURNS
                .read()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        )
    });
    if netns == Netns::Study {
        return Some(Turn { bin, _turn: turn });
    }
    let exe = std::env::current_exe().unwrap();
    let status = Command::new("unshare")
        .args([
            unshare,
            "sh",
            "-c",
            "ip link set lo up && exec \"$0\" \"$@\"",
        ])
        .arg(exe)
        .args([
            test.as_str(),
            "--exact",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env(INSIDE, "1")
        .status()
        .expect("unshare runs");
    assert!(
        status.success(),
        "the test inside the namespace failed: {status:?}"
    );
    None
}

/// The running test's name (the harness names each test's thread after it).
fn test_name() -> String {
    std::thread::current()
        .name()
        .filter(|n| *n != "main")
        .expect("a test thread, named after its test")
        .to_owned()
}

/// Say that `test` cannot run and why, or fail if SITL is required here.
fn skip(test: &str, why: &str) -> Option<Turn> {
    assert!(
        std::env::var_os(REQUIRE).is_none(),
        "{test}: {why} ({REQUIRE} is set: SITL tests must run here)"
    );
    say(&format!("SKIP: {test}: {why} [SITL]\n"));
    None
}

/// Write `line` to stderr in one write, past the test harness's capture of `eprintln!`.
fn say(line: &str) {
    let _ = std::io::Write::write_all(&mut std::io::stderr().lock(), line.as_bytes());
}

/// Why `need` is not met here, if it is not.
fn missing(need: Need) -> Option<String> {
    let runs = |c: &mut Command| c.output().is_ok_and(|o| o.status.success());
    match need {
        Need::Python(module) => {
            (!runs(Command::new("python3").args(["-c", &format!("import {module}")])))
                .then(|| format!("Python's {module} is not importable (.ci/run installs it)"))
        }
        Need::Program(name) => (!runs(Command::new(name).arg("--version")))
            .then(|| format!("{name} is not on the PATH (.ci/run installs it)")),
        Need::Autopilot(other) => {
            let variable = other.variable();
            let there = std::env::var_os(variable).is_some_and(|b| Path::new(&b).is_file());
            (!there).then(|| format!("set {variable} to its SITL binary too (docs/live.md)"))
        }
    }
}

/// The flags of `unshare` that make a network namespace here: `-n` (as root), else `-rn` (a
/// user namespace too), as `savsim study` tries them.
fn unshare_flags() -> Option<&'static str> {
    ["-n", "-rn"].into_iter().find(|flags| {
        Command::new("unshare")
            .args([*flags, "true"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    })
}

/// A SITL process, killed when dropped.
pub(crate) struct Sitl(pub(crate) Child);

impl Drop for Sitl {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub(crate) fn start_sitl(
    bin: &PathBuf,
    instance: u8,
    sysid: u8,
    serial0: &str,
    dir: &std::path::Path,
) -> Sitl {
    start_sitl_at(bin, instance, sysid, serial0, dir, 1)
}

/// [`start_sitl`] at `speedup` times real time.
pub(crate) fn start_sitl_at(
    bin: &PathBuf,
    instance: u8,
    sysid: u8,
    serial0: &str,
    dir: &std::path::Path,
    speedup: u32,
) -> Sitl {
    let mut command = Command::new(bin);
    command
        .current_dir(dir)
        .args(["--model", "+", "--speedup", &speedup.to_string(), "--wipe"])
        .args(["-I", &instance.to_string(), "--sysid", &sysid.to_string()])
        .args(["--home", "-35.363261,149.165230,584,353"])
        .args(["--serial0", serial0])
        .stdout(std::fs::File::create(dir.join("sitl.log")).map_or(Stdio::null(), Stdio::from))
        .stderr(Stdio::null());
    if let Some(defaults) = std::env::var_os("SAVSIM_ARDUCOPTER_DEFAULTS") {
        command.arg("--defaults").arg(defaults);
    }
    Sitl(command.spawn().expect("start ArduCopter SITL"))
}

/// COMMAND_LONG `command` with params `p` for vehicle 1/1.
pub(crate) fn command_long(command: MavCmd, p: [f32; 7]) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: 1,
        target_component: 1,
        confirmation: 0,
    })
}

/// MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN for vehicle 1/1: `param1` 1 reboots, 2 shuts down.
pub(crate) fn reboot_shutdown(param1: f32) -> MavMessage {
    let mut p = [0.0; 7];
    p[0] = param1;
    command_long(MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, p)
}

/// Print what a SITL run saw (link, vehicles, ingest) and check that vehicles 1 and 2 both
/// sent positions, up to the end of the run (a rebooted one's too), lost no frame and had at
/// most `most_late` frames out of order. Returns the summary.
pub(crate) fn two_vehicles_to_the_end(
    run: &LiveRun,
    input: &str,
    most_late: u64,
) -> serde_json::Value {
    let summary = run.session.summary("live", input);
    eprintln!(
        "{}",
        serde_json::to_string_pretty(&serde_json::json!({
            "link": run.report,
            "vehicles": summary["vehicles"],
            "ingest": summary["ingest"],
        }))
        .unwrap()
    );
    let world = &run.session.world();
    let end = run.session.stats().time_span_s.unwrap().1;
    for sysid in [1, 2] {
        let id = SenderId {
            system_id: sysid,
            component_id: 1,
        };
        let seen = world.seen.get(&id).copied().unwrap_or_default();
        assert!(seen.positions > 200, "vehicle {sysid}: {seen:?}");
        // Samples are on the vehicle's clock, held within 2 s of their arrival (a SITL clock
        // that runs slow under load lags that much): 5 s still says "to the end".
        let last = world.vehicle(&id).unwrap().history.latest().unwrap().t_s;
        assert!(
            end - last < 5.0,
            "vehicle {sysid} stopped {:.1} s before the end",
            end - last
        );
        let seq = run.session.stats().sequence[&id];
        assert!(
            seq.lost == 0 && seq.late <= most_late,
            "vehicle {sysid}: {seq:?}"
        );
    }
    summary
}

#[test]
fn two_arducopters_on_one_udp_link_one_rebooted() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let runtime = crate::common::runtime();
    let (link, savsim) = crate::common::udp_link(&runtime);
    let to_savsim = format!("udpclient:127.0.0.1:{}", savsim.port());
    let (dir0, dir1) = (dir.path().join("0"), dir.path().join("1"));
    std::fs::create_dir_all(&dir0).unwrap();
    std::fs::create_dir_all(&dir1).unwrap();
    // SERIAL1 stays SITL's default, TCP 5762 (+10 per instance): the test's GCS port.
    let _first = start_sitl(&bin, 0, 1, &to_savsim, &dir0);
    let _second = start_sitl(&bin, 1, 2, &to_savsim, &dir1);
    // The test's GCS: connect to vehicle 1's SERIAL1 and reboot it at 20 s.
    let rebooter = std::thread::spawn(move || {
        let started = Instant::now();
        let mut gcs = loop {
            match TcpStream::connect("127.0.0.1:5762") {
                Ok(s) => break s,
                Err(_) if started.elapsed() < Duration::from_secs(20) => {
                    std::thread::sleep(Duration::from_millis(200))
                }
                Err(_) => return false,
            }
        };
        std::thread::sleep(Duration::from_secs(20).saturating_sub(started.elapsed()));
        let bytes = crate::common::frame_v2(250, 190, 0, &reboot_shutdown(1.0));
        // Stay connected while it is read (SITL drops what a closed connection left).
        let sent = gcs.write_all(&bytes).is_ok();
        std::thread::sleep(Duration::from_secs(3));
        sent
    });
    let session = Session::new(None, CollisionConfig::default(), None).unwrap();
    let run = crate::common::run_live(&runtime, vec![link], Duration::from_secs(75), session, None);
    assert!(
        rebooter.join().unwrap(),
        "vehicle 1's SERIAL1 never answered"
    );
    for d in [&dir0, &dir1] {
        let log = std::fs::read_to_string(d.join("sitl.log")).unwrap_or_default();
        let tail: Vec<&str> = log.lines().rev().take(8).collect();
        eprintln!("{}: {}", d.display(), tail.join(" | "));
    }
    two_vehicles_to_the_end(&run, "sitl", 0);
    let world = &run.session.world();
    let first = run
        .report
        .vehicles
        .iter()
        .find(|v| v.vehicle == "1/1")
        .unwrap();
    assert!(first.reboots + first.re_requests >= 1, "{first:?}");
    assert_eq!(
        world.seen[&SenderId {
            system_id: 1,
            component_id: 1
        }]
            .boot_resets,
        1
    );
}
