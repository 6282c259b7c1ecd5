//! Starting and stopping one SITL autopilot for a study row: its own instance number (and so
//! its own ports), its own working folder, home at the scene's origin, killed when dropped.
//!
//! ArduCopter SITL (`arducopter`, built from ArduPilot's sources; savsim neither bundles nor
//! builds it): `-I N` opens SERIAL0 on TCP 5760 + 10 N, SERIAL1 on 5762 + 10 N and SERIAL2 on
//! 5763 + 10 N, and its RC input on UDP 5501 + 10 N. savsim's session takes SERIAL0
//! (`--serial0 udpclient:127.0.0.1:PORT`, to the row's own UDP link), the pilot SERIAL1
//! (`--serial1 tcp:2:wait`: SITL does not boot until the pilot is connected).
//! SITL binds its TCP ports on every interface: `savsim study` runs inside a network
//! namespace of its own where the machine allows (`study::row`).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::study::pilot::{Pilot, PilotError};
use crate::world::SenderId;

/// SITL's SERIAL1 TCP port for instance `instance`.
pub fn serial1_port(instance: u16) -> u16 {
    5762 + 10 * instance
}

/// How to start ArduCopter SITL.
#[derive(Debug, Clone, PartialEq)]
pub struct ArduCopter {
    /// The `arducopter` binary.
    pub binary: PathBuf,
    /// Defaults files read before the row's parameters (e.g. ArduPilot's
    /// Tools/autotest/default_params/copter.parm).
    pub defaults: Vec<PathBuf>,
}

/// One row's SITL: the process (killed and waited for when dropped) and where it lives.
#[derive(Debug)]
pub struct Sitl {
    child: Child,
    /// Its working folder (its eeprom, logs and `sitl.log`).
    pub dir: PathBuf,
    /// The pilot's port: ArduCopter's SERIAL1 (TCP, to connect to), PX4's onboard link's
    /// destination (UDP, to listen on).
    pub pilot_port: u16,
}

impl Sitl {
    /// Start `command` in `dir`, its console to `dir/sitl.log`, the pilot to connect at
    /// `pilot_port`.
    fn spawn(mut command: Command, dir: &Path, pilot_port: u16) -> std::io::Result<Sitl> {
        command
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(dir.join("sitl.log"))?)
            .stderr(Stdio::null());
        Ok(Sitl {
            child: command.spawn()?,
            dir: dir.to_path_buf(),
            pilot_port,
        })
    }

    /// Whether the process has ended, and how.
    pub fn exited(&mut self) -> Option<std::process::ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// The last `lines` lines of its console output.
    pub fn log_tail(&self, lines: usize) -> String {
        let text = std::fs::read_to_string(self.dir.join("sitl.log")).unwrap_or_default();
        let tail: Vec<&str> = text.lines().rev().take(lines).collect();
        tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
    }
}

impl Drop for Sitl {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Where and how one row's ArduCopter runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Start<'a> {
    /// The instance number (`-I`): its ports.
    pub instance: u16,
    /// Home: the scene's origin, on its ground.
    pub home: Geodetic,
    /// Heading at home, degrees clockwise from north.
    pub home_yaw_deg: f64,
    /// SITL's speedup.
    pub speedup: f64,
    /// SERIAL0, e.g. `udpclient:127.0.0.1:PORT`.
    pub serial0: &'a str,
    /// The row's parameters, `(NAME, VALUE)`, written to a defaults file after the others.
    pub params: &'a [(String, f64)],
    /// The row's working folder (created).
    pub dir: &'a Path,
}

impl ArduCopter {
    /// ArduCopter from `flag` (`--arducopter`) or `SAVSIM_ARDUCOPTER`, its defaults files from
    /// `SAVSIM_ARDUCOPTER_DEFAULTS` (comma-separated), every path absolute (each SITL runs in
    /// a folder of its own). None when neither names one.
    pub fn from_flag_or_env(flag: Option<&Path>) -> Option<ArduCopter> {
        let binary = flag
            .map(Path::to_path_buf)
            .or_else(|| std::env::var_os("SAVSIM_ARDUCOPTER").map(PathBuf::from))?;
        let defaults: Vec<PathBuf> = std::env::var("SAVSIM_ARDUCOPTER_DEFAULTS")
            .map(|d| {
                d.split(',')
                    .filter(|p| !p.is_empty())
                    .map(PathBuf::from)
                    .collect()
            })
            .unwrap_or_default();
        let absolute = |p: PathBuf| std::fs::canonicalize(&p).unwrap_or(p);
        Some(ArduCopter {
            binary: absolute(binary),
            defaults: defaults.into_iter().map(absolute).collect(),
        })
    }

