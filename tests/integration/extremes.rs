//! Numerics at the extremes, each case with its exact expected outcome: which obstacle is hit
//! (or none) and when, within a stated tolerance. Positions go through MAVLink where the case is
//! about geodesy (poles, antimeridian, altitude), so the whole ingest path is exercised.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use savsim::bench::{collisions, run_samples};
use savsim::collision::contact::queries::{ray_distance_m, Placed};
use savsim::collision::events::Event;
use savsim::collision::sensing::octree::{Octree, OctreeConfig, OctreeWorkspace};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::{CollisionConfig, Mode, Pipeline};
use savsim::scene::{Aabb64, Scene};
use savsim::session::Session;
use savsim::world::{Attitude, TrackSample};

use crate::common::{feed, position_frames, sample, scene_at, straight};

fn fly(scene: &Scene, mode: Mode, flight: &[TrackSample]) -> Vec<(String, f64)> {
    let mut pipeline = Pipeline::new(
        scene,
        CollisionConfig {
            mode,
            ..CollisionConfig::default()
        },
    );
    let (_, events) = run_samples(&mut pipeline, scene, 1, flight, &[]);
    owned(&events)
}

fn owned(events: &[Event]) -> Vec<(String, f64)> {
    collisions(events)
        .into_iter()
        .map(|(o, t)| (o.to_owned(), t))
        .collect()
}

/// Fly a straight ENU line from `a` eastward at `speed` (10 Hz, level, nose east) as MAVLink
/// GLOBAL_POSITION_INT + ATTITUDE frames through a session over `scene`; its collisions.
fn fly_mavlink(scene: Scene, mode: Mode, a: DVec3, b: DVec3, speed_mps: f64) -> Vec<(String, f64)> {
    let plane = LocalTangentPlane::new(scene.origin);
    let mut session = Session::new(
        Some(std::sync::Arc::new(scene)),
        CollisionConfig {
            mode,
            ..CollisionConfig::default()
        },
        None,
    )
    .unwrap();
    let flight = straight(plane.origin(), a, b, speed_mps, 10.0);
    let mut seq = 0u8;
    for s in &flight {
        // Velocity in the local NED frame at the vehicle (ENU of the plane ~ local here).
        let frames = position_frames(
            &plane,
            1,
            &mut seq,
            s.time_boot_ms,
            s.position_enu_m,
            s.velocity_enu_mps,
        );
        feed(&mut session, s.t_s, &frames);
    }
    session.finish().unwrap();
    owned(session.notable())
}

/// The quad's forward half-length (its nose to its reference point), metres.
fn quad_nose_m() -> f64 {
    let q = savsim::scene::models::quad();
    f64::from(q.local_aabb.maxs.x)
}

/// A 10 m cube on the ground 100 m east of the origin, a flight at 5 m up from 0 to 200 m east
/// at 10 m/s: contact when the nose reaches x = 95, at t = 1000 + (95 - nose) / 10 s.
fn expect_cube_hit(origin: Geodetic) {
    for mode in [Mode::Exact, Mode::Reference] {
        let scene = scene_at(
            origin,
            "[[obstacle]]\nid = \"cube\"\nkind = \"building\"\nshape = { box = [10.0, 10.0, 10.0] }\nposition_enu_m = [100.0, 0.0, 0.0]\n",
        );
        let hits = fly_mavlink(
            scene,
            mode,
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::new(200.0, 0.0, 5.0),
            10.0,
        );
        let want = 1000.0 + (95.0 - quad_nose_m()) / 10.0;
        assert_eq!(hits.len(), 1, "{origin:?} {mode:?}: {hits:?}");
        assert_eq!(hits[0].0, "cube");
        // MAVLink carries 1e-7 degrees (1.1 cm) and millimetres: 2 ms at 10 m/s.
        assert!(
            (hits[0].1 - want).abs() < 0.002,
            "{origin:?} {mode:?}: contact at {} s, expected {want} s",
            hits[0].1
        );
    }
}

