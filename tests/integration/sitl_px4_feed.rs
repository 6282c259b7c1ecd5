//! The closed loop against PX4 SITL with its SIH simulator (docs/closed-loop.md): savsim's
//! `--feed obstacle-distance` from the bundled city is PX4's obstacle distance, and PX4's
//! collision prevention (CP_DIST) keeps a quadrotor flown at a building's face in Position
//! mode from closing on it. Needs `SAVSIM_PX4` (as `sitl_px4`); runs in a network namespace of
//! its own.
//!
//! The flight: home at N -30 m of the city's origin, take off to 30 m, turn west
//! (DO_REPOSITION's yaw), Position mode, then the pitch stick forward for 25 s towards building
//! b1852, whose east face is at E -57 m (N -90 to -10 m, 67 m high). The test is the pilot: a
//! ground station (250/190) on PX4's onboard link (UDP 14580 <-> 14540) sending MANUAL_CONTROL
//! at 20 Hz (PX4 SITL's COM_RC_IN_MODE 1: joystick), while savsim is on PX4's GCS link
//! (127.0.0.1:14550). With CP_DIST 5 and the feed, the copter must stay at least 1 m from the
//! face, savsim report no collision, and PX4's own OBSTACLE_DISTANCE (its fused map, streamed
//! on the onboard link) be savsim's bins; without the feed (CP_DIST off: with it on and no
//! data PX4 refuses to move), savsim reports the collision.
//!
//! Traffic: with `--feed adsb` and NAV_TRAFF_AVOID 3, PX4 lands for a scripted airliner on a
//! collision course, and the ADS-B it relays back is not read as traffic. The PX4 tests take
//! turns (`sitl_px4::px4_inside_own_namespace`).

use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavCmd, MavFrame, MavMessage, MavModeFlag, MavParamType, MavType,
    COMMAND_INT_DATA, MANUAL_CONTROL_DATA, PARAM_SET_DATA,
};
use savsim::ingest::address::ConnectAddress;
use savsim::ingest::live::Link;
use savsim::live::LiveRun;
use savsim::scene::Scene;

use crate::common::{frame_v2, heartbeat, root, runtime};
use crate::sitl::Sitl;
use crate::sitl_feed::{
    airliner_through_the_origin, east_north, sent_feed, start_savsim, ObstacleFrame,
};
use crate::sitl_px4::{near_origin_deg, px4_inside_own_namespace, start_px4};

/// b1852's east face, scene E metres; where the flight starts, scene N metres.
const FACE_EAST_M: f64 = -57.0;
const START_NORTH_M: f64 = -30.0;
/// PX4's main modes (custom_mode's third byte): POSCTL, AUTO; AUTO's sub mode LAND (its
/// fourth byte).
const POSCTL: u32 = 3;
const AUTO: u32 = 4;
const AUTO_LAND: u32 = 6;

/// What the pilot heard from PX4 (1/1) on the onboard link.
#[derive(Debug, Default, Clone)]
struct Heard {
    armed: bool,
    custom_mode: u32,
    /// Every custom_mode PX4 reported, in order (main mode in byte 2, sub mode in byte 3).
    modes: Vec<u32>,
    /// East, north, up (m) of the city's origin, PX4's clock (ms) and heading (cdeg).
    position: Option<(f64, f64, f64)>,
    time_boot_ms: u32,
    heading_cdeg: u16,
    /// Every position once the test starts recording (the stick forward; the traffic hover).
    track: Vec<(f64, f64, f64)>,
    /// PX4's OBSTACLE_DISTANCE (its fused map): its clock (ms), distances, angle_offset.
    obstacle: Vec<(u32, [u16; 72], f32)>,
    texts: Vec<String>,
}

/// A PX4 parameter's value.
#[derive(Clone, Copy)]
enum Param {
    Real(f32),
    Int(i32),
}

/// The pilot: a ground station on PX4's onboard link, a reader thread and a writer.
struct Pilot {
    socket: UdpSocket,
    to: SocketAddr,
    sequence: u8,
    heard: Arc<Mutex<Heard>>,
    recording: Arc<AtomicBool>,
}

