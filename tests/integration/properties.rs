//! Property tests (fixed seeds) against brute force: ray casts against the paper's
//! Moller-Trumbore formula in f64, octree queries against a linear scan, sweeps against dense
//! sampling.

use glam::{DQuat, DVec3, Vec3};
use parry3d::shape::{Cuboid, TriMesh};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use savsim::collision::contact::{self, Placed};
use savsim::collision::octree::{Octree, OctreeConfig, OctreeWorkspace};
use savsim::scene::Aabb64;

fn runner(cases: u32) -> TestRunner {
    TestRunner::new_with_rng(
        Config {
            cases,
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]),
    )
}

/// The paper's ray/triangle test (section 3.3.1), in f64. `None` for a miss or a ray parallel
/// to the triangle (P.E1 = 0).
fn moller_trumbore(o: DVec3, d: DVec3, v: [DVec3; 3]) -> Option<f64> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let p = d.cross(e2);
    let det = p.dot(e1);
    if det.abs() < 1e-12 {
        return None;
    }
    let t_vec = o - v[0];
    let q = t_vec.cross(e1);
    let (u, w, t) = (p.dot(t_vec) / det, q.dot(d) / det, q.dot(e2) / det);
    (u >= 0.0 && w >= 0.0 && u + w <= 1.0 && t >= 0.0).then_some(t)
}

fn v3() -> impl Strategy<Value = DVec3> {
    (-50.0..50.0f64, -50.0..50.0f64, -50.0..50.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

#[test]
fn ray_casts_agree_with_moller_trumbore() {
    let strategy = (
        proptest::collection::vec((v3(), v3(), v3()), 1..12),
        v3(),
        v3(),
        (-1.0e5..1.0e5f64, -1.0e5..1.0e5f64),
    );
    runner(400)
        .run(&strategy, |(tris, origin, dir, (ox, oy))| {
            prop_assume!(dir.length() > 1e-3);
            let dir = dir.normalize();
            // Place the mesh far from the scene origin: the query must stay exact.
            let offset = DVec3::new(ox, oy, 0.0);
            let vertices: Vec<Vec3> = tris
                .iter()
                .flat_map(|(a, b, c)| [*a, *b, *c])
                .map(|v| v.as_vec3())
                .collect();
            let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            let areas_ok = tris
                .iter()
                .all(|(a, b, c)| (*b - *a).cross(*c - *a).length() > 1e-2);
            prop_assume!(areas_ok);
            let mesh = TriMesh::new(vertices, indices).unwrap();
            let placed = Placed {
                shape: &mesh,
                position_enu_m: offset,
                enu_from_shape: DQuat::IDENTITY,
                pivot_local_m: Vec3::ZERO,
            };
            let got = contact::ray_distance_m(origin + offset, dir, 500.0, &placed);
            let want = tris
                .iter()
                .filter_map(|(a, b, c)| moller_trumbore(origin, dir, [*a, *b, *c]))
                .filter(|t| *t <= 500.0)
                .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
            match (got, want) {
                (Some(g), Some(w)) => prop_assert!((g - w).abs() < 1e-3 * (1.0 + w), "{g} vs {w}"),
                (None, None) => {}
                // Grazing hits (an edge within f32 rounding) may go either way; nothing else may.
                (g, w) => {
                    let t = g.or(w).unwrap();
                    let p = origin + dir * t;
                    let near_edge = tris.iter().any(|(a, b, c)| {
                        [(*a, *b), (*b, *c), (*c, *a)].iter().any(|(s, e)| {
                            let u = ((p - *s).dot(*e - *s) / (*e - *s).length_squared())
                                .clamp(0.0, 1.0);
                            (p - (*s + (*e - *s) * u)).length() < 1e-3
                        })
                    });
                    prop_assert!(near_edge, "parry {g:?}, Moller-Trumbore {w:?}");
                }
            }
            Ok(())
        })
        .unwrap();
}

fn aabb() -> impl Strategy<Value = Aabb64> {
    (v3(), (0.0..20.0f64, 0.0..20.0f64, 0.0..20.0f64))
        .prop_map(|(c, (x, y, z))| Aabb64::around(c * 20.0, DVec3::new(x, y, z)))
}

#[test]
fn octree_queries_agree_with_a_linear_scan() {
    let strategy = (
        proptest::collection::vec(aabb(), 0..300),
        proptest::collection::vec(aabb(), 1..10),
        4.0..300.0f64,
    );
    runner(200)
        .run(&strategy, |(boxes, queries, leaf_m)| {
            let tree = Octree::build(
                &boxes,
                OctreeConfig {
                    leaf_target_m: leaf_m,
                    ..OctreeConfig::default()
                },
            );
            let mut ws = OctreeWorkspace::default();
            for q in &queries {
                let mut got = Vec::new();
                tree.query_aabb(q, &mut ws, |i| got.push(i));
                got.sort_unstable();
                let want: Vec<u32> = (0..boxes.len() as u32)
                    .filter(|&i| boxes[i as usize].intersects(q))
                    .collect();
                prop_assert_eq!(got, want);
                let p = q.centre();
                if let Some(leaf) = tree.leaf_at(p) {
                    prop_assert!(tree.node_aabb(leaf).contains(p));
                    for &i in tree.leaf_items(leaf) {
                        prop_assert!(boxes[i as usize].intersects(&tree.node_aabb(leaf)));
                    }
                }
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn sweeps_agree_with_dense_sampling() {
    let strategy = (
        v3(),
        v3(),
        (0.2..5.0f64, 0.2..5.0f64, 0.2..5.0f64),
        -3.0..3.0f64,
    );
    runner(300)
        .run(&strategy, |(start, end, half, yaw_rad)| {
            let obstacle = Cuboid::new(Vec3::new(3.0, 8.0, 5.0));
            let mover = Cuboid::new(Vec3::new(half.0 as f32, half.1 as f32, half.2 as f32));
            let rotation = DQuat::from_rotation_z(yaw_rad);
            let at = |p: DVec3| Placed {
                shape: &mover,
                position_enu_m: p,
                enu_from_shape: rotation,
                pivot_local_m: Vec3::ZERO,
            };
            let wall = Placed {
                shape: &obstacle,
                position_enu_m: DVec3::new(0.0, 0.0, 0.0),
                enu_from_shape: DQuat::IDENTITY,
                pivot_local_m: Vec3::ZERO,
            };
            let hit = contact::sweep(&at(start), &at(end), &wall, &wall);
            let steps = 2000;
            let sampled = (0..=steps)
                .map(|i| i as f64 / steps as f64)
                .find(|u| contact::intersects(&at(start.lerp(end, *u)), &wall));
            let length = (end - start).length().max(1e-9);
            match (hit, sampled) {
                (Some(h), Some(u)) => prop_assert!(
                    h.fraction <= u + 1e-6
                        && (u - h.fraction) * length < 0.05 + length / steps as f64,
                    "sweep {} sampled {u}",
                    h.fraction
                ),
                (None, None) => {}
                (Some(h), None) => {
                    // Only a graze finer than the sampling may be missed by sampling.
                    let p = start.lerp(end, h.fraction);
                    prop_assert!(
                        contact::distance_m(&at(p), &wall) < 1e-2,
                        "sweep says {h:?}"
                    );
                }
                (None, Some(u)) => prop_assert!(false, "sampling hits at {u}, sweep misses"),
            }
            Ok(())
        })
        .unwrap();
}
