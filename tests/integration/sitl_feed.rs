//! The closed loop against ArduCopter SITL (docs/closed-loop.md): savsim feeds the copter's
//! MAVLink proximity sensor from the bundled city, and ArduPilot's own avoidance stops it
//! before a wall it cannot otherwise see. Needs `SAVSIM_ARDUCOPTER` (and
//! `SAVSIM_ARDUCOPTER_DEFAULTS`, ArduPilot's copter.parm), as `sitl`; `SAVSIM_FEED_SPEEDUP`
//! sets SITL's speedup (default 1). Runs in a network namespace of its own.
//!
//! The flight: home at the city's origin, GUIDED, take off to 30 m, go to N -30 m, then fly
//! west at 5 m/s for 25 s (vehicle's clock) towards building b1852, whose east face is at
//! E -57 m from N -90 to N -10 m and 67 m high. With `--feed proximity` and AVOID_ENABLE=3,
//! AVOID_BEHAVE=1 (stop), AVOID_MARGIN=3 and PRX1_FILT=0 the copter must stop at least 1 m short
//! of the face and savsim report no collision; without the feed savsim reports the collision.

use std::io::Write;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, MavModeFlag, MavSysStatusSensor, PositionTargetTypemask,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::links::sockets::Link;
use savsim::live::{run_links, LiveOptions, LiveRun};
use savsim::pipeline::CollisionConfig;
use savsim::scene::Scene;
use savsim::session::Session;

use crate::common::{frame_v2, root, runtime, udp_link};
use crate::sitl::{sitl_test, Autopilot, Netns, Sitl, Turn};

/// b1852's east face, scene E metres.
const FACE_EAST_M: f64 = -57.0;
/// ArduCopter's speedup in these flights (all but the proximity-health test, which times
/// ArduPilot's 500 ms timeout on the wall clock): every wait is on the vehicle's clock.
const SPEEDUP: f64 = 5.0;
/// The city's origin (CMAC), where every SITL test's home is.
pub(crate) const ORIGIN_LAT_DEG: f64 = -35.363261;
pub(crate) const ORIGIN_LON_DEG: f64 = 149.165230;

/// The copter at one GLOBAL_POSITION_INT: its clock (ms), east, north, up (m), its mode, the
/// threat level of its last COLLISION report.
type TrackPoint = (u32, (f64, f64, f64), u32, u8);

/// What the test's GCS heard from the copter.
#[derive(Debug, Default, Clone)]
struct Heard {
    armed: bool,
    time_boot_ms: u32,
    /// East, north of the origin (metres, WGS84 radii of curvature), relative altitude (m).
    east_north_up: Option<(f64, f64, f64)>,
    texts: Vec<String>,
    /// Flight modes the copter reported, in order (custom_mode; 4 GUIDED, 19 AVOID_ADSB).
    modes: Vec<u32>,
    /// COLLISION messages from the copter: (threat id, action, threat level).
    collisions: Vec<(u32, u8, u8)>,
    /// SYS_STATUS's proximity sensor: when its health changed, and to what.
    proximity_health: Vec<(Instant, bool)>,
    /// The copter's own DISTANCE_SENSOR (its proximity sectors and rangefinder, as it sees
    /// them): its clock (ms), orientation, current distance (cm).
    distance_sensors: Vec<(u32, u8, u16)>,
    /// RANGEFINDER's distance (m) beside the relative altitude (m) last heard with it.
    rangefinder: Vec<(f32, f64)>,
    /// At each GLOBAL_POSITION_INT: the copter's clock (ms), east, north, up (m), its mode
    /// and the threat level of its last COLLISION report.
    track: Vec<TrackPoint>,
}

/// The GCS on SITL's SERIAL1 (TCP 5762), as sysid 250: a reader thread and a writer.
struct Gcs {
    stream: TcpStream,
    seq: u8,
    heard: Arc<Mutex<Heard>>,
}

