//! Issue 23: what outside checks found, each fixed at its root. Every test here failed on main
//! before its fix (93ec3d2).

use std::sync::Arc;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage, MavType};
use savsim::collision::ColliderKind;
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::{BodySource, CollisionConfig, Mode, MovingBodies, Pipeline, Rays};
use savsim::session::Session;

use crate::common::{feed, frame_v2, heartbeat, pose_messages, scene_at};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

/// A terrain written out in the scene: heights (rows south to north) `CELL_M` apart, its
/// south-west corner at `CORNER`.
const CELL_M: f64 = 20.0;
const N: usize = 9;
const CORNER: [f64; 3] = [-80.0, -80.0, 0.0];

type Heights = Vec<Vec<f64>>;

fn flat(h: f64) -> Heights {
    vec![vec![h; N]; N]
}

fn sloped() -> Heights {
    (0..N)
        .map(|iy| {
            (0..N)
                .map(|ix| 0.3 * ix as f64 * CELL_M + 0.1 * iy as f64 * CELL_M)
                .collect()
        })
        .collect()
}

fn rough() -> Heights {
    (0..N)
        .map(|iy| {
            (0..N)
                .map(|ix| ((ix * 7 + iy * 13) % 11) as f64 * 1.7 + ((ix * iy) % 3) as f64 * 0.25)
                .collect()
        })
        .collect()
}

fn terrain_scene(heights: &Heights) -> String {
    format!(
        "[[terrain]]\nid = \"t\"\nheights_m = {heights:?}\ncell_m = {CELL_M}\nposition_enu_m = {CORNER:?}\npatch_cells = 4\n"
    )
}

/// The grid's triangles in ENU: two per cell, split along the cell's south-west to north-east
/// diagonal (as scenes/README.md says).
fn triangles(heights: &Heights) -> Vec<[DVec3; 3]> {
    let at = |ix: usize, iy: usize| {
        DVec3::new(
            CORNER[0] + ix as f64 * CELL_M,
            CORNER[1] + iy as f64 * CELL_M,
            CORNER[2] + heights[iy][ix],
        )
    };
    let mut out = Vec::new();
    for iy in 0..N - 1 {
        for ix in 0..N - 1 {
            let (sw, se, nw, ne) = (
                at(ix, iy),
                at(ix + 1, iy),
                at(ix, iy + 1),
                at(ix + 1, iy + 1),
            );
            out.push([sw, se, ne]);
            out.push([sw, ne, nw]);
        }
    }
    out
}