    /// Start SITL for one row (a fresh eeprom: `--wipe`). Its console goes to `sitl.log` in
    /// the row's folder. Under Linux it is started through `setpriv --pdeathsig KILL` where
    /// that exists, so that it dies with the thread that started it even if savsim is killed.
    pub fn start(&self, start: &Start<'_>) -> std::io::Result<Sitl> {
        // SITL waits for the pilot before it boots: its clock starts at the same point of the
        // row whatever the wall-clock delay (at speedup 100 a second of waiting would be 100 s
        // of its clock).
        let command = self.command(start, "+", "tcp:2:wait", start.speedup)?;
        Sitl::spawn(command, start.dir, serial1_port(start.instance))
    }

    /// Start SITL in lockstep (`--model JSON:127.0.0.1`: its physics is savsim's, on UDP
    /// `9002 + 10 N`), its SERIAL1 as `serial1` (savsim's pilot port), never sleeping to keep
    /// a pace of its own (its clock is savsim's).
    pub fn start_lockstep(&self, start: &Start<'_>, serial1: &str) -> std::io::Result<Sitl> {
        let command = self.command(start, "JSON:127.0.0.1", serial1, SPEEDUP_CEILING)?;
        Sitl::spawn(command, start.dir, 0)
    }

    fn command(
        &self,
        start: &Start<'_>,
        model: &str,
        serial1: &str,
        speedup: f64,
    ) -> std::io::Result<Command> {
        std::fs::create_dir_all(start.dir)?;
        let row_parm = start.dir.join("row.parm");
        let text: String = start
            .params
            .iter()
            .map(|(name, value)| format!("{name} {value}\n"))
            .collect();
        std::fs::write(&row_parm, text)?;
        let mut defaults: Vec<String> = self
            .defaults
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect();
        defaults.push(row_parm.to_string_lossy().into_owned());
        let home = format!(
            "{:.7},{:.7},{:.2},{:.1}",
            start.home.lat_deg, start.home.lon_deg, start.home.alt_m, start.home_yaw_deg
        );
        let mut command = launcher(&self.binary);
        command
            .current_dir(start.dir)
            .args(["--model", model, "--wipe"])
            .args(["--speedup", &speedup.to_string()])
            .args(["-I", &start.instance.to_string()])
            .args(["--home", &home])
            .args(["--serial0", start.serial0])
            .args(["--serial1", serial1])
            .args(["--defaults", &defaults.join(",")]);
        Ok(command)
    }
}

/// The speedup a lockstepped ArduCopter is given: SITL's speedup is a ceiling on its pace,
/// and in lockstep savsim's clock sets the pace.
const SPEEDUP_CEILING: f64 = 1000.0;

/// How to start PX4 SITL with its SIH simulator (`px4` of `px4_sitl_default`, built from PX4's
/// sources).
///
/// Instance `-i N`: its GCS link listens on UDP 18570 + N (and sends to 14550 until it hears a
/// peer, then to that peer: savsim's session sends to it first), its onboard link listens on
/// 14580 + N and sends to 14540 + N (the pilot). Its working folder is the row's; it also
/// makes `/tmp/px4-sock-N`, so two studies on one machine must not share instance numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Px4 {
    /// The `px4` binary.
    pub binary: PathBuf,
}

/// PX4 SITL instance `instance`'s autopilot: its startup script sets MAV_SYS_ID to the
/// instance + 1; component 1.
pub fn px4_autopilot(instance: u16) -> SenderId {
    SenderId {
        system_id: (instance + 1).min(255) as u8,
        component_id: 1,
    }
}