impl Gcs {
    fn connect() -> Gcs {
        let started = Instant::now();
        let stream = loop {
            match TcpStream::connect("127.0.0.1:5762") {
                Ok(s) => break s,
                Err(e) if started.elapsed() > Duration::from_secs(30) => {
                    panic!("SITL's SERIAL1 never answered: {e}")
                }
                Err(_) => std::thread::sleep(Duration::from_millis(200)),
            }
        };
        let heard = Arc::new(Mutex::new(Heard::default()));
        let (reader, into) = (stream.try_clone().unwrap(), heard.clone());
        std::thread::spawn(move || {
            let mut r = mavlink::MavlinkReader::new(reader);
            loop {
                match r.read_any_message::<MavMessage>() {
                    Ok((h, m)) if h.system_id == 1 => {
                        let mut heard = into.lock().unwrap();
                        match m {
                            MavMessage::HEARTBEAT(hb) if h.component_id == 1 => {
                                heard.armed = hb
                                    .base_mode
                                    .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                                if heard.modes.last() != Some(&hb.custom_mode) {
                                    heard.modes.push(hb.custom_mode);
                                }
                            }
                            MavMessage::SYS_STATUS(st) => {
                                let bit = MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_PROXIMITY;
                                let healthy = st.onboard_control_sensors_present.contains(bit)
                                    && st.onboard_control_sensors_health.contains(bit);
                                if heard.proximity_health.last().map(|h| h.1) != Some(healthy) {
                                    heard.proximity_health.push((Instant::now(), healthy));
                                }
                            }
                            MavMessage::DISTANCE_SENSOR(d) if h.component_id == 1 => {
                                heard.distance_sensors.push((
                                    d.time_boot_ms,
                                    d.orientation as u8,
                                    d.current_distance,
                                ));
                            }
                            MavMessage::RANGEFINDER(r) => {
                                if let Some(p) = heard.east_north_up {
                                    heard.rangefinder.push((r.distance, p.2));
                                }
                            }
                            MavMessage::COLLISION(c) => {
                                heard
                                    .collisions
                                    .push((c.id, c.action as u8, c.threat_level as u8));
                            }
                            MavMessage::GLOBAL_POSITION_INT(p) => {
                                heard.time_boot_ms = p.time_boot_ms;
                                let at = east_north(p.lat, p.lon, p.relative_alt);
                                heard.east_north_up = Some(at);
                                let mode = heard.modes.last().copied().unwrap_or(0);
                                let threat = heard.collisions.last().map_or(0, |c| c.2);
                                heard.track.push((p.time_boot_ms, at, mode, threat));
                            }
                            MavMessage::STATUSTEXT(t) => {
                                let text: String = t.text.to_str().unwrap_or("?").to_owned();
                                eprintln!("SITL: {text}");
                                heard.texts.push(text);
                            }
                            _ => {}
                        }
                    }
                    Ok(_) => {}
                    Err(mavlink::error::MessageReadError::Io(_)) => return,
                    Err(_) => {}
                }
            }
        });
        Gcs {
            stream,
            seq: 0,
            heard,
        }
    }

    fn send(&mut self, m: &MavMessage) {
        let _ = self.stream.write_all(&frame_v2(250, 190, self.seq, m));
        self.seq = self.seq.wrapping_add(1);
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7]) {
        self.send(&crate::sitl::command_long(command, p));
    }

    fn heard(&self) -> Heard {
        self.heard.lock().unwrap().clone()
    }

    /// Heartbeat and keep-alives until `done` says so or `limit` (wall clock) passes.
    fn until(&mut self, limit: Duration, mut step: impl FnMut(&mut Gcs) -> bool) -> bool {
        let started = Instant::now();
        while started.elapsed() < limit {
            self.send(&crate::common::heartbeat(
                mavlink::dialects::ardupilotmega::MavType::MAV_TYPE_GCS,
                mavlink::dialects::ardupilotmega::MavAutopilot::MAV_AUTOPILOT_INVALID,
            ));
            if step(self) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    }

    fn target(&mut self, type_mask: u16, p: [f32; 3], v: [f32; 3]) {
        self.send(&MavMessage::SET_POSITION_TARGET_LOCAL_NED(
            SET_POSITION_TARGET_LOCAL_NED_DATA {
                time_boot_ms: 0,
                x: p[0],
                y: p[1],
                z: p[2],
                vx: v[0],
                vy: v[1],
                vz: v[2],
                afx: 0.0,
                afy: 0.0,
                afz: 0.0,
                yaw: 0.0,
                yaw_rate: 0.0,
                type_mask: PositionTargetTypemask::from_bits_truncate(type_mask),
                target_system: 1,
                target_component: 1,
                coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            },
        ));
    }
}

