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
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{MavCmd, MavMessage, COMMAND_LONG_DATA};
use savsim::ingest::stats::SenderId;
use savsim::live::LiveRun;
use savsim::pipeline::CollisionConfig;
use savsim::session::Session;

const INSIDE: &str = "SAVSIM_SITL_INSIDE_NETNS";

pub(crate) fn arducopter() -> Option<PathBuf> {
    let path = std::env::var_os("SAVSIM_ARDUCOPTER").map(PathBuf::from);
    if path.is_none() {
        eprintln!("skipped: set SAVSIM_ARDUCOPTER to an ArduCopter SITL binary (docs/live.md)");
    }
    path
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

/// Whether this is `test` running inside a network namespace of its own with only a loopback
/// interface. If it is not, runs `test` again there (`unshare -n`), waits for it and returns
/// false: the caller returns at once.
pub(crate) fn inside_own_network_namespace(test: &str) -> bool {
    if std::env::var_os(INSIDE).is_some() {
        return true;
    }
    let exe = std::env::current_exe().unwrap();
    let status = Command::new("unshare")
        .args(["-n", "sh", "-c", "ip link set lo up && exec \"$0\" \"$@\""])
        .arg(exe)
        .args([test, "--exact", "--nocapture"])
        .env(INSIDE, "1")
        .status();
    match status {
        Ok(s) => assert!(s.success(), "the test inside the namespace failed: {s:?}"),
        Err(e) => eprintln!("skipped: `unshare -n` is not available here ({e})"),
    }
    false
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
        let last = world.vehicles[&id].history.latest().unwrap().t_s;
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
    let Some(bin) = arducopter() else { return };
    if !inside_own_network_namespace("sitl::two_arducopters_on_one_udp_link_one_rebooted") {
        return;
    }
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
