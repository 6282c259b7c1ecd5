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
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{
    MavCmd, MavFrame, MavMessage, MavModeFlag, PositionTargetTypemask, COMMAND_LONG_DATA,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use savsim::app::live::{run_links, LiveOptions};
use savsim::collision::pipeline::CollisionConfig;
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::session::Session;

use crate::common::{frame_v2, root, runtime, udp_link};
use crate::sitl::{inside_own_network_namespace, Sitl};

/// b1852's east face, scene E metres.
const FACE_EAST_M: f64 = -57.0;
const ORIGIN_LAT_DEG: f64 = -35.363261;
const ORIGIN_LON_DEG: f64 = 149.165230;

/// What the test's GCS heard from the copter.
#[derive(Debug, Default, Clone)]
struct Heard {
    armed: bool,
    time_boot_ms: u32,
    /// East, north of the origin (metres, WGS84 radii of curvature), relative altitude (m).
    east_north_up: Option<(f64, f64, f64)>,
    texts: Vec<String>,
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
                            }
                            MavMessage::GLOBAL_POSITION_INT(p) => {
                                heard.time_boot_ms = p.time_boot_ms;
                                heard.east_north_up =
                                    Some(east_north(p.lat, p.lon, p.relative_alt));
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
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
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
        }));
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
fn east_north(lat_e7: i32, lon_e7: i32, relative_alt_mm: i32) -> (f64, f64, f64) {
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

/// Fly the scenario with or without the feed; returns where the copter ended (E, N, U) and
/// savsim's collisions.
fn fly(bin: &PathBuf, with_feed: bool, speedup: f64) -> ((f64, f64, f64), u64, u64) {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("feed.parm");
    // Without the feed, no proximity sensor is configured (ArduPilot would refuse to arm with
    // "PRX1: No Data"); the avoidance settings are the same.
    let proximity = if with_feed {
        "PRX1_TYPE 2\nPRX_FILT 0\n"
    } else {
        ""
    };
    std::fs::write(
        &params,
        format!("{proximity}AVOID_ENABLE 3\nAVOID_BEHAVE 1\nAVOID_MARGIN 3\n"),
    )
    .unwrap();
    let mut defaults = std::env::var("SAVSIM_ARDUCOPTER_DEFAULTS").unwrap_or_default();
    if !defaults.is_empty() {
        defaults.push(',');
    }
    defaults.push_str(params.to_str().unwrap());
    let rt = runtime();
    let (link, savsim) = udp_link(&rt);
    let _sitl = Sitl(
        Command::new(bin)
            .current_dir(dir.path())
            .args([
                "--model",
                "+",
                "--speedup",
                &speedup.to_string(),
                "--wipe",
                "-I",
                "0",
            ])
            .args(["--home", "-35.363261,149.165230,584,270"])
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
    let scene = Arc::new(savsim::scene::load(&root().join("scenes/city.toml")).unwrap());
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    if with_feed {
        session
            .start_feed(FeedConfig {
                kinds: FeedKinds::parse("proximity").unwrap(),
                ..FeedConfig::default()
            })
            .unwrap();
    }
    let shutdown = Arc::new(AtomicBool::new(false));
    let stop = shutdown.clone();
    let limit = Duration::from_secs_f64(240.0 / speedup + 30.0);
    let savsim_thread = std::thread::spawn(move || {
        let options = LiveOptions {
            duration: Some(limit),
            ..LiveOptions::default()
        };
        let handle = rt.handle().clone();
        let run = run_links(&handle, vec![link], &options, session, None, stop).unwrap();
        drop(rt);
        run
    });
    let mut gcs = Gcs::connect();
    let wall = |s: f64| Duration::from_secs_f64(s / speedup + 5.0);
    // Streams on SERIAL1: positions at 10 Hz.
    gcs.command(
        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        [33.0, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    );
    // GUIDED and armed: ArduPilot refuses to arm until the GPS is good (and, with the
    // proximity sensor configured, until the feed flows).
    let mut asked = Instant::now() - Duration::from_secs(10);
    let armed = gcs.until(wall(120.0), |g| {
        if g.heard().armed {
            return true;
        }
        if asked.elapsed() > Duration::from_secs_f64(2.0 / speedup) {
            asked = Instant::now();
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
    assert!(armed, "never armed: {:?}", gcs.heard().texts);
    gcs.command(
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 30.0],
    );
    let up = gcs.until(wall(40.0), |g| {
        g.heard().east_north_up.is_some_and(|p| p.2 > 29.0)
    });
    assert!(up, "never reached 30 m: {:?}", gcs.heard());
    // To N -30 m (position target, NED about the EKF origin, which is home: the origin).
    let position_only = 0b0000_1101_1111_1000;
    let there = gcs.until(wall(40.0), |g| {
        g.target(position_only, [-30.0, 0.0, -30.0], [0.0; 3]);
        g.heard()
            .east_north_up
            .is_some_and(|p| (p.1 + 30.0).abs() < 1.0 && p.0.abs() < 1.0)
    });
    assert!(
        there,
        "never reached N -30 m: {:?}",
        gcs.heard().east_north_up
    );
    // West at 5 m/s for 25 s of the vehicle's clock (re-sent at 10 Hz: GUIDED's velocity
    // targets time out after 3 s).
    let velocity_only = 0b0000_1101_1100_0111;
    let from_ms = gcs.heard().time_boot_ms;
    gcs.until(wall(25.0), |g| {
        g.target(velocity_only, [0.0; 3], [0.0, -5.0, 0.0]);
        g.heard().time_boot_ms.wrapping_sub(from_ms) > 25_000
    });
    let end = gcs.heard().east_north_up.unwrap();
    shutdown.store(true, Ordering::Relaxed);
    let mut run = savsim_thread.join().unwrap();
    run.session.finish().unwrap();
    let totals = run.session.pipeline.as_ref().unwrap().totals.clone();
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
    let Some(bin) = std::env::var_os("SAVSIM_ARDUCOPTER").map(PathBuf::from) else {
        eprintln!("skipped: set SAVSIM_ARDUCOPTER to an ArduCopter SITL binary (docs/live.md)");
        return;
    };
    if !inside_own_network_namespace(
        "sitl_feed::arducopter_stops_before_the_wall_with_the_feed_and_hits_it_without",
    ) {
        return;
    }
    let speedup: f64 = std::env::var("SAVSIM_FEED_SPEEDUP")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
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