impl Pilot {
    fn connect() -> Pilot {
        // PX4's onboard link sends to 14540 (the last flight's pilot may still be letting go).
        let started = Instant::now();
        let socket = loop {
            match UdpSocket::bind("127.0.0.1:14540") {
                Ok(s) => break s,
                Err(e) if started.elapsed() > Duration::from_secs(5) => panic!("UDP 14540: {e}"),
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        socket
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        let heard = Arc::new(Mutex::new(Heard::default()));
        let recording = Arc::new(AtomicBool::new(false));
        let (reader, into, track) = (
            socket.try_clone().unwrap(),
            heard.clone(),
            recording.clone(),
        );
        std::thread::spawn(move || {
            let mut buffer = [0u8; 2048];
            loop {
                let Ok(n) = reader.recv(&mut buffer) else {
                    if Arc::strong_count(&into) == 1 {
                        return;
                    }
                    continue;
                };
                let mut r = mavlink::MavlinkReader::new(&buffer[..n]);
                while let Ok((h, m)) = r.read_any_message::<MavMessage>() {
                    if (h.system_id, h.component_id) != (1, 1) {
                        continue;
                    }
                    let mut heard = into.lock().unwrap();
                    match m {
                        MavMessage::HEARTBEAT(hb) => {
                            heard.armed = hb
                                .base_mode
                                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                            heard.custom_mode = hb.custom_mode;
                            if heard.modes.last() != Some(&hb.custom_mode) {
                                heard.modes.push(hb.custom_mode);
                            }
                        }
                        MavMessage::GLOBAL_POSITION_INT(p) => {
                            let at = east_north(p.lat, p.lon, p.relative_alt);
                            heard.position = Some(at);
                            heard.time_boot_ms = p.time_boot_ms;
                            heard.heading_cdeg = p.hdg;
                            if track.load(Ordering::Relaxed) {
                                heard.track.push(at);
                            }
                        }
                        MavMessage::OBSTACLE_DISTANCE(o) => {
                            let ms = (o.time_usec / 1000) as u32;
                            heard.obstacle.push((ms, o.distances, o.angle_offset));
                        }
                        MavMessage::STATUSTEXT(t) => {
                            let text = t.text.to_str().unwrap_or("?").to_owned();
                            eprintln!("PX4: {text}");
                            heard.texts.push(text);
                        }
                        _ => {}
                    }
                }
            }
        });
        Pilot {
            socket,
            to: "127.0.0.1:14580".parse().unwrap(),
            sequence: 0,
            heard,
            recording,
        }
    }

    fn send(&mut self, m: &MavMessage) {
        let _ = self
            .socket
            .send_to(&frame_v2(250, 190, self.sequence, m), self.to);
        self.sequence = self.sequence.wrapping_add(1);
    }

    fn command(&mut self, command: MavCmd, p: [f32; 7]) {
        self.send(&crate::sitl::command_long(command, p));
    }

    fn param(&mut self, name: &str, value: Param) {
        // PX4 encodes parameters bytewise: an integer's bits travel in the float field.
        let (param_value, param_type) = match value {
            Param::Real(v) => (v, MavParamType::MAV_PARAM_TYPE_REAL32),
            Param::Int(v) => (f32::from_bits(v as u32), MavParamType::MAV_PARAM_TYPE_INT32),
        };
        self.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value,
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
            param_type,
        }));
    }

    fn heard(&self) -> Heard {
        self.heard.lock().unwrap().clone()
    }

    /// At 20 Hz until `done` says so or `limit` passes: MANUAL_CONTROL with the pitch stick at
    /// `pitch` (-1000..1000, forward positive; throttle centred), a heartbeat each second.
    fn until(
        &mut self,
        limit: Duration,
        pitch: i16,
        mut step: impl FnMut(&mut Pilot, &Heard) -> bool,
    ) -> bool {
        let started = Instant::now();
        let mut beat = started - Duration::from_secs(1);
        while started.elapsed() < limit {
            if beat.elapsed() >= Duration::from_secs(1) {
                beat = Instant::now();
                self.send(&heartbeat(
                    MavType::MAV_TYPE_GCS,
                    MavAutopilot::MAV_AUTOPILOT_INVALID,
                ));
            }
            self.send(&MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA {
                x: pitch,
                z: 500,
                target: 1,
                ..MANUAL_CONTROL_DATA::default()
            }));
            let heard = self.heard();
            if step(self, &heard) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        false
    }
}

/// A PX4 flight under way: the quadrotor, savsim live on its GCS link (a thread), the pilot on
/// its onboard link.
struct Flight {
    pilot: Pilot,
    shutdown: Arc<AtomicBool>,
    savsim: std::thread::JoinHandle<LiveRun>,
    /// savsim's `--feed-out`: every frame the feed sent.
    feed_out: PathBuf,
    /// When savsim's run began (a scripted track's clock).
    began: Instant,
    _px4: Sitl,
    _dir: tempfile::TempDir,
}

