//! Exact rays against terrain held as height fields, against an analytic cast written here
//! (Moller-Trumbore on the grid's own triangles, sharing no code with savsim's): the feed's
//! ray fan in every direction and every mode, the rangefinder under a pitched and rolled
//! vehicle, and the sensing layer's rays on exact terrain.

use std::sync::Arc;

use glam::DVec3;
use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage, MavType};
use savsim::collision::ColliderKind;
use savsim::feed::{FeedConfig, FeedKinds};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::{BodySource, CollisionConfig, Mode, MovingBodies, Pipeline, Rays};
use savsim::session::Session;

use crate::common::{feed, frame_v2, heartbeat, pose_messages, rangefinder_m, scene_at};

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
                .vehicles()
                .map(|(_, v)| v)
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
        .vehicles()
        .map(|(_, v)| v)
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