/// Why PX4 could not be started at its home.
#[derive(Debug, thiserror::Error)]
pub enum Px4StartError {
    /// The process could not be started (or its folder made).
    #[error("start {binary}: {source}")]
    Start {
        /// The `px4` binary.
        binary: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// SIH's home altitude or a parameter could not be set over MAVLink before the flight.
    #[error("setting its parameters before the flight: {why}; {tail}")]
    Prime {
        /// What the parameter exchange said.
        why: PilotError,
        /// The last lines of PX4's console.
        tail: String,
    },
}

/// PX4 instance `instance`'s GCS link port (where savsim's session sends).
pub fn px4_gcs_port(instance: u16) -> u16 {
    18570 + instance
}

/// PX4 instance `instance`'s onboard link: where it listens, and where it sends (the pilot).
pub fn px4_onboard_ports(instance: u16) -> (u16, u16) {
    (14580 + instance, 14540 + instance)
}

impl Px4 {
    /// Its `etc` folder (ROMFS), beside `bin/`.
    fn etc(&self) -> std::io::Result<PathBuf> {
        let folder = self.binary.parent().and_then(|bin| bin.parent());
        folder.map(|build| build.join("etc")).ok_or_else(|| {
            std::io::Error::other(format!(
                "{}: no etc folder beside its bin folder",
                self.binary.display()
            ))
        })
    }

    /// Whether this PX4 takes SIH's home (`PX4_HOME_LAT`/`LON`, set into SIH_LOC_LAT0/LON0 by
    /// its startup script) in 1e-7 degrees: PX4 up to 1.15 declares those parameters INT32,
    /// later ones FLOAT degrees. Read from the build's `parameters.xml` beside `bin/`; without
    /// it, degrees.
    fn home_in_e7(&self) -> bool {
        let Some(xml) = self.binary.parent().and_then(Path::parent) else {
            return false;
        };
        let text = std::fs::read_to_string(xml.join("parameters.xml")).unwrap_or_default();
        text.lines()
            .find(|l| l.contains("name=\"SIH_LOC_LAT0\""))
            .is_some_and(|l| l.contains("type=\"INT32\""))
    }

    /// Whether its startup script leaves SIH's home altitude (SIH_LOC_H0) at its default (maps
    /// PX4_HOME_LAT and _LON only; which releases do: docs/study.md): then savsim boots it once
    /// to set SIH_LOC_H0
    /// over MAVLink (`study::row`), or the vehicle would fly hundreds of metres from the scene's
    /// height.
    pub fn home_alt_by_param(&self) -> bool {
        let script = self
            .etc()
            .ok()
            .map(|etc| etc.join("init.d-posix/px4-rc.simulator"))
            .and_then(|p| std::fs::read_to_string(p).ok())
            .unwrap_or_default();
        !script.contains("SIH_LOC_H0")
    }

    /// Start PX4 SIH at `start.home`, its altitude included, with `start.params` in force
    /// from its boot: where its startup script leaves SIH's home altitude alone
    /// ([`Px4::home_alt_by_param`]) or parameters are given, PX4 is first booted once in
    /// `start.dir` to set SIH_LOC_H0 and each parameter over MAVLink (PX4 keeps them in the
    /// folder's parameters.bson), then started again. Some parameters are read only at boot
    /// (PX4 1.15's navigator reads NAV_TRAFF_AVOID once), so a value set in flight may never
    /// act. The PX4 a study row or a test flies.
    ///
    /// Its onboard link's pilot port ([`px4_onboard_ports`]) must be free while it primes;
    /// the GCS link of the first boot sends to 14550 like any PX4, so open a listener there
    /// after this returns if a restart must not be seen.
    pub fn start_at_home(&self, start: &Start<'_>) -> Result<Sitl, Px4StartError> {
        let home_alt = self.home_alt_by_param();
        if home_alt || !start.params.is_empty() {
            self.prime(start, home_alt)?;
        }
        self.start(start).map_err(|source| self.start_error(source))
    }