#[test]
fn poles_antimeridian_and_altitude_extremes_hit_on_time() {
    for origin in [
        Geodetic::new(89.9, 30.0, 0.0),
        Geodetic::new(-89.9, -150.0, 2800.0),
        // The flight crosses from +180 to -180 degrees of longitude 53 m after its start.
        Geodetic::new(-16.0, 179.9995, 10.0),
        Geodetic::new(31.5, 35.5, -400.0),
        Geodetic::new(47.0, 8.0, 20_000.0),
    ] {
        expect_cube_hit(origin);
    }
}

#[test]
fn an_obstacle_placed_by_latitude_and_longitude_across_the_antimeridian() {
    // The cube's centre is given as -179.9990 deg: east of an origin at +179.9995 deg.
    let origin = Geodetic::new(-16.0, 179.9995, 10.0);
    let plane = LocalTangentPlane::new(origin);
    let centre = plane.enu_m_from_geodetic(&Geodetic::new(-16.0, -179.999, 10.0));
    assert!(
        (centre.x - 160.5).abs() < 1.0 && centre.y.abs() < 0.01,
        "{centre}"
    );
    let scene = scene_at(
        origin,
        "[[obstacle]]\nid = \"across\"\nkind = \"building\"\nshape = { box = [10.0, 10.0, 10.0] }\nposition_geo = [-16.0, -179.999, 10.0]\n",
    );
    let hits = fly_mavlink(
        scene,
        Mode::Reference,
        DVec3::new(0.0, 0.0, 5.0 + centre.z),
        DVec3::new(300.0, 0.0, 5.0 + centre.z),
        10.0,
    );
    let want = 1000.0 + (centre.x - 5.0 - quad_nose_m()) / 10.0;
    assert_eq!(hits.len(), 1, "{hits:?}");
    assert!(
        (hits[0].1 - want).abs() < 0.002,
        "{hits:?}, expected {want}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// 0 to 300 m/s at 5, 10 or 50 Hz into a 2 m wall: swept modes hit it once, on time; a
    /// vehicle that never reaches it (speed 0) hits nothing.
    #[test]
    fn any_speed_hits_a_thin_wall_on_time(speed in 0.0f64..300.0, rate_index in 0usize..3) {
        let rate = [5.0, 10.0, 50.0][rate_index];
        let scene = scene_at(
            Geodetic::new(-35.36, 149.16, 584.0),
            "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [2.0, 40.0, 40.0] }\nposition_enu_m = [101.0, 0.0, 0.0]\n",
        );
        let nose = quad_nose_m();
        let flight = if speed < 0.5 {
            let p = DVec3::new(90.0, 0.0, 10.0);
            (0..20).map(|i| sample(scene.origin, 1000.0 + i as f64 / rate, p, DVec3::ZERO)).collect()
        } else {
            let start = DVec3::new(100.0 - nose - speed * 2.0 - 1.0, 0.0, 10.0);
            straight(scene.origin, start, start + DVec3::X * speed * 4.0, speed, rate)
        };
        for mode in [Mode::Exact, Mode::Reference] {
            let hits = fly(&scene, mode, &flight);
            if speed < 0.5 {
                prop_assert!(hits.is_empty(), "{mode:?}: {hits:?}");
                continue;
            }
            let want = 1000.0 + (2.0 * speed + 1.0) / speed;
            prop_assert_eq!(hits.len(), 1, "{:?} at {} m/s, {} Hz: {:?}", mode, speed, rate, hits);
            // 1 cm of sweep tolerance at the speed flown, plus 0.1 ms.
            prop_assert!(
                (hits[0].1 - want).abs() < 0.01 / speed + 1e-4,
                "{:?} at {} m/s, {} Hz: contact at {}, expected {}", mode, speed, rate, hits[0].1, want
            );
        }
    }
}

#[test]
fn rays_along_faces_through_edges_and_vertices_agree_with_the_broad_phase() {
    let cuboid = parry3d::shape::Cuboid::new(glam::Vec3::splat(5.0));
    let placed = Placed {
        shape: &cuboid,
        position_enu_m: DVec3::splat(5.0),
        enu_from_shape: DQuat::IDENTITY,
        pivot_local_m: glam::Vec3::ZERO,
    };
    let aabb = Aabb64::new(DVec3::ZERO, DVec3::splat(10.0));
    let s2 = 2f64.sqrt();
    let s3 = 3f64.sqrt();
    for (what, origin, dir, want) in [
        (
            "along an edge",
            DVec3::new(-10.0, 0.0, 0.0),
            DVec3::X,
            Some(10.0),
        ),
        (
            "in a face's plane",
            DVec3::new(-10.0, 5.0, 10.0),
            DVec3::X,
            Some(10.0),
        ),
        (
            "just above a face",
            DVec3::new(-10.0, 5.0, 10.001),
            DVec3::X,
            None,
        ),
        (
            "at a vertical edge",
            DVec3::new(-10.0, -10.0, 5.0),
            DVec3::new(1.0, 1.0, 0.0) / s2,
            Some(10.0 * s2),
        ),
        (
            "at a vertex",
            DVec3::splat(-10.0),
            DVec3::ONE / s3,
            Some(10.0 * s3),
        ),
        (
            "zero direction",
            DVec3::new(-10.0, 5.0, 5.0),
            DVec3::ZERO,
            None,
        ),
        (
            "NaN direction",
            DVec3::new(-10.0, 5.0, 5.0),
            DVec3::NAN,
            None,
        ),
    ] {
        let narrow = ray_distance_m(origin, dir, 100.0, &placed);
        let broad = aabb.ray_entry(origin, dir, 100.0);
        match want {
            Some(d) => {
                let n = narrow.unwrap_or_else(|| panic!("{what}: narrow phase missed"));
                let b = broad.unwrap_or_else(|| panic!("{what}: broad phase missed"));
                assert!(
                    (n - d).abs() < 1e-3 && (b - d).abs() < 1e-9,
                    "{what}: {n} {b} vs {d}"
                );
            }
            None => assert!(
                narrow.is_none() && broad.is_none(),
                "{what}: {narrow:?} {broad:?}"
            ),
        }
    }
    // The octree's ray cast refuses a zero or NaN direction too.
    let tree = Octree::build(&[aabb], OctreeConfig::default());
    let mut ws = OctreeWorkspace::default();
    for dir in [DVec3::ZERO, DVec3::NAN] {
        assert_eq!(
            tree.cast_ray(DVec3::splat(-1.0), dir, 100.0, &mut ws, |_, _| Some(0.0)),
            None
        );
    }
}

/// A cube of side `size_m` as an OBJ, with a zero-area triangle and a repeated face added.
fn cube_obj(size_m: f64) -> String {
    let h = size_m / 2.0;
    let mut s = String::new();
    for i in 0..8 {
        let c = |bit: i32| if i & bit == 0 { -h } else { h };
        s += &format!("v {} {} {}\n", c(1), c(2), c(4) + h);
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s += &format!(
            "f {} {} {}\nf {} {} {}\n",
            f[0], f[1], f[2], f[0], f[2], f[3]
        );
    }
    s += "f 1 1 2\n"; // zero area
    s += "f 1 3 4\n"; // a repeat
    s
}

#[test]
fn meshes_from_a_millimetre_to_ten_kilometres_with_bad_triangles() {
    let dir = tempfile::tempdir().unwrap();
    for (size_m, at_x) in [(0.001, 50.0), (1.0, 50.0), (10_000.0, 5_050.0)] {
        std::fs::write(dir.path().join("cube.obj"), cube_obj(size_m)).unwrap();
        let scene_path = dir.path().join("scene.toml");
        std::fs::write(
            &scene_path,
            format!(
                "[origin]\nlat_deg = -35.36\nlon_deg = 149.16\nalt_m = 584.0\n\
                 [[vehicle]]\nmodel = {{ box = [1.0, 1.0, 0.4] }}\n\
                 [[obstacle]]\nid = \"cube\"\nkind = \"building\"\nshape = {{ mesh = \"cube.obj\" }}\n\
                 position_enu_m = [{at_x}, 0.0, 0.0]\n"
            ),
        )
        .unwrap();
        let scene = savsim::scene::load(&scene_path).unwrap();
        // 12 faces and the repeat; the zero-area triangle is dropped on load.
        assert_eq!(scene.obstacles[0].geometry.triangle_count(), 13);
        // A 1 m x 1 m x 0.4 m box vehicle (0.4 m below its reference point) through the cube's
        // middle height (10 m up for the big one): one contact, also while the millimetre cube
        // is inside the vehicle's hull.
        let z = (size_m / 2.0).min(10.0) + 0.2;
        let face_x = at_x - size_m / 2.0;
        let nose = 0.5;
        let start = DVec3::new(face_x - nose - 20.0, 0.0, z);
        let flight = straight(scene.origin, start, start + DVec3::X * 40.0, 10.0, 10.0);
        for mode in [Mode::Exact, Mode::Reference] {
            let hits = fly(&scene, mode, &flight);
            assert_eq!(hits.len(), 1, "{size_m} m, {mode:?}: {hits:?}");
            let want = 1000.0 + 2.0;
            assert!(
                (hits[0].1 - want).abs() < 0.002,
                "{size_m} m, {mode:?}: {} vs {want}",
                hits[0].1
            );
        }
    }
}

#[test]
fn coplanar_contact_counts_and_a_millimetre_above_does_not() {
    let scene = scene_at(
        Geodetic::new(-35.36, 149.16, 584.0),
        "[[vehicle]]\nmodel = { box = [1.0, 1.0, 0.4] }\n\
         [[obstacle]]\nid = \"roof\"\nkind = \"building\"\nshape = { box = [20.0, 20.0, 10.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    // Level, the vehicle's box spans 0.4 m below its reference point.
    for (z, touching) in [(10.4, true), (10.401, false)] {
        let p = DVec3::new(0.0, 0.0, z);
        let flight: Vec<TrackSample> = (0..3)
            .map(|i| sample(scene.origin, 1000.0 + i as f64 * 0.1, p, DVec3::ZERO))
            .collect();
        for mode in [Mode::Box, Mode::Mesh, Mode::Exact, Mode::Reference] {
            let hits = fly(&scene, mode, &flight);
            assert_eq!(!hits.is_empty(), touching, "z {z}, {mode:?}: {hits:?}");
        }
    }
}

#[test]
fn euler_angles_at_gimbal_lock_give_a_unit_attitude() {
    let origin = Geodetic::new(-35.36, 149.16, 584.0);
    let plane = LocalTangentPlane::new(origin);
    for (pitch, up) in [
        (std::f64::consts::FRAC_PI_2, 1.0),
        (-std::f64::consts::FRAC_PI_2, -1.0),
    ] {
        for (roll, yaw) in [(0.0, 0.0), (0.7, 1.3), (-2.0, -3.0)] {
            let a = Attitude::from_euler_ned(&plane, &origin, roll, pitch, yaw, 0);
            assert!(a.enu_from_frd.is_finite() && a.enu_from_frd.is_normalized());
            let forward = a.forward_enu();
            assert!((forward - DVec3::Z * up).length() < 1e-9, "{forward}");
        }
    }
}

#[test]
fn leaving_and_reentering_between_samples_is_two_collisions() {
    // Inside a 10 m block, out through its roof to 2 m above it, and back in: the contact that
    // the sweep finds on the way out has ended by the sample, so going back in is new.
    let scene = scene_at(
        Geodetic::new(-35.36, 149.16, 584.0),
        "[[obstacle]]\nid = \"block\"\nkind = \"building\"\nshape = { box = [20.0, 20.0, 10.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let flight: Vec<TrackSample> = [8.0, 12.5, 8.0]
        .iter()
        .enumerate()
        .map(|(i, &z)| {
            sample(
                scene.origin,
                1000.0 + i as f64 * 0.1,
                DVec3::new(0.0, 0.0, z),
                DVec3::ZERO,
            )
        })
        .collect();
    for mode in [Mode::Mesh, Mode::Exact, Mode::Reference] {
        let hits = fly(&scene, mode, &flight);
        assert_eq!(hits.len(), 2, "{mode:?}: {hits:?}");
    }
}