/// East, north (m) of the scene's origin and up (m) for a GLOBAL_POSITION_INT: the WGS84
/// radii of curvature at the origin (exact to millimetres within 100 m; shares no code with
/// savsim's geodesy).
pub(crate) fn east_north(lat_e7: i32, lon_e7: i32, relative_alt_mm: i32) -> (f64, f64, f64) {
    let (a, e2) = (6_378_137.0f64, 6.694_379_990_14e-3);
    let phi = ORIGIN_LAT_DEG.to_radians();
    let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let (n_radius, m_radius) = (a / w, a * (1.0 - e2) / w.powi(3));
    let dlat = (f64::from(lat_e7) * 1e-7 - ORIGIN_LAT_DEG).to_radians();
    let dlon = (f64::from(lon_e7) * 1e-7 - ORIGIN_LON_DEG).to_radians();
    (
        dlon * n_radius * phi.cos(),
        dlat * m_radius,
        f64::from(relative_alt_mm) * 1e-3,
    )
}

/// savsim live over `scene` on `link` (on `rt`), with `feed` (if any) recorded to `feed_out`,
/// on a thread of its own until `limit` passes or `stop` is set. On the vehicle's clock (one
/// vehicle: `Session::use_vehicle_clock`): scripted traffic moves from the vehicle's boot on
/// its clock, at any speedup, as in `savsim study`.
pub(crate) fn start_savsim(
    rt: tokio::runtime::Runtime,
    link: Link,
    scene: Scene,
    feed: Option<&str>,
    limit: Duration,
    feed_out: &Path,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<LiveRun> {
    let mut session =
        Session::new(Some(Arc::new(scene)), CollisionConfig::default(), None).unwrap();
    session.use_vehicle_clock();
    if let Some(list) = feed {
        session
            .start_feed(FeedConfig {
                kinds: FeedKinds::parse(list).unwrap(),
                ..FeedConfig::default()
            })
            .unwrap();
    }
    let options = LiveOptions {
        duration: Some(limit),
        feed_out: feed.map(|_| feed_out.to_path_buf()),
        ..LiveOptions::default()
    };
    std::thread::spawn(move || {
        let handle = rt.handle().clone();
        let run = run_links(&handle, vec![link], &options, session, None, stop).unwrap();
        drop(rt);
        run
    })
}

/// A SITL flight under way: the copter, savsim live on its SERIAL0 (a thread), the test's GCS
/// on its SERIAL1.
struct Flight {
    gcs: Gcs,
    shutdown: Arc<AtomicBool>,
    savsim: Option<std::thread::JoinHandle<LiveRun>>,
    speedup: f64,
    /// savsim's `--feed-out`: every frame the feed sent.
    feed_out: PathBuf,
    _sitl: Sitl,
    _dir: tempfile::TempDir,
}

impl Flight {
    /// Start ArduCopter (home at the city's origin, facing west) with `params` on top of
    /// `SAVSIM_ARDUCOPTER_DEFAULTS`, and savsim over `scene` with `feed` (if any).
    fn start(
        bin: &PathBuf,
        params: &str,
        scene: Scene,
        feed: Option<&str>,
        speedup: f64,
    ) -> Flight {
        let dir = tempfile::tempdir().unwrap();
        let extra = dir.path().join("extra.parm");
        std::fs::write(&extra, params).unwrap();
        let mut defaults = std::env::var("SAVSIM_ARDUCOPTER_DEFAULTS").unwrap_or_default();
        if !defaults.is_empty() {
            defaults.push(',');
        }
        defaults.push_str(extra.to_str().unwrap());
        let rt = runtime();
        let (link, savsim) = udp_link(&rt);
        let sitl = Sitl(
            Command::new(bin)
                .current_dir(dir.path())
                .args(["--model", "+", "--speedup", &speedup.to_string(), "--wipe"])
                .args(["-I", "0", "--home", "-35.363261,149.165230,584,270"])
                .args([
                    "--serial0",
                    &format!("udpclient:127.0.0.1:{}", savsim.port()),
                ])
                .args(["--defaults", &defaults])
                .stdout(
                    std::fs::File::create(dir.path().join("sitl.log"))
                        .map_or(Stdio::null(), Stdio::from),
                )
                .stderr(Stdio::null())
                .spawn()
                .expect("start ArduCopter SITL"),
        );
        let shutdown = Arc::new(AtomicBool::new(false));
        // The longest flight is 250 s of the vehicle's clock; a loaded machine may run SITL
        // at well below its speedup.
        let limit = Duration::from_secs_f64(600.0 / speedup + 120.0);
        let feed_out = dir.path().join("feed.tlog");
        let savsim = start_savsim(rt, link, scene, feed, limit, &feed_out, shutdown.clone());
        Flight {
            gcs: Gcs::connect(),
            shutdown,
            savsim: Some(savsim),
            speedup,
            feed_out,
            _sitl: sitl,
            _dir: dir,
        }
    }

    /// The wall-clock deadline for `s` seconds of the vehicle's clock: twice its time at the
    /// speedup and 30 s more (a loaded machine runs SITL below its speedup). A deadline, never
    /// a duration: every wait ends on a condition.
    fn wall(&self, s: f64) -> Duration {
        Duration::from_secs_f64(2.0 * s / self.speedup + 30.0)
    }

    /// Hover for `s` seconds of the vehicle's clock (heartbeats; `ask` at each step of the
    /// first second of wall time).
    fn hover_for(&mut self, s: f64, mut ask: impl FnMut(&mut Gcs)) {
        let from_ms = self.gcs.heard().time_boot_ms;
        let started = Instant::now();
        let limit = self.wall(s);
        let done = self.gcs.until(limit, |g| {
            if started.elapsed() < Duration::from_secs(1) {
                ask(g);
            }
            g.heard().time_boot_ms.wrapping_sub(from_ms) >= (s * 1000.0) as u32
        });
        assert!(
            done,
            "{s} s of the vehicle's clock did not pass in {limit:?}"
        );
    }

    /// GUIDED, armed (ArduPilot refuses until its GPS is good and, with a proximity sensor
    /// configured, until the feed flows), up to `up_m`, then to (`north_m`, `east_m`).
    fn take_off_to(&mut self, up_m: f32, north_m: f32, east_m: f32) {
        let (armed_within, leg) = (self.wall(120.0), self.wall(40.0));
        let every = Duration::from_secs_f64(2.0 / self.speedup);
        let mut asked = Instant::now() - Duration::from_secs(10);
        let armed = self.gcs.until(armed_within, |g| {
            if g.heard().armed {
                return true;
            }
            if asked.elapsed() > every {
                asked = Instant::now();
                // Positions at 10 Hz on SERIAL1, GUIDED, arm.
                g.command(
                    MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                    [33.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                );
                g.command(
                    MavCmd::MAV_CMD_DO_SET_MODE,
                    [1.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                );
                g.command(
                    MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                );
            }
            false
        });
        assert!(armed, "never armed: {:?}", self.gcs.heard().texts);
        self.gcs.command(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, up_m],
        );
        let up = self.gcs.until(leg, |g| {
            g.heard()
                .east_north_up
                .is_some_and(|p| p.2 > f64::from(up_m) - 1.0)
        });
        assert!(up, "never reached {up_m} m: {:?}", self.gcs.heard());
        // A position target, NED about the EKF origin (home: the scene's origin).
        let position_only = 0b0000_1101_1111_1000;
        let there = self.gcs.until(leg, |g| {
            g.target(position_only, [north_m, east_m, -up_m], [0.0; 3]);
            g.heard().east_north_up.is_some_and(|p| {
                (p.1 - f64::from(north_m)).abs() < 1.0 && (p.0 - f64::from(east_m)).abs() < 1.0
            })
        });
        assert!(
            there,
            "never reached N {north_m} E {east_m}: {:?}",
            self.gcs.heard().east_north_up
        );
    }

    /// Stop savsim (SITL goes on); savsim's run.
    fn stop_savsim(&mut self) -> LiveRun {
        self.shutdown.store(true, Ordering::Relaxed);
        let mut run = self.savsim.take().expect("savsim runs").join().unwrap();
        run.session.finish().unwrap();
        run
    }

    /// Stop savsim and SITL; savsim's run.
    fn finish(mut self) -> LiveRun {
        self.stop_savsim()
    }
}

/// Fly the wall scenario with or without the feed; returns where the copter ended (E, N, U),
/// savsim's collisions and near misses.
fn fly(bin: &PathBuf, with_feed: bool, speedup: f64) -> ((f64, f64, f64), u64, u64) {
    // Without the feed, no proximity sensor is configured (ArduPilot would refuse to arm with
    // "PRX1: No Data"); the avoidance settings are the same.
    let proximity = if with_feed {
        "PRX1_TYPE 2\nPRX_FILT 0\n"
    } else {
        ""
    };
    let params = format!("{proximity}AVOID_ENABLE 3\nAVOID_BEHAVE 1\nAVOID_MARGIN 3\n");
    let city = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let feed = with_feed.then_some("proximity");
    let mut flight = Flight::start(bin, &params, city, feed, speedup);
    flight.take_off_to(30.0, -30.0, 0.0);
    // West at 5 m/s for 25 s of the vehicle's clock (re-sent at 10 Hz: GUIDED's velocity
    // targets time out after 3 s).
    let velocity_only = 0b0000_1101_1100_0111;
    let from_ms = flight.gcs.heard().time_boot_ms;
    let leg = flight.wall(25.0);
    flight.gcs.until(leg, |g| {
        g.target(velocity_only, [0.0; 3], [0.0, -5.0, 0.0]);
        g.heard().time_boot_ms.wrapping_sub(from_ms) > 25_000
    });
    let end = flight.gcs.heard().east_north_up.unwrap();
    let run = flight.finish();
    let totals = run.session.pipeline().unwrap().totals().clone();
    let summary = run.session.summary("live", "sitl");
    eprintln!(
        "feed {with_feed}, speedup {speedup}: ended at E {:.2} N {:.2} U {:.2}; collisions {}, near misses {}; feed {}; link feed {}",
        end.0,
        end.1,
        end.2,
        totals.collisions,
        totals.near_misses,
        summary["feed"],
        serde_json::to_string(&run.report.feed).unwrap()
    );
    (end, totals.collisions, totals.near_misses)
}

#[test]
fn arducopter_stops_before_the_wall_with_the_feed_and_hits_it_without() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let speedup: f64 = std::env::var("SAVSIM_FEED_SPEEDUP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(SPEEDUP);
    let (end, collisions, near_misses) = fly(&bin, true, speedup);
    assert!(
        end.0 - FACE_EAST_M >= 1.0,
        "with the feed the copter stopped at E {:.2} m, {:.2} m from the face",
        end.0,
        end.0 - FACE_EAST_M
    );
    assert_eq!(collisions, 0);
    assert!(near_misses >= 1, "within 10 m of the face: a near miss");
    let (end, collisions, _) = fly(&bin, false, speedup);
    assert!(
        collisions >= 1,
        "without the feed: ended at {end:?} and no collision"
    );
}

/// ADS-B: an A320 crosses the hovering copter's position at its height, at 40 m/s; with
/// `--feed adsb`, ArduPilot (ADSB_TYPE=1, AVD_ENABLE=1, AVD_F_ACTION=3: move horizontally)
/// sees it, reports the threat (COLLISION about the airliner's ICAO address), takes its action
/// (mode AVOID_ADSB) and keeps them at least 50 m apart (savsim's closest approach).
/// `SAVSIM_AVD_F_ACTION=2` (climb or descend) runs the same flight with ArduPilot's vertical
/// action, which in the ArduPilot tried steers towards the threat's altitude
/// (docs/closed-loop.md): separation is then printed, not asserted. savsim runs on the
/// vehicle's clock, so the track moves at ArduCopter's speedup.
/// Open air at the city's origin; an A320 track waits 2.4 km east at 30 m until +100 s of
/// the flight's clock, then flies west through the origin at 40 m/s (overhead at +160 s).
pub(crate) fn airliner_through_the_origin() -> Scene {
    crate::common::scene_at(
        savsim::geo::Geodetic::new(ORIGIN_LAT_DEG, ORIGIN_LON_DEG, 584.0),
        "[[dynamic]]\nid = \"airliner\"\nkind = \"a320\"\nwaypoints = [\
         { t_s = 0.0, position_enu_m = [2400.0, 0.0, 30.0] }, \
         { t_s = 100.0, position_enu_m = [2400.0, 0.0, 30.0] }, \
         { t_s = 220.0, position_enu_m = [-2400.0, 0.0, 30.0] }]\n",
    )
}

#[test]
fn arducopter_avoids_a_scripted_airliner_sent_as_adsb() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let scene = airliner_through_the_origin();
    let action: u8 = std::env::var("SAVSIM_AVD_F_ACTION")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let params = format!("ADSB_TYPE 1\nAVD_ENABLE 1\nAVD_F_ACTION {action}\n");
    let mut flight = Flight::start(&bin, &params, scene, Some("adsb,collision"), SPEEDUP);
    flight.take_off_to(30.0, 0.0, 0.0);
    // Hover until the airliner has passed: +190 s of the vehicle's clock (the track's clock,
    // from its boot), 30 s after its closest approach; what ArduPilot did shows in savsim's
    // closest approach.
    let passed = flight
        .gcs
        .until(flight.wall(190.0), |g| g.heard().time_boot_ms > 190_000);
    assert!(passed, "the vehicle's clock never reached +190 s");
    let heard = flight.gcs.heard();
    let acted = heard.modes.contains(&19) && !heard.collisions.is_empty();
    let run = flight.finish();
    let summary = run.session.summary("live", "sitl");
    // Once a second of the copter's clock: where it was, its mode, the threat it reported.
    let mut last_s = 0;
    for (t_ms, p, mode, threat) in &heard.track {
        if t_ms / 1000 > last_s {
            last_s = t_ms / 1000;
            eprintln!(
                "t {:>6.1} s  E {:>7.2} N {:>7.2} U {:>6.2}  mode {mode:>2}  threat {threat}",
                f64::from(*t_ms) / 1e3,
                p.0,
                p.1,
                p.2
            );
        }
    }
    eprintln!(
        "modes {:?}, COLLISION from the copter {:?}, feed {}, link feed {}, approaches {}",
        heard.modes,
        &heard.collisions[..heard.collisions.len().min(5)],
        summary["feed"],
        serde_json::to_string(&run.report.feed).unwrap(),
        summary["approaches"]
    );
    assert!(
        acted,
        "ArduPilot did not act on the airliner: modes {:?}, {:?}",
        heard.modes, heard.texts
    );
    // The threat it reported is savsim's airliner (scene track 0: ICAO 0xF00000).
    assert!(
        heard.collisions.iter().any(|c| c.0 == 0xF0_0000),
        "{:?}",
        heard.collisions
    );
    let closest = summary["approaches"][0]["distance_m"].as_f64().unwrap();
    if action == 3 {
        assert!(
            closest >= 50.0,
            "the airliner passed {closest:.1} m from the copter"
        );
    }
}

/// ArduPilot's MAVProximity autotest, mirrored: with PRX1_TYPE=2, the copter on the ground at
/// the city's origin, its proximity sensor turns healthy (SYS_STATUS) within 5 s of savsim's
/// first feed frame and unhealthy within 1 s after savsim stops (ArduPilot's 500 ms timeout).
#[test]
fn arducopter_proximity_is_healthy_while_fed_and_not_after() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let city = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let mut flight = Flight::start(&bin, "PRX1_TYPE 2\n", city, Some("proximity"), 1.0);
    // SYS_STATUS at 10 Hz on SERIAL1; wait for the first position (savsim feeds from then on).
    let fed = flight.gcs.until(Duration::from_secs(60), |g| {
        g.command(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [1.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        g.command(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [33.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        g.heard().east_north_up.is_some()
    });
    assert!(fed, "no position from the copter");
    let healthy = flight.gcs.until(Duration::from_secs(10), |g| {
        g.heard().proximity_health.last().is_some_and(|h| h.1)
    });
    let heard = flight.gcs.heard();
    assert!(healthy, "proximity never healthy: {:?}", heard.texts);
    let became = heard.proximity_health.last().unwrap().0;
    // Fed for 10 s more; then savsim stops.
    flight.gcs.until(Duration::from_secs(10), |_| false);
    let run = flight.stop_savsim();
    let stopped = Instant::now();
    let unhealthy = flight.gcs.until(Duration::from_secs(5), |g| {
        g.heard().proximity_health.last().is_some_and(|h| !h.1)
    });
    let heard = flight.gcs.heard();
    let went = heard.proximity_health.last().unwrap().0;
    // The feed starts at the first position savsim accepts (after the GPS fix): its first frame
    // was `span_ms` of the vehicle's clock (speedup 1: the wall clock) before it stopped.
    let feed = run.session.summary("live", "sitl")["feed"].clone();
    let span_ms = feed["vehicles"][0]["counts"]["span_ms"].as_u64().unwrap();
    let first_frame = stopped - Duration::from_millis(span_ms);
    let to_healthy = became.saturating_duration_since(first_frame);
    eprintln!(
        "proximity healthy {:.2} s after the first feed frame; unhealthy {:.2} s after savsim stopped; health changes {:?}; feed {feed}",
        to_healthy.as_secs_f64(),
        went.saturating_duration_since(stopped).as_secs_f64(),
        heard.proximity_health.iter().map(|h| h.1).collect::<Vec<_>>(),
    );
    assert!(to_healthy < Duration::from_secs(5));
    assert!(unhealthy, "still healthy 5 s after the feed stopped");
    assert!(went.saturating_duration_since(stopped) < Duration::from_secs(1));
    drop(flight);
}

/// One OBSTACLE_DISTANCE savsim sent: vehicle clock (ms), its 72 distances, min cm, max cm,
/// angle_offset.
pub(crate) type ObstacleFrame = (u32, [u16; 72], u16, u16, f32);

/// One DISTANCE_SENSOR savsim sent: vehicle clock (ms), orientation, distance cm, min cm,
/// max cm.
type SensorReading = (u32, u8, u16, u16, u16);

/// The feed savsim sent, from its `--feed-out` recording. Read with the mavlink crate.
pub(crate) fn sent_feed(bytes: &[u8]) -> (Vec<SensorReading>, Vec<ObstacleFrame>) {
    let (mut at, mut sensors, mut obstacles) = (0, Vec::new(), Vec::new());
    while at + 8 < bytes.len() {
        let frame = &bytes[at + 8..];
        let len = 12 + usize::from(frame[1]) + if frame[2] & 1 == 1 { 13 } else { 0 };
        let mut r = mavlink::MavlinkReader::new(&frame[..len]);
        match r.read_any_message::<MavMessage>() {
            Ok((_, MavMessage::DISTANCE_SENSOR(d))) => sensors.push((
                d.time_boot_ms,
                d.orientation as u8,
                d.current_distance,
                d.min_distance,
                d.max_distance,
            )),
            Ok((_, MavMessage::OBSTACLE_DISTANCE(o))) => {
                obstacles.push((
                    (o.time_usec / 1000) as u32,
                    o.distances,
                    o.min_distance,
                    o.max_distance,
                    o.angle_offset,
                ));
            }
            _ => {}
        }
        at += 8 + len;
    }
    (sensors, obstacles)
}

/// Hover near b1852's east face (N -30, E -45, 30 m up, nose west: the face 12 m ahead) with
/// the feed `feed` and `params`, asking for the copter's DISTANCE_SENSOR; what the copter said
/// and savsim's recording of what it sent.
fn hover_by_the_face(bin: &PathBuf, params: &str, feed: &str) -> (Heard, Vec<u8>) {
    let city = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let mut flight = Flight::start(bin, params, city, Some(feed), SPEEDUP);
    flight.take_off_to(30.0, -30.0, -45.0);
    // Its DISTANCE_SENSOR at 10 Hz on SERIAL1; 15 s of hovering.
    flight.hover_for(15.0, |g| {
        g.command(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [132.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
    });
    let heard = flight.gcs.heard();
    let path = flight.feed_out.clone();
    // Stopping savsim flushes its recording; read it before the flight's directory goes.
    flight.stop_savsim();
    (heard, std::fs::read(path).unwrap())
}

/// Every echo of the copter's proximity sectors in the last 10 s, against what savsim sent in
/// the 600 ms of the copter's clock before it: the closest sent value per echo, per sector.
fn echoes_against(heard: &Heard, sent: impl Fn(u32, u8) -> Vec<u16>) -> (usize, Vec<String>) {
    let last_ms = heard.distance_sensors.last().map_or(0, |d| d.0);
    let (mut checked, mut wrong) = (0, Vec::new());
    for &(t_ms, orientation, cm) in &heard.distance_sensors {
        if orientation > 7 || t_ms + 10_000 < last_ms {
            continue;
        }
        let candidates = sent(t_ms, orientation);
        let Some(closest) = candidates.iter().map(|&s| s.abs_diff(cm)).min() else {
            continue;
        };
        checked += 1;
        if closest > 1 {
            wrong.push(format!(
                "sector {orientation} at {t_ms} ms: echoed {cm} cm, sent {candidates:?}"
            ));
        }
    }
    (checked, wrong)
}

/// ArduPilot's MAVProximity autotest, its echo half: the copter reports back each proximity
/// sector it was fed (its own DISTANCE_SENSOR, orientations 0-7) within 1 cm of what savsim
/// sent for that sector.
#[test]
fn arducopter_echoes_every_sector_it_was_fed_within_a_centimetre() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let (heard, feed_out) = hover_by_the_face(&bin, "PRX1_TYPE 2\nPRX_FILT 0\n", "proximity");
    let (sent, _) = sent_feed(&feed_out);
    let (checked, wrong) = echoes_against(&heard, |t_ms, orientation| {
        sent.iter()
            .filter(|s| s.1 == orientation && s.0 <= t_ms && s.0 + 600 >= t_ms && s.2 <= s.4)
            .map(|s| s.2)
            .collect()
    });
    let sectors: std::collections::BTreeSet<u8> = heard
        .distance_sensors
        .iter()
        .map(|d| d.1)
        .filter(|&o| o <= 7)
        .collect();
    eprintln!(
        "{checked} echoes checked, sectors {sectors:?}, {} wrong",
        wrong.len()
    );
    assert!(checked >= 50, "too few echoes: {checked}");
    assert!(
        sectors.contains(&0),
        "the face ahead (sector 0) was echoed: {sectors:?}"
    );
    assert!(wrong.is_empty(), "{wrong:?}");
}

/// ArduPilot's OBSTACLE_DISTANCE_3D autotest, for the 72-bin OBSTACLE_DISTANCE savsim sends:
/// the copter's proximity sectors (its DISTANCE_SENSOR echo) are, within 1 cm, the nearest of
/// savsim's bins whose angle falls in each 45-degree sector (body FRD, clockwise from the nose).
#[test]
fn arducopter_reads_obstacle_distance_bins_into_its_sectors() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let (heard, feed_out) =
        hover_by_the_face(&bin, "PRX1_TYPE 2\nPRX_FILT 0\n", "obstacle-distance");
    let (_, sent) = sent_feed(&feed_out);
    // The nearest in-range bin of sector k: bin j at angle_offset + 5 j degrees clockwise,
    // in sector (angle + 22.5) / 45 (ArduPilot's AP_Proximity_Boundary_3D::get_face).
    let sector_of = |frame: &ObstacleFrame, k: u8| {
        (0..72)
            .filter(|&j| {
                let angle = (f64::from(frame.4) + 5.0 * j as f64).rem_euclid(360.0);
                ((angle + 22.5) / 45.0).floor() as u8 % 8 == k
            })
            .map(|j| frame.1[j])
            .filter(|&d| d != 65535 && d >= frame.2 && d <= frame.3)
            .min()
    };
    // OBSTACLE_DISTANCE carries time_usec: savsim stamps it with the vehicle's clock.
    let (checked, wrong) = echoes_against(&heard, |t_ms, orientation| {
        sent.iter()
            .filter(|s| s.0 <= t_ms && s.0 + 600 >= t_ms)
            .filter_map(|s| sector_of(s, orientation))
            .collect()
    });
    eprintln!(
        "{checked} echoes checked, {} wrong, {} frames sent",
        wrong.len(),
        sent.len()
    );
    assert!(checked >= 50, "too few echoes: {checked}");
    assert!(wrong.is_empty(), "{wrong:?}");
}

/// ArduPilot's FlyRangeFinderMAVlink autotest: with RNGFND1_TYPE=10 and savsim's
/// `--feed rangefinder`, the copter's rangefinder (RANGEFINDER) agrees with its altitude above
/// home (GLOBAL_POSITION_INT.relative_alt) within 1 m while it hovers over the street at the
/// city's origin, and its own DISTANCE_SENSOR (downward) says the same.
#[test]
fn arducopter_rangefinder_agrees_with_its_altitude() {
    let Some(Turn { bin, .. }) = sitl_test(Autopilot::ArduCopter, Netns::Own, &[]) else {
        return;
    };
    let city = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let params = "RNGFND1_TYPE 10\nRNGFND1_MIN 0.2\nRNGFND1_MAX 40\n";
    let mut flight = Flight::start(&bin, params, city, Some("rangefinder"), SPEEDUP);
    flight.take_off_to(10.0, 0.0, 0.0);
    flight.hover_for(8.0, |g| {
        for id in [173.0, 132.0] {
            g.command(
                MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                [id, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            );
        }
    });
    let heard = flight.gcs.heard();
    drop(flight);
    let late: Vec<&(f32, f64)> = heard.rangefinder.iter().rev().take(40).collect();
    let worst = late
        .iter()
        .map(|(d, alt)| (f64::from(*d) - alt).abs())
        .fold(0.0, f64::max);
    let downward: Vec<u16> = heard
        .distance_sensors
        .iter()
        .filter(|d| d.1 == 25)
        .map(|d| d.2)
        .collect();
    eprintln!(
        "RANGEFINDER against relative_alt over the last {} readings: worst {worst:.2} m; last {:?}; downward DISTANCE_SENSOR last {:?}",
        late.len(),
        late.first(),
        downward.last()
    );
    assert!(late.len() >= 20, "too few RANGEFINDER readings");
    assert!(worst <= 1.0);
    let alt = late[0].1;
    let last_cm = *downward
        .last()
        .expect("the copter's downward DISTANCE_SENSOR");
    assert!(
        (f64::from(last_cm) / 100.0 - alt).abs() <= 1.0,
        "{last_cm} cm at {alt} m"
    );
}