    /// Start PX4 in lockstep (`PX4_SIM_MODEL=none_iris`: its simulator_mavlink connects to
    /// savsim on TCP `4560 + N` and its clock is savsim's), `start.params` in force from its
    /// boot: written as `param set` lines to a `px4-rc.params` its startup script sources
    /// from the PATH (`rc/` in the row's folder, first on it), with its system id.
    pub fn start_lockstep(&self, start: &Start<'_>, system_id: u8) -> std::io::Result<Sitl> {
        std::fs::create_dir_all(start.dir)?;
        let binary = runnable_px4(&self.binary, start.dir)?;
        let etc = self.etc()?;
        let rc = start.dir.join("rc");
        std::fs::create_dir_all(&rc)?;
        let mut lines = format!("#!/bin/sh\nparam set MAV_SYS_ID {system_id}\n");
        for (name, value) in start.params {
            lines += &format!("param set {name} {value}\n");
        }
        std::fs::write(rc.join("px4-rc.params"), lines)?;
        let path = std::env::var_os("PATH").unwrap_or_default();
        let mut paths = vec![rc];
        paths.extend(std::env::split_paths(&path));
        let mut command = launcher(&binary);
        command
            .current_dir(start.dir)
            .args(["-d", "-i", &start.instance.to_string(), "-w"])
            .arg(start.dir)
            .arg(etc)
            .env("PX4_SIM_MODEL", "none_iris")
            .env_remove("PX4_SIMULATOR")
            .env(
                "PATH",
                std::env::join_paths(paths).map_err(std::io::Error::other)?,
            );
        Sitl::spawn(command, start.dir, px4_onboard_ports(start.instance).1)
    }

    fn start_error(&self, source: std::io::Error) -> Px4StartError {
        Px4StartError::Start {
            binary: self.binary.display().to_string(),
            source,
        }
    }

    /// Boot PX4 once in `start.dir`, set SIH_LOC_H0 to `start.home`'s altitude (when
    /// `home_alt`) and each of `start.params`, and stop it once PX4 has saved them (its
    /// parameters.bson written after the last set, within 5 s of wall time).
    fn prime(&self, start: &Start<'_>, home_alt: bool) -> Result<(), Px4StartError> {
        let first = self.start(start).map_err(|e| self.start_error(e))?;
        let saved = start.dir.join("parameters.bson");
        let (listens, sends) = px4_onboard_ports(start.instance);
        let plane = LocalTangentPlane::new(start.home);
        let id = px4_autopilot(start.instance);
        let home = home_alt.then_some(("SIH_LOC_H0", start.home.alt_m));
        let params = home
            .into_iter()
            .chain(start.params.iter().map(|(n, v)| (n.as_str(), *v)));
        let set = Pilot::udp(sends, listens, id, plane).and_then(|mut pilot| {
            let mut last_set = SystemTime::now();
            for (name, value) in params {
                pilot.set_param_before_flight(name, value, Duration::from_secs(1))?;
                last_set = SystemTime::now();
            }
            Ok(last_set)
        });
        if let Ok(last_set) = set {
            let written_since = |at: SystemTime| {
                std::fs::metadata(&saved)
                    .and_then(|m| m.modified())
                    .is_ok_and(|m| m >= at)
            };
            let deadline = Instant::now() + Duration::from_secs(5);
            while !written_since(last_set) && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        let tail = first.log_tail(3);
        drop(first);
        set.map(|_| ())
            .map_err(|why| Px4StartError::Prime { why, tail })
    }

    /// Start PX4 SIH (quadrotor, airframe 10040) for one row, home at `start.home` (latitude
    /// and longitude only: [`Px4::start_at_home`] sets the altitude too), at `start.speedup`
    /// (PX4_SIM_SPEED_FACTOR), in the row's folder (`sitl.log` its console). The row's
    /// parameters are set over MAVLink by the pilot (PX4 has no defaults file).
    pub fn start(&self, start: &Start<'_>) -> std::io::Result<Sitl> {
        std::fs::create_dir_all(start.dir)?;
        let binary = runnable_px4(&self.binary, start.dir)?;
        let etc = self.etc()?;
        let e7 = self.home_in_e7();
        let home = |deg: f64| {
            if e7 {
                format!("{}", (deg * 1e7).round() as i64)
            } else {
                format!("{deg:.7}")
            }
        };
        let mut command = launcher(&binary);
        command
            .current_dir(start.dir)
            .args(["-d", "-i", &start.instance.to_string(), "-w"])
            .arg(start.dir)
            .arg(etc)
            .env("PX4_SYS_AUTOSTART", "10040")
            .env("PX4_SIMULATOR", "sihsim")
            .env("PX4_SIM_MODEL", "sihsim_quadx")
            .env("PX4_SIM_SPEED_FACTOR", start.speedup.to_string())
            .env("PX4_HOME_LAT", home(start.home.lat_deg))
            .env("PX4_HOME_LON", home(start.home.lon_deg))
            .env("PX4_HOME_ALT", format!("{:.2}", start.home.alt_m));
        Sitl::spawn(command, start.dir, px4_onboard_ports(start.instance).1)
    }
}

/// The `px4` to run from `dir`: `binary` itself, or, when the `px4-NAME` command links beside
/// it are plain files (a copy that did not keep symbolic links: each holds the text `px4`),
/// `dir/px4-bin/px4`, a folder of links made again: `px4` to `binary`, each `px4-NAME` to
/// `px4`, anything else (`px4-alias.sh`) to its file. PX4's startup script runs its commands
/// as `px4-NAME` from the folder of the `px4` it was started as.
fn runnable_px4(binary: &Path, dir: &Path) -> std::io::Result<PathBuf> {
    let Some(bin) = binary.parent() else {
        return Ok(binary.to_path_buf());
    };
    let flattened = |path: &Path| {
        std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file() && m.len() <= 16)
            && std::fs::read(path).is_ok_and(|text| text.trim_ascii() == b"px4")
    };
    let commands: Vec<PathBuf> = std::fs::read_dir(bin)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("px4-"))
        })
        .collect();
    if !commands.iter().any(|p| flattened(p)) {
        return Ok(binary.to_path_buf());
    }
    relink(binary, &commands, &dir.join("px4-bin"), flattened)
}