/// Nearest hit of a ray on any triangle (Moller-Trumbore in f64), within `max_m`.
fn analytic_cast(tris: &[[DVec3; 3]], origin: DVec3, dir: DVec3, max_m: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    for [a, b, c] in tris {
        let (e1, e2) = (*b - *a, *c - *a);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = origin - *a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = dir.dot(q) / det;
        let t = e2.dot(q) / det;
        let inside = (-1e-9..=1.0 + 1e-9).contains(&u) && v >= -1e-9 && u + v <= 1.0 + 1e-9;
        if inside && (0.0..=max_m).contains(&t) && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best
}

/// Directions spread over the whole sphere (a Fibonacci lattice).
fn sphere(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

#[test]
fn exact_rays_meet_height_fields_in_every_direction_and_every_mode() {
    let origins = [
        DVec3::new(0.0, 0.0, 30.0),
        DVec3::new(-37.0, 21.0, 4.0),
        DVec3::new(55.0, -61.0, 12.5),
        DVec3::new(3.0, 3.0, 0.75),
    ];
    let dirs = sphere(300);
    for (name, heights) in [
        ("flat 0", flat(0.0)),
        ("flat 0.5", flat(0.5)),
        ("sloped", sloped()),
        ("rough", rough()),
    ] {
        let scene = scene_at(ORIGIN, &terrain_scene(&heights));
        let tris = triangles(&heights);
        for mode in [Mode::Exact, Mode::Box, Mode::Paper, Mode::Mesh, Mode::None] {
            let mut pipeline = Pipeline::new(
                &scene,
                CollisionConfig {
                    mode,
                    ..CollisionConfig::default()
                },
            );
            let own = BodySource::Vehicle {
                vehicle: 1,
                component_id: 1,
            };
            let mut hits = 0;
            for &origin in &origins {
                let mut out = vec![None; dirs.len()];
                let rays = Rays {
                    origin_enu_m: origin,
                    dirs_enu: &dirs,
                    max_m: 150.0,
                };
                pipeline.cast_exact_rays(&scene, own, &MovingBodies::default(), rays, &mut out);
                for (dir, got) in dirs.iter().zip(&out) {
                    // Under the surface (the up ray meets it): inside the terrain.
                    let below = analytic_cast(&tris, origin, DVec3::Z, 1e4).is_some();
                    let want = if below {
                        Some(0.0)
                    } else {
                        analytic_cast(&tris, origin, *dir, 150.0)
                    };
                    match (got, want) {
                        (Some(g), Some(w)) => {
                            assert!(
                                (g - w).abs() < 1e-3,
                                "{name} {mode:?} from {origin} along {dir}: {g} m, want {w} m"
                            );
                            hits += 1;
                        }
                        (None, None) => {}
                        _ => panic!(
                            "{name} {mode:?} from {origin} along {dir}: {got:?}, want {want:?}"
                        ),
                    }
                }
            }
            assert!(hits > 400, "{name} {mode:?}: {hits} hits");
        }
    }
}

/// The down reading of a feed frame, metres (`None`: max + 1, nothing within range).
fn rangefinder_m(messages: &[MavMessage]) -> Option<f64> {
    messages.iter().find_map(|m| match m {
        MavMessage::DISTANCE_SENSOR(d) if d.orientation as u8 == 25 => {
            (d.current_distance <= d.max_distance).then(|| f64::from(d.current_distance) / 100.0)
        }
        _ => None,
    })
}

#[test]
fn the_rangefinder_reads_terrain_under_a_hovering_pitched_and_rolled_vehicle() {
    let plane = LocalTangentPlane::new(ORIGIN);
    let poses = [
        (DVec3::new(0.0, 0.0, 30.0), [0.0, 0.0, 0.0]),
        (DVec3::new(10.0, -20.0, 30.0), [0.2, -0.3, 1.1]),
        (DVec3::new(-30.0, 25.0, 18.0), [-0.35, 0.15, -2.4]),
        (DVec3::new(40.0, 40.0, 25.0), [0.05, 0.4, 3.0]),
    ];
    let mut all_sensing_checked = 0;
    for (name, heights) in [
        ("flat 0", flat(0.0)),
        ("flat 0.5", flat(0.5)),
        ("sloped", sloped()),
        ("rough", rough()),
    ] {
        let scene = Arc::new(scene_at(ORIGIN, &terrain_scene(&heights)));
        let tris = triangles(&heights);
        let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
        session
            .start_feed(FeedConfig {
                kinds: FeedKinds::parse("proximity,rangefinder").unwrap(),
                ..FeedConfig::default()
            })
            .unwrap();
        let hb = heartbeat(
            MavType::MAV_TYPE_QUADROTOR,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        );
        feed(&mut session, 100.0, &frame_v2(1, 1, 0, &hb));
        let mut sensing_checked = 0;
        for (i, (p, rpy)) in poses.iter().enumerate() {
            // `p.z` is the height above the ground under the vehicle.
            let top = DVec3::new(p.x, p.y, 1e3);
            let ground = 1e3 - analytic_cast(&tris, top, DVec3::NEG_Z, 2e3).unwrap();
            let p = DVec3::new(p.x, p.y, ground + p.z);
            // Each pose twice: the second frame's rays are cast with the colliders the first
            // frame's swaps left.
            let mut swaps_before = 0;
            for again in 0..2u32 {
                let t_ms = 20_000 + 200 * i as u32 + 100 * again;
                let mut bytes = Vec::new();
                for (k, m) in pose_messages(&plane, t_ms, p, DVec3::ZERO, *rpy)
                    .iter()
                    .enumerate()
                {
                    bytes.extend(frame_v2(1, 1, (4 * i + 2 * again as usize + k) as u8, m));
                }
                swaps_before = session.pipeline().unwrap().totals().swaps;
                feed(&mut session, 100.0 + f64::from(t_ms - 19_900) / 1e3, &bytes);
            }
            if session.pipeline().unwrap().totals().swaps == swaps_before {
                sensing_checked += sensing_rays_agree(&session, &tris, &format!("{name} pose {i}"));
            }
            let sample = *session
                .world()
                .vehicles
                .values()
                .next()
                .unwrap()
                .history
                .latest()
                .unwrap();
            let down = sample.attitude.enu_from_frd * DVec3::Z;
            let messages: Vec<MavMessage> = session.drain_feed().map(|m| m.message).collect();
            let want = analytic_cast(&tris, sample.position_enu_m, down, 40.0);
            let got = rangefinder_m(&messages);
            assert!(
                want.is_some(),
                "{name} pose {i}: the test's pose sees the ground"
            );
            assert!(
                got.zip(want).is_some_and(|(g, w)| (g - w).abs() <= 0.011),
                "{name} pose {i}: rangefinder {got:?} m, the terrain is {want:?} m along body down"
            );
        }
        eprintln!("{name}: {sensing_checked} sensing rays on exact terrain checked");
        all_sensing_checked += sensing_checked;
    }
    assert!(
        all_sensing_checked >= 2,
        "{all_sensing_checked} sensing rays met exact terrain"
    );
}

/// The sensing layer's rays (the six body axes, pitched and rolled with the vehicle) that hit
/// terrain held as its exact shape (a `mesh` collider; a `box` collider is the paper's box, not
/// the ground) meet it where the analytic cast does.
fn sensing_rays_agree(session: &Session, tris: &[[DVec3; 3]], what: &str) -> usize {
    let pipeline = session.pipeline().unwrap();
    let sensing = &pipeline.vehicle(1, 1).unwrap().sensing;
    let origin = session
        .world()
        .vehicles
        .values()
        .next()
        .unwrap()
        .history
        .latest()
        .unwrap()
        .position_enu_m;
    let mut exact = 0;
    for (dir, hit) in &sensing.rays {
        let Some(hit) = hit else { continue };
        let held = sensing
            .colliders()
            .find(|(o, _, _)| *o == hit.obstacle)
            .map(|c| c.1);
        if held == Some(ColliderKind::Mesh) {
            let want = analytic_cast(tris, origin, *dir, 1e3).unwrap();
            assert!(
                (hit.distance_m - want).abs() < 1e-3,
                "{what}: sensing ray {dir}: {} m, want {want} m",
                hit.distance_m
            );
            exact += 1;
        }
    }
    exact
}

/// A wall 1 m thick across the east axis at E 50 m: a vehicle flying east at `speed` crosses it
/// between two samples (no sample inside it at 10 Hz above 10 m/s).
const WALL: &str = "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [1.0, 200.0, 60.0] }\nposition_enu_m = [50.0, 0.0, 0.0]\n";

/// A session over the wall with one vehicle's heartbeat taken.
fn wall_session() -> Session {
    let scene = Arc::new(scene_at(ORIGIN, WALL));
    let mut session = Session::new(Some(scene), CollisionConfig::default(), None).unwrap();
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    feed(&mut session, 0.0, &frame_v2(1, 1, 0, &hb));
    session
}

/// The collisions with the wall the session reported: (`t`, `time_of_impact`, swept).
fn wall_collisions(session: &Session) -> Vec<(f64, f64, bool)> {
    session
        .notable()
        .iter()
        .filter_map(|e| match &e.kind {
            savsim::collision::events::EventKind::Collision {
                time_of_impact,
                swept,
                ..
            } => Some((e.t, *time_of_impact, *swept)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_quick_reboot_is_a_new_track_whose_first_interval_is_swept() {
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session = wall_session();
    let mut seq = 0u8;
    // Up to 6.5 s of its clock, hovering west of the wall.
    for i in 0..=65u32 {
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            i * 100,
            DVec3::new(0.0, 0.0, 30.0),
            DVec3::ZERO,
        );
        feed(&mut session, 100.0 + f64::from(i) * 0.1, &bytes);
    }
    // Silent 2 s, then streaming again from 1.5 s of a new clock (PX4 SITL restarts in
    // 0.49 s), flying east at 20 m/s through the wall between its first two samples.
    for (k, east_m) in [40.0, 60.0, 80.0].into_iter().enumerate() {
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            1_500 + 100 * k as u32,
            DVec3::new(east_m, 0.0, 30.0),
            DVec3::new(20.0, 0.0, 0.0),
        );
        feed(&mut session, 108.5 + 0.1 * k as f64, &bytes);
    }
    let seen = session.world().seen.values().next().unwrap();
    assert_eq!(seen.boot_resets, 1, "{seen:?}");
    let hits = wall_collisions(&session);
    assert_eq!(hits.len(), 1, "{hits:?}");
    let (t, toi, swept) = hits[0];
    assert!(swept, "{hits:?}");
    // Half way between the samples that arrived at 108.5 and 108.6 s.
    assert!(
        (toi - 108.55).abs() < 0.03 && (t - 108.6).abs() < 0.03,
        "{hits:?}"
    );
}

/// Flies east at 10 m/s of the vehicle's clock, sampled every 100 ms of it, through the wall
/// at E 50 m, with the vehicle's clock running `speedup` times the arrival clock; returns the
/// collision and the arrival time of the first sample east of the wall's face.
fn fly_through_wall(speedup: f64, latency: impl Fn(u32) -> f64) -> ((f64, f64, bool), f64) {
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut session = wall_session();
    let mut seq = 0u8;
    let mut crossed_at = None;
    for i in 0..120u32 {
        let east_m = f64::from(i) - 0.25;
        let arrival_s = 1000.0 + f64::from(i) * 0.1 / speedup + latency(i);
        let bytes = crate::common::position_frames(
            &plane,
            1,
            &mut seq,
            30_000 + i * 100,
            DVec3::new(east_m, 0.0, 30.0),
            DVec3::new(10.0, 0.0, 0.0),
        );
        feed(&mut session, arrival_s, &bytes);
        if east_m >= 49.5 && crossed_at.is_none() {
            crossed_at = Some(arrival_s);
        }
    }
    let hits = wall_collisions(&session);
    assert_eq!(hits.len(), 1, "{hits:?}");
    (hits[0], crossed_at.unwrap())
}

#[test]
fn event_times_are_the_arrival_clock_at_any_speedup_and_drift() {
    // SITL at speedups 1, 5 and 30 with jittered latency; PX4 SIH running slow (0.9).
    for speedup in [1.0, 5.0, 30.0, 0.9] {
        let ((t, toi, _), crossed_at) =
            fly_through_wall(speedup, |i| 0.002 + f64::from(i * 37 % 11) * 0.001);
        assert!(
            (t - crossed_at).abs() < 0.3 && toi <= t && t - toi < 0.1 / speedup + 0.02,
            "speedup {speedup}: collision at t {t}, impact {toi}; the track crossed at {crossed_at}"
        );
    }
}

/// `savsim` with `args`, killed if it runs longer than `limit` (a hang is a failure).
fn savsim_within(args: &[&str], limit: std::time::Duration) -> std::process::Output {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > limit {
            let _ = child.kill();
            panic!("savsim {args:?} still running after {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn absurd_numbers_in_a_row_are_that_rows_error_and_the_rest_run() {
    use arrow_array::{cast::AsArray, types::UInt64Type, Array};
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    let own = "0 0 0 100; 20 200 0 100";
    std::fs::write(
        &manifest,
        format!(
            "id,own,intruder,duration_s,rate_hz\n\
             long,{own},{own},1e14,\n\
             fast,{own},{own},,1e300\n\
             many,{own},{own},1e6,1000\n\
             far,0 0 0 1e300; 1 0 0 0,{own},,\n\
             nan,{own},{own},NaN,\n\
             good,{own},{own},,\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = savsim_within(
        &[
            "batch",
            manifest.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        std::time::Duration::from_secs(60),
    );
    crate::common::assert_ran(&run);
    let file = std::fs::File::open(out.join("part-00000-of-00001.parquet")).unwrap();
    let batch = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .unwrap()
        .build()
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    let errors = batch.column_by_name("error").unwrap().as_string::<i32>();
    for (i, want) in [
        "duration_s 1e14",
        "rate_hz 1e300",
        "samples a row",
        "waypoint 1",
        "duration_s NaN",
    ]
    .iter()
    .enumerate()
    {
        assert!(
            errors.value(i).contains(want),
            "row {i}: {:?}",
            errors.value(i)
        );
    }
    assert!(errors.is_null(5), "{}", errors.value(5));
    let collisions = batch
        .column_by_name("collisions")
        .unwrap()
        .as_primitive::<UInt64Type>();
    assert_eq!(collisions.value(5), 1);
}

#[test]
fn absurd_flags_are_usage_errors_not_panics() {
    for args in [
        &[
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--duration-s",
            "1e20",
        ][..],
        &[
            "live",
            "--connect",
            "udpin:127.0.0.1:0",
            "--rate-hz",
            "1e300",
        ],
        &["replay", "x.tlog", "--ray-length-m", "1e300"],
        &["replay", "x.tlog", "--sensor-hz", "1e300"],
        &["batch", "gen-encounters", "--n", "1000000000000"],
        &[
            "batch",
            "gen-encounters",
            "--n",
            "1",
            "--duration-s",
            "1e300",
        ],
        &["bench", "--scale-max", "1000000000000"],
    ] {
        let run = savsim_within(args, std::time::Duration::from_secs(20));
        let said = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {said}");
        assert!(!said.contains("panicked"), "{args:?}: {said}");
    }
}

/// A session over `scene` (no terrain) with `--feed LIST` and the ADS-B radius given, a vehicle
/// heartbeat taken.
fn fed_session(scene: &str, list: &str, adsb_radius_m: f64) -> Session {
    let mut session = Session::new(
        Some(Arc::new(scene_at(ORIGIN, scene))),
        CollisionConfig::default(),
        None,
    )
    .unwrap();
    session
        .start_feed(FeedConfig {
            kinds: FeedKinds::parse(list).unwrap(),
            adsb_radius_m,
            ..FeedConfig::default()
        })
        .unwrap();
    let hb = heartbeat(
        MavType::MAV_TYPE_QUADROTOR,
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
    );
    feed(&mut session, 10.0, &frame_v2(1, 1, 0, &hb));
    feed(&mut session, 10.0, &frame_v2(2, 1, 0, &hb));
    session
}

/// Vehicle `sysid` level at the geodetic `at`, nose north, stamped `t_ms`; returns what the
/// feed sent it.
fn hover_at(session: &mut Session, sysid: u8, at: Geodetic, t_ms: u32) -> Vec<MavMessage> {
    let plane = LocalTangentPlane::new(ORIGIN);
    let p = plane.enu_m_from_geodetic(&at);
    let mut bytes = Vec::new();
    for (k, m) in pose_messages(&plane, t_ms, p, DVec3::ZERO, [0.0, 0.0, 0.0])
        .iter()
        .enumerate()
    {
        bytes.extend(frame_v2(sysid, 1, k as u8, m));
    }
    feed(session, 10.0 + f64::from(t_ms) / 1e3, &bytes);
    session
        .drain_feed()
        .filter(|m| m.to.system_id == sysid)
        .map(|m| m.message)
        .collect()
}

/// `metres` east of the origin, `up_m` above the ellipsoid at the origin's height.
fn east_of_origin(metres: f64, up_m: f64) -> Geodetic {
    // Longitude per metre east at the origin's latitude (WGS84 prime vertical radius).
    let (a, e2) = (6_378_137.0, 6.694_379_990_14e-3);
    let lat = ORIGIN.lat_deg.to_radians();
    let n = a / (1.0 - e2 * lat.sin().powi(2)).sqrt();
    Geodetic::new(
        ORIGIN.lat_deg,
        ORIGIN.lon_deg + (metres / (n * lat.cos())).to_degrees(),
        ORIGIN.alt_m + up_m,
    )
}

#[test]
fn with_no_terrain_the_rangefinder_reads_the_height_above_the_ellipsoid_far_from_the_origin() {
    let mut session = fed_session("", "rangefinder", 2000.0);
    for (i, east_m) in [0.0, 10_000.0, 30_000.0].into_iter().enumerate() {
        let sent = hover_at(
            &mut session,
            1,
            east_of_origin(east_m, 20.0),
            1000 + 100 * i as u32,
        );
        let got = rangefinder_m(&sent);
        // On main the ground was the plane through the origin: 7.8 m higher 10 km out.
        assert!(
            got.is_some_and(|g| (g - 20.0).abs() <= 0.011),
            "{east_m} m east, 20 m up: rangefinder {got:?}"
        );
    }
}

#[test]
fn levelled_sectors_are_level_where_the_vehicle_is() {
    let mut session = fed_session("", "proximity", 2000.0);
    let plane = LocalTangentPlane::new(ORIGIN);
    let at = east_of_origin(100_000.0, 50.0);
    hover_at(&mut session, 1, at, 1000);
    let p = plane.enu_m_from_geodetic(&at);
    let readings = session.feed().unwrap().readings().to_vec();
    assert_eq!(readings.len(), 9);
    for r in readings.iter().filter(|r| r.dir_enu.z.abs() < 0.5) {
        // 30 m along a level ray the height above the ellipsoid changes by the earth's
        // curvature only (0.07 mm); on main the rays were level in the scene's plane, 0.9
        // degrees off 100 km out.
        let climb_m = plane.geodetic_from_enu_m(p + r.dir_enu * 30.0).alt_m - at.alt_m;
        assert!(
            climb_m.abs() < 1e-3,
            "{:?}: climbs {climb_m} m over 30 m",
            r.dir_enu
        );
    }
}

#[test]
fn adsb_heading_and_climb_are_the_aircrafts_own_and_far_aircraft_are_not_sent() {
    let plane = LocalTangentPlane::new(ORIGIN);
    // A track 50 km east, flying along the scene's north axis at 100 m/s, level in the
    // scene's plane.
    let start = plane.enu_m_from_geodetic(&east_of_origin(50_000.0, 300.0));
    let end = start + DVec3::new(0.0, 6000.0, 0.0);
    let scene = format!(
        "[[dynamic]]\nid = \"far\"\nkind = \"a320\"\nwaypoints = [ {{ t_s = 0.0, position_enu_m = {:?} }}, {{ t_s = 60.0, position_enu_m = {:?} }} ]\n",
        start.to_array(),
        end.to_array()
    );
    let mut session = fed_session(&scene, "adsb", 60_000.0);
    hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
    let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 2000);
    let Some(MavMessage::ADSB_VEHICLE(a)) = sent
        .iter()
        .find(|m| matches!(m, MavMessage::ADSB_VEHICLE(_)))
    else {
        panic!("no ADSB_VEHICLE in {sent:?}")
    };
    // The truth from two geodetic points 1 s apart on the track (ellipsoidal radii).
    let t_s = 1.0;
    let p0 = plane.geodetic_from_enu_m(start + (end - start) * (t_s / 60.0));
    let p1 = plane.geodetic_from_enu_m(start + (end - start) * ((t_s + 1.0) / 60.0));
    let (a_m, e2) = (6_378_137.0, 6.694_379_990_14e-3);
    let lat = p0.lat_deg.to_radians();
    let w = (1.0 - e2 * lat.sin().powi(2)).sqrt();
    let (m_r, n_r) = (a_m * (1.0 - e2) / w.powi(3), a_m / w);
    let north = (p1.lat_deg - p0.lat_deg).to_radians() * (m_r + p0.alt_m);
    let east = (p1.lon_deg - p0.lon_deg).to_radians() * (n_r + p0.alt_m) * lat.cos();
    let heading_cdeg = (east.atan2(north).to_degrees().rem_euclid(360.0) * 100.0).round();
    let climb_cms = ((p1.alt_m - p0.alt_m) * 100.0).round();
    assert!(
        (f64::from(a.heading) - heading_cdeg).abs() <= 1.0,
        "heading {} cdeg, the track's own {heading_cdeg}",
        a.heading
    );
    assert!(
        (f64::from(a.ver_velocity) - climb_cms).abs() <= 1.0,
        "vertical speed {} cm/s, the track's own {climb_cms}",
        a.ver_velocity
    );

    // Two vehicles 3 km apart do not hear of each other with the default radius; 1 km apart do.
    for (apart_m, heard) in [(3000.0, false), (1000.0, true)] {
        let mut session = fed_session("", "adsb", 2000.0);
        hover_at(&mut session, 2, east_of_origin(apart_m, 30.0), 1000);
        let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
        let adsb = sent
            .iter()
            .filter(|m| matches!(m, MavMessage::ADSB_VEHICLE(_)))
            .count();
        assert_eq!(adsb, usize::from(heard), "{apart_m} m apart");
    }
}

#[test]
fn collision_reports_traffic_already_inside_its_volume_whatever_the_time_to_closest() {
    let plane = LocalTangentPlane::new(ORIGIN);
    let at = plane.enu_m_from_geodetic(&east_of_origin(0.0, 30.0));
    // 100 m east at the vehicle's height, closing at 1 m/s: closest approach in 100 s.
    let a = at + DVec3::new(100.0, 0.0, 0.0);
    let b = at + DVec3::new(-100.0, 0.0, 0.0);
    let scene = format!(
        "[[dynamic]]\nid = \"slow\"\nkind = \"balloon\"\nwaypoints = [ {{ t_s = 0.0, position_enu_m = {:?} }}, {{ t_s = 200.0, position_enu_m = {:?} }} ]\n",
        a.to_array(),
        b.to_array()
    );
    let mut session = fed_session(&scene, "collision", 2000.0);
    hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 1000);
    let sent = hover_at(&mut session, 1, east_of_origin(0.0, 30.0), 2000);
    assert!(
        sent.iter().any(|m| matches!(m, MavMessage::COLLISION(_))),
        "no COLLISION for a balloon 99 m away: {sent:?}"
    );
}

fn adsb_frame(icao: u32, flags: u16, altitude_type: u8) -> Vec<u8> {
    use mavlink::dialects::ardupilotmega::{
        AdsbAltitudeType, AdsbEmitterType, AdsbFlags, ADSB_VEHICLE_DATA,
    };
    use num_traits::FromPrimitive;
    let m = MavMessage::ADSB_VEHICLE(ADSB_VEHICLE_DATA {
        ICAO_address: icao,
        lat: -353_600_000,
        lon: 1_491_600_000,
        altitude_type: AdsbAltitudeType::from_u8(altitude_type).unwrap(),
        altitude: 900_000,
        heading: 9_000,
        hor_velocity: 5_000,
        ver_velocity: 300,
        callsign: (*b"TEST1234\0").into(),
        emitter_type: AdsbEmitterType::ADSB_EMITTER_TYPE_LARGE,
        tslc: 1,
        flags: AdsbFlags::from_bits_truncate(flags),
        squawk: 1200,
    });
    frame_v2(50, 1, 0, &m)
}

#[test]
fn adsb_reports_are_read_by_their_flags_and_altitude_type() {
    let mut session = Session::new(None, CollisionConfig::default(), None).unwrap();
    // Coordinates and altitude valid, heading and speeds too: a moving aircraft.
    feed(&mut session, 1.0, &adsb_frame(0x10, 0x1FF, 1));
    // No valid coordinates: not a position (Mode S relays).
    feed(&mut session, 1.0, &adsb_frame(0x11, 0x1FE, 1));
    // Coordinates but no altitude: not placed.
    feed(&mut session, 1.0, &adsb_frame(0x12, 0x1FD, 1));
    // Valid position, heading and velocity not: held still, not extrapolated.
    feed(&mut session, 1.0, &adsb_frame(0x13, 0x03, 1));
    // QNH barometric altitude: kept, and counted apart.
    feed(&mut session, 1.0, &adsb_frame(0x14, 0x1FF, 0));
    let traffic = &session.world().traffic;
    assert_eq!(
        traffic.keys().copied().collect::<Vec<_>>(),
        [0x10, 0x13, 0x14]
    );
    let v = |icao: u32| traffic[&icao].history.latest().unwrap().velocity_enu_mps;
    assert!(
        (v(0x10).truncate().length() - 50.0).abs() < 0.01 && v(0x10).z > 2.9,
        "{}",
        v(0x10)
    );
    assert_eq!(v(0x13), DVec3::ZERO);
    assert!(traffic[&0x14].pressure_altitude && !traffic[&0x10].pressure_altitude);
    let rejected = &session.stats().rejected;
    assert_eq!(
        rejected.get(&savsim::ingest::decode::Rejection::AdsbNoPosition),
        Some(&2)
    );
}

#[test]
fn one_far_future_tlog_timestamp_does_not_freeze_the_clock() {
    let dir = tempfile::tempdir().unwrap();
    let flight = dir.path().join("f.tlog");
    let plane = LocalTangentPlane::new(ORIGIN);
    let mut w = savsim::ingest::tlog::TlogWriter::new(std::fs::File::create(&flight).unwrap());
    let mut seq = 0u8;
    for i in 0..100u32 {
        let t_us = 1_700_000_000_000_000 + u64::from(i) * 100_000;
        // One record's timestamp (outside the CRC) is 300 years on.
        let first_us = if i == 10 {
            10_000_000_000_000_000
        } else {
            t_us
        };
        let messages = pose_messages(
            &plane,
            1000 + 100 * i,
            DVec3::new(f64::from(i), 0.0, 30.0),
            DVec3::new(10.0, 0.0, 0.0),
            [0.0, 0.0, 0.0],
        );
        for (k, m) in messages.iter().enumerate() {
            let at = if k == 0 { first_us } else { t_us };
            w.write_record(at, &frame_v2(1, 1, seq, m)).unwrap();
            seq = seq.wrapping_add(1);
        }
    }
    w.flush().unwrap();
    drop(w);
    let session = crate::common::replay_into_session(&flight, None);
    let stats = &session.stats();
    eprintln!(
        "records {} outliers {} jumps {} back {} span {:?}",
        stats.tlog_records,
        stats.clock_outliers,
        stats.clock_jumps,
        stats.clock_backwards,
        stats.time_span_s
    );
    assert_eq!(stats.clock_outliers, 1);
    let (first, last) = stats.time_span_s.unwrap();
    assert!((last - first - 9.9).abs() < 1e-6, "{first} {last}");
    let latest = session
        .world()
        .vehicles
        .values()
        .next()
        .unwrap()
        .history
        .latest()
        .unwrap()
        .t_s;
    assert!(
        (latest - last).abs() < 0.05,
        "the last sample at {latest}, the clock at {last}"
    );
}