impl Flight {
    /// savsim over `scene` with `feed` (if any), then PX4 with home `north_m` north of the
    /// city's origin.
    fn start(bin: &Path, scene: Scene, feed: Option<&str>, north_m: f64) -> Flight {
        let dir = tempfile::tempdir().unwrap();
        let rt = runtime();
        let gcs: SocketAddr = "127.0.0.1:14550".parse().unwrap();
        let link = rt
            .block_on(Link::open(&ConnectAddress::UdpIn(gcs.into())))
            .unwrap();
        let feed_out = dir.path().join("feed.tlog");
        let shutdown = Arc::new(AtomicBool::new(false));
        let began = Instant::now();
        let limit = Duration::from_secs(300);
        let savsim = start_savsim(rt, link, scene, feed, limit, &feed_out, shutdown.clone());
        let px4 = start_px4(bin, 0, &dir.path().join("px4"), north_m, 0.0);
        Flight {
            pilot: Pilot::connect(),
            shutdown,
            savsim,
            feed_out,
            began,
            _px4: px4,
            _dir: dir,
        }
    }

    /// Positions and PX4's obstacle map at 10 Hz on the pilot's link, `params`, then armed and
    /// taken off to 30 m (MIS_TAKEOFF_ALT; PX4 holds there).
    fn take_off(&mut self, params: &[(&str, Param)]) {
        let pilot = &mut self.pilot;
        let mut asked = Instant::now() - Duration::from_secs(10);
        let armed = pilot.until(Duration::from_secs(90), 0, |p, h| {
            if h.armed {
                return true;
            }
            if asked.elapsed() > Duration::from_secs(2) && h.position.is_some() {
                asked = Instant::now();
                for id in [33.0, 330.0] {
                    p.command(
                        MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                        [id, 100_000.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                    );
                }
                for &(name, value) in params
                    .iter()
                    .chain(&[("MIS_TAKEOFF_ALT", Param::Real(30.0))])
                {
                    p.param(name, value);
                }
                p.command(
                    MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                );
            }
            false
        });
        assert!(armed, "PX4 never armed: {:?}", pilot.heard().texts);
        let nan = f32::NAN;
        let mut asked = Instant::now() - Duration::from_secs(10);
        let up = pilot.until(Duration::from_secs(60), 0, |p, h| {
            if asked.elapsed() > Duration::from_secs(3) && h.position.is_some_and(|q| q.2 < 5.0) {
                asked = Instant::now();
                p.command(
                    MavCmd::MAV_CMD_NAV_TAKEOFF,
                    [nan, 0.0, 0.0, nan, nan, nan, nan],
                );
            }
            h.position.is_some_and(|q| q.2 > 29.0)
        });
        assert!(up, "never reached 30 m: {:?}", pilot.heard());
    }

    /// Stop savsim and PX4: what the pilot heard, savsim's run, the OBSTACLE_DISTANCE frames
    /// it sent.
    fn finish(self) -> (Heard, LiveRun, Vec<ObstacleFrame>) {
        let heard = self.pilot.heard();
        self.shutdown.store(true, Ordering::Relaxed);
        let mut run = self.savsim.join().unwrap();
        run.session.finish().unwrap();
        let sent = std::fs::read(&self.feed_out).map_or(Vec::new(), |b| sent_feed(&b).1);
        (heard, run, sent)
    }
}

/// Fly at the face with or without the feed: (PX4 heard, savsim's run, the feed it sent).
fn fly(bin: &Path, with_feed: bool) -> (Heard, LiveRun, Vec<ObstacleFrame>) {
    let city = savsim::scene::load(&root().join("scenes/city.toml")).unwrap();
    let feed = with_feed.then_some("obstacle-distance");
    let mut flight = Flight::start(bin, city, feed, START_NORTH_M);
    // Collision prevention on with the feed; off without (on, with no data, PX4 will not move).
    let cp_dist = if with_feed { 5.0 } else { -1.0 };
    flight.take_off(&[("CP_DIST", Param::Real(cp_dist))]);
    let pilot = &mut flight.pilot;
    // Hold there, nose west (DO_REPOSITION's yaw, radians from north).
    let (lat_deg, lon_deg) = near_origin_deg(START_NORTH_M, 0.0);
    let (lat_e7, lon_e7) = (
        (lat_deg * 1e7).round() as i32,
        (lon_deg * 1e7).round() as i32,
    );
    let mut asked = Instant::now() - Duration::from_secs(10);
    let west = pilot.until(Duration::from_secs(40), 0, |p, h| {
        if asked.elapsed() > Duration::from_secs(3) {
            asked = Instant::now();
            // PX4 answers MAV_FRAME_GLOBAL (0) in COMMAND_INT with UNSUPPORTED_MAV_FRAME:
            // it wants the older MAV_FRAME_GLOBAL_INT (5), deprecated in MAVLink since 2024.
            #[allow(deprecated)]
            let frame = MavFrame::MAV_FRAME_GLOBAL_INT;
            p.send(&MavMessage::COMMAND_INT(COMMAND_INT_DATA {
                param1: -1.0,
                param2: 1.0,
                param3: 0.0,
                param4: -std::f32::consts::FRAC_PI_2,
                x: lat_e7,
                y: lon_e7,
                z: 584.0 + 30.0,
                command: MavCmd::MAV_CMD_DO_REPOSITION,
                target_system: 1,
                target_component: 1,
                frame,
                current: 0,
                autocontinue: 0,
            }));
        }
        h.heading_cdeg.abs_diff(27_000) < 300 && h.position.is_some_and(|q| q.0.abs() < 2.0)
    });
    assert!(west, "never faced west at the start: {:?}", pilot.heard());
    // Position mode, sticks centred, then the pitch stick forward for 25 s of PX4's clock.
    let mut asked = Instant::now() - Duration::from_secs(10);
    let posctl = pilot.until(Duration::from_secs(20), 0, |p, h| {
        if asked.elapsed() > Duration::from_secs(2) {
            asked = Instant::now();
            p.command(
                MavCmd::MAV_CMD_DO_SET_MODE,
                [1.0, POSCTL as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
            );
        }
        (h.custom_mode >> 16) & 0xff == POSCTL
    });
    assert!(posctl, "never in Position mode: {:?}", pilot.heard().texts);
    pilot.recording.store(true, Ordering::Relaxed);
    let from_ms = pilot.heard().time_boot_ms;
    pilot.until(Duration::from_secs(35), 700, |_, h| {
        h.time_boot_ms.wrapping_sub(from_ms) > 25_000
    });
    flight.finish()
}

/// PX4's fused map is savsim's bins where both are in range: each map frame, turned by the
/// difference of the two `angle_offset`s (both multiples of 5 degrees: one bin to one bin),
/// against the frames savsim sent in the 600 ms of PX4's clock before it. Returns how many
/// map frames were checked and those no sent frame matches within 1 cm.
fn map_against_sent(heard: &Heard, sent: &[ObstacleFrame]) -> (usize, Vec<String>) {
    let (mut checked, mut wrong) = (0, Vec::new());
    for (t_ms, map, map_offset) in &heard.obstacle {
        if map.iter().all(|&d| d == u16::MAX) {
            continue;
        }
        let candidates: Vec<&ObstacleFrame> = sent
            .iter()
            .filter(|s| s.0 <= *t_ms && s.0 + 600 >= *t_ms)
            .collect();
        if candidates.is_empty() {
            continue;
        }
        checked += 1;
        let matches = |s: &&ObstacleFrame| {
            let shift = ((map_offset - s.4) / 5.0).round() as i64;
            (0..72).all(|i| {
                let j = (i as i64 + shift).rem_euclid(72) as usize;
                map[i] == u16::MAX || map[i].abs_diff(s.1[j]) <= 1
            })
        };
        if !candidates.iter().any(matches) {
            let nearest = map.iter().min().copied().unwrap_or(u16::MAX);
            wrong.push(format!(
                "map at {t_ms} ms (nearest {nearest} cm) matches none of {} sent frames",
                candidates.len()
            ));
        }
    }
    (checked, wrong)
}

#[test]
fn px4_keeps_its_distance_from_the_face_with_obstacle_distance_and_hits_it_without() {
    let test = "sitl_px4_feed::px4_keeps_its_distance_from_the_face_with_obstacle_distance_and_hits_it_without";
    let Some((bin, _serial)) = px4_inside_own_namespace(test) else {
        return;
    };
    let (heard, run, sent) = fly(&bin, true);
    let closest_east = heard.track.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let end = heard.position.unwrap();
    let totals = run.session.pipeline().unwrap().totals().clone();
    let (checked, wrong) = map_against_sent(&heard, &sent);
    let summary = run.session.summary("live", "sitl-px4");
    eprintln!(
        "with the feed: nearest the face at E {closest_east:.2} ({:.2} m short), ended at E {:.2} N {:.2} U {:.2}; collisions {}, near misses {}; {} frames sent, {} PX4 maps, {checked} checked, {} wrong; feed {}; link feed {}",
        closest_east - FACE_EAST_M,
        end.0,
        end.1,
        end.2,
        totals.collisions,
        totals.near_misses,
        sent.len(),
        heard.obstacle.len(),
        wrong.len(),
        summary["feed"],
        serde_json::to_string(&run.report.feed).unwrap()
    );
    assert!(
        heard.track.len() > 100,
        "positions while flying: {}",
        heard.track.len()
    );
    assert!(
        closest_east - FACE_EAST_M >= 1.0,
        "with the feed PX4 came to E {closest_east:.2}, {:.2} m from the face",
        closest_east - FACE_EAST_M
    );
    assert_eq!(totals.collisions, 0);
    assert!(checked >= 50, "PX4's obstacle map checked {checked} times");
    assert!(wrong.is_empty(), "{wrong:?}");

    let (heard, run, _) = fly(&bin, false);
    let end = heard.position.unwrap();
    let totals = run.session.pipeline().unwrap().totals().clone();
    eprintln!(
        "without the feed: ended at E {:.2} N {:.2} U {:.2}; collisions {}",
        end.0, end.1, end.2, totals.collisions
    );
    assert!(
        totals.collisions >= 1,
        "without the feed: ended at {end:?} and no collision"
    );
}

/// PX4's traffic avoidance on savsim's ADS-B: the quadrotor holds at 30 m over the city's
/// origin with NAV_TRAFF_AVOID 3 (land); an A320 track waits 2.4 km east at the same height
/// until +100 s of savsim's run, then flies west through the origin at 40 m/s. With
/// `--feed adsb`, PX4 must take the airliner for a conflict (its defaults: 500 m across, 500 m
/// up or down, 60 s ahead) and land; savsim's closest approach tells what that bought. PX4
/// re-streams the traffic it receives: savsim must not read it back (`adsb_echoes`).
#[test]
fn px4_lands_when_a_scripted_airliner_sent_as_adsb_closes() {
    let test = "sitl_px4_feed::px4_lands_when_a_scripted_airliner_sent_as_adsb_closes";
    let Some((bin, _serial)) = px4_inside_own_namespace(test) else {
        return;
    };
    let mut flight = Flight::start(&bin, airliner_through_the_origin(), Some("adsb"), 0.0);
    flight.take_off(&[("NAV_TRAFF_AVOID", Param::Int(3))]);
    flight.pilot.recording.store(true, Ordering::Relaxed);
    let started = Instant::now();
    // Until PX4 lands for the airliner, then until the airliner has passed (+190 s of
    // savsim's run, 30 s after it crossed the origin).
    let landing = flight.pilot.until(Duration::from_secs(150), 0, |_, h| {
        (h.custom_mode >> 16) & 0xff == AUTO && h.custom_mode >> 24 == AUTO_LAND
    });
    let landed_after = started.elapsed();
    if landing {
        let began = flight.began;
        flight.pilot.until(Duration::from_secs(120), 0, |_, _| {
            began.elapsed() > Duration::from_secs(190)
        });
    }
    let (heard, run, _) = flight.finish();
    let summary = run.session.summary("live", "sitl-px4");
    let modes: Vec<String> = heard
        .modes
        .iter()
        .map(|m| format!("{}.{}", (m >> 16) & 0xff, m >> 24))
        .collect();
    eprintln!(
        "modes (main.sub) {modes:?}; LAND {:.1} s after the hover began; ended at {:?}; approaches {}; feed adsb_echoes {}; traffic {:?}",
        landed_after.as_secs_f64(),
        heard.position,
        summary["approaches"],
        summary["feed"]["adsb_echoes"],
        run.session.world().traffic.keys().collect::<Vec<_>>()
    );
    assert!(
        landing,
        "PX4 did not land for the airliner: modes {modes:?}"
    );
    assert!(
        run.session.world().traffic.is_empty(),
        "the airliner PX4 re-streamed became traffic"
    );
    let vertical = summary["approaches"][0]["vertical_m"].as_f64().unwrap();
    assert!(
        vertical.abs() >= 15.0,
        "the airliner passed {vertical:.1} m above or below the copter"
    );
}