/// [`runnable_px4`]'s folder of links in `links`.
#[cfg(unix)]
fn relink(
    binary: &Path,
    commands: &[PathBuf],
    links: &Path,
    flattened: impl Fn(&Path) -> bool,
) -> std::io::Result<PathBuf> {
    use std::os::unix::fs::symlink;
    if links.exists() {
        std::fs::remove_dir_all(links)?;
    }
    std::fs::create_dir_all(links)?;
    let px4 = links.join("px4");
    symlink(std::path::absolute(binary)?, &px4)?;
    for command in commands {
        let Some(name) = command.file_name() else {
            continue;
        };
        if flattened(command) {
            symlink("px4", links.join(name))?;
        } else {
            symlink(std::path::absolute(command)?, links.join(name))?;
        }
    }
    Ok(px4)
}

/// Without symbolic links, the binary as it is.
#[cfg(not(unix))]
fn relink(
    binary: &Path,
    _commands: &[PathBuf],
    _links: &Path,
    _flattened: impl Fn(&Path) -> bool,
) -> std::io::Result<PathBuf> {
    Ok(binary.to_path_buf())
}

/// A command running `binary`: under Linux through `setpriv --pdeathsig KILL` where that
/// exists, so that the process dies with the thread that started it even if savsim is killed.
fn launcher(binary: &Path) -> Command {
    match pdeathsig() {
        Some(setpriv) => {
            let mut c = Command::new(setpriv);
            c.args(["--pdeathsig", "KILL", "--"]).arg(binary);
            c
        }
        None => Command::new(binary),
    }
}

/// `setpriv`, when it is there and can set a parent-death signal.
fn pdeathsig() -> Option<&'static str> {
    static FOUND: std::sync::OnceLock<Option<&'static str>> = std::sync::OnceLock::new();
    *FOUND.get_or_init(|| {
        let ok = Command::new("setpriv")
            .args(["--pdeathsig", "KILL", "--", "true"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then_some("setpriv")
    })
}
