//! Property tests (fixed seeds) against brute force: ray casts against the paper's
//! Moller-Trumbore formula in f64, octree and static `Bvh` queries and rays against a linear
//! scan (near the origin and 1000 km from it), sweeps against dense sampling judged by a separating-axis test of its own, the terrain
//! bounds the contact layer proves with (the surface's maximum over a rectangle, a segment
//! under the surface) against dense sampling of the surface.

use std::sync::Arc;

use glam::{DQuat, DVec3, Vec3};
use parry3d::shape::{Cuboid, TriMesh};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use savsim::collision::broad_phase::StaticBroadPhase;
use savsim::collision::contact::queries::{self, Placed};
use savsim::collision::sensing::octree::{Octree, OctreeConfig, OctreeWorkspace};
use savsim::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
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
            let got = queries::ray_distance_m(origin + offset, dir, 500.0, &placed);
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

/// The sweep test's wall: a box at the origin, axis-aligned, these half extents.
const WALL_HALF_M: DVec3 = DVec3::new(3.0, 8.0, 5.0);

/// The separating-axis test for a box (centre `centre`, rotated by `rotation`, half extents
/// `half`) against an axis-aligned box at the origin, in f64, written here from the theorem:
/// the largest gap over the 15 candidate axes (<= 0 when the boxes touch or overlap; never more
/// than their true distance). Judges `sweep` without the routines `sweep` confirms with.
fn separation_m(centre: DVec3, rotation: DQuat, half: (f64, f64, f64), wall_half: DVec3) -> f64 {
    let own = [
        rotation * DVec3::X,
        rotation * DVec3::Y,
        rotation * DVec3::Z,
    ];
    let own_half = [half.0, half.1, half.2];
    let world = [DVec3::X, DVec3::Y, DVec3::Z];
    let mut axes: Vec<DVec3> = own.iter().chain(world.iter()).copied().collect();
    for a in own {
        for b in world {
            let c = a.cross(b);
            if c.length() > 1e-9 {
                axes.push(c.normalize());
            }
        }
    }
    axes.iter()
        .map(|l| {
            let r_own: f64 = (0..3).map(|i| own_half[i] * own[i].dot(*l).abs()).sum();
            let r_wall =
                wall_half.x * l.x.abs() + wall_half.y * l.y.abs() + wall_half.z * l.z.abs();
            centre.dot(*l).abs() - r_own - r_wall
        })
        .fold(f64::NEG_INFINITY, f64::max)
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
            let obstacle = Cuboid::new(WALL_HALF_M.as_vec3());
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
            let hit = queries::sweep(&at(start), &at(end), &wall, &wall);
            let steps = 2000;
            let sampled = (0..=steps)
                .map(|i| i as f64 / steps as f64)
                .find(|u| separation_m(start.lerp(end, *u), rotation, half, WALL_HALF_M) <= 0.0);
            let length = (end - start).length().max(1e-9);
            match (hit, sampled) {
                (Some(h), Some(u)) => prop_assert!(
                    h <= u + 1e-6 && (u - h) * length < 0.05 + length / steps as f64,
                    "sweep {h} sampled {u}"
                ),
                (None, None) => {}
                (Some(h), None) => {
                    // Only a graze finer than the sampling may be missed by sampling.
                    let p = start.lerp(end, h);
                    prop_assert!(
                        separation_m(p, rotation, half, WALL_HALF_M) < 1e-2,
                        "sweep says {h:?}"
                    );
                }
                (None, Some(u)) => prop_assert!(false, "sampling hits at {u}, sweep misses"),
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn static_bvh_queries_and_rays_agree_with_a_linear_scan() {
    let strategy = (
        proptest::collection::vec(aabb(), 0..300),
        proptest::collection::vec((aabb(), v3(), v3()), 1..10),
        prop_oneof![Just(0.0f64), Just(1.0e6f64)],
    );
    runner(200)
        .run(&strategy, |(boxes, queries, far_m)| {
            // The whole scene 1000 km out (as a far scene origin puts it): f32 must not show.
            let shift = DVec3::new(far_m, -0.5 * far_m, 0.0);
            let boxes: Vec<Aabb64> = boxes
                .iter()
                .map(|b| Aabb64::new(b.min + shift, b.max + shift))
                .collect();
            let index = StaticBroadPhase::build(&boxes);
            for (q, origin, dir) in &queries {
                let q = Aabb64::new(q.min + shift, q.max + shift);
                let mut got = Vec::new();
                index.query_aabb(&q, |i| got.push(i));
                got.sort_unstable();
                let want: Vec<u32> = (0..boxes.len() as u32)
                    .filter(|&i| boxes[i as usize].intersects(&q))
                    .collect();
                prop_assert_eq!(got, want);
                let Some(dir) = dir.try_normalize() else {
                    continue;
                };
                let origin = *origin * 10.0 + shift;
                let entry = |i: u32, limit: f64| {
                    boxes[i as usize]
                        .ray_entry(origin, dir, limit)
                        .filter(|&t| t < limit)
                };
                let best = index.cast_ray(origin, dir, 800.0, entry);
                let truth = (0..boxes.len() as u32)
                    .filter_map(|i| entry(i, 800.0).map(|t| (i, t)))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                prop_assert_eq!(best.map(|b| b.1), truth.map(|b| b.1));
            }
            Ok(())
        })
        .unwrap();
}

/// A random terrain patch: `n` x `n` samples `cell_m` apart, heights up to `relief_m`.
fn terrain() -> impl Strategy<Value = Geometry> {
    (2usize..8, 1.0..30.0f32, 0.0..60.0f32).prop_flat_map(|(n, cell_m, relief_m)| {
        proptest::collection::vec(0.0..=relief_m.max(1e-3), n * n).prop_map(move |heights| {
            let grid = Arc::new(HeightGrid {
                nx: n,
                ny: n,
                cell_m,
                heights_m: heights,
            });
            Geometry::terrain(TerrainPatch {
                grid,
                x0: 0,
                y0: 0,
                nx: n,
                ny: n,
                base_m: 0.0,
            })
            .unwrap()
        })
    })
}

fn extent(t: &Geometry) -> f32 {
    t.local_aabb.maxs.x
}

#[test]
fn the_terrain_surface_maximum_over_a_rectangle_is_exact() {
    let strategy = (
        terrain(),
        0.0..1.0f32,
        0.0..1.0f32,
        0.0..0.6f32,
        0.0..0.6f32,
    );
    runner(300)
        .run(&strategy, |(t, fx, fy, fw, fh)| {
            let e = extent(&t);
            let (x0, y0) = (fx * e, fy * e);
            let (x1, y1) = (x0 + fw * e, y0 + fh * e);
            let Some(top) = t.terrain_surface_max_in(x0, y0, x1, y1) else {
                return Ok(());
            };
            // Dense sampling of the clipped rectangle never exceeds it, and comes close.
            let (cx1, cy1) = (x1.min(e), y1.min(e));
            let n = 60;
            let mut sampled = f32::NEG_INFINITY;
            for i in 0..=n {
                for j in 0..=n {
                    let x = x0 + (cx1 - x0) * i as f32 / n as f32;
                    let y = y0 + (cy1 - y0) * j as f32 / n as f32;
                    if let Some(h) = t.terrain_height_at(x, y) {
                        prop_assert!(h <= top + 1e-3, "{h} above the maximum {top}");
                        sampled = sampled.max(h);
                    }
                }
            }
            // The surface is no steeper than the relief over half a cell (a triangle's legs).
            let cell_m = match &t.source {
                savsim::scene::geometry::GeometrySource::Terrain(p) => p.grid.cell_m,
                _ => unreachable!(),
            };
            let relief = t.local_aabb.maxs.z - t.local_aabb.mins.z;
            let spacing = ((cx1 - x0).max(cy1 - y0)) / n as f32;
            prop_assert!(
                top <= sampled + 2.0 * relief / cell_m * spacing * 1.5 + 1e-3,
                "maximum {top} far above what sampling found {sampled}"
            );
            Ok(())
        })
        .unwrap();
}

#[test]
fn a_segment_proved_under_the_terrain_is_under_it_all_along() {
    let strategy = (
        terrain(),
        (0.0..1.0f32, 0.0..1.0f32, -2.0..8.0f32),
        (0.0..1.0f32, 0.0..1.0f32, -2.0..8.0f32),
    );
    let proved = std::cell::Cell::new(0);
    runner(2000)
        .run(&strategy, |(t, a, b)| {
            let e = extent(&t);
            // Each end at a depth under the surface there (negative: above it), so that the
            // segment grazes the surface's creases.
            let end = |(fx, fy, depth): (f32, f32, f32)| {
                let (x, y) = (fx * e, fy * e);
                Vec3::new(x, y, t.terrain_height_at(x, y).unwrap_or(0.0) - depth)
            };
            let (a, b) = (end(a), end(b));
            let claimed = t.terrain_holds_segment(a, b, 0.01);
            let n = 2000;
            let under_all = (0..=n).all(|i| {
                let q = a.lerp(b, i as f32 / n as f32);
                t.terrain_height_at(q.x, q.y).is_some_and(|h| q.z < h)
            });
            if claimed {
                proved.set(proved.get() + 1);
                prop_assert!(
                    under_all,
                    "claimed under all along, but sampling finds it above"
                );
            }
            Ok(())
        })
        .unwrap();
    let proved = proved.get();
    assert!(
        proved > 20,
        "the property must be exercised ({proved} proofs)"
    );
}

#[test]
fn a_segment_over_a_valley_along_a_cell_diagonal_is_not_under_the_terrain() {
    // One cell whose diagonal (the triangles' shared edge) is a valley at 0 m between 10 m
    // corners: a level segment across it at 5 m is under the surface at both ends only.
    let grid = Arc::new(HeightGrid {
        nx: 2,
        ny: 2,
        cell_m: 10.0,
        heights_m: vec![0.0, 10.0, 10.0, 0.0],
    });
    let valley = Geometry::terrain(TerrainPatch {
        grid,
        x0: 0,
        y0: 0,
        nx: 2,
        ny: 2,
        base_m: 0.0,
    })
    .unwrap();
    let (a, b) = (Vec3::new(9.0, 1.0, 5.0), Vec3::new(1.0, 9.0, 5.0));
    assert!(valley.terrain_height_at(9.0, 1.0).unwrap() > 5.0);
    assert!(valley.terrain_height_at(1.0, 9.0).unwrap() > 5.0);
    assert!(!valley.terrain_holds_segment(a, b, 0.01));
    // Along the valley, 1 m under its floor: under all along.
    let (c, d) = (Vec3::new(1.0, 1.0, -1.0), Vec3::new(9.0, 9.0, -1.0));
    assert!(valley.terrain_holds_segment(c, d, 0.01));
    // The maximum over the cell's lower half includes the 10 m corner.
    assert_eq!(
        valley.terrain_surface_max_in(0.0, 0.0, 10.0, 4.0),
        Some(10.0)
    );
}
