//! Issue 11: exact contacts as a layer of their own, sensing beside them, stable identities and
//! the vehicle's own clock. Each test names what it guards against.

use std::sync::Arc;
use std::time::Duration;

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use savsim::bench::{collisions, run_samples};
use savsim::collision::events::{Event, EventKind};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::ingest::address::ConnectAddress;
use savsim::ingest::live::Link;
use savsim::pipeline::{
    BodyKey, BodyPose, BodySource, CollisionConfig, DynamicBody, Mode, Pipeline, VehicleKey,
};
use savsim::scene::{Kind, Scene};
use savsim::session::Session;
use savsim::world::TrackSample;

use crate::common::{feed, position_frames, sample, scene_at, straight};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

fn scene(body: &str) -> Scene {
    scene_at(ORIGIN, body)
}

fn config(mode: Mode) -> CollisionConfig {
    CollisionConfig {
        mode,
        ..CollisionConfig::default()
    }
}

fn collisions_on(events: &[Event], vehicle: u16) -> Vec<(String, f64)> {
    events
        .iter()
        .filter(|e| e.vehicle == vehicle)
        .filter_map(|e| match &e.kind {
            EventKind::Collision {
                obstacle,
                time_of_impact,
                ..
            } => Some((obstacle.clone(), *time_of_impact)),
            _ => None,
        })
        .collect()
}

fn body(id: &str, source: BodySource, generation: u32, at: DVec3, geometry: usize) -> DynamicBody {
    let pose = BodyPose {
        position_enu_m: at,
        enu_from_body: DQuat::IDENTITY,
    };
    DynamicBody {
        key: BodyKey { source, generation },
        id: id.into(),
        kind: Kind::Dji,
        threat: 45.0,
        geometry_index: geometry,
        previous: pose,
        current: pose,
        speed_mps: 0.0,
    }
}

/// Moving bodies come, go and reorder between ticks (the panic of issue 11: a per-tick index
/// kept as an identity). Every event names the body it is about.
#[test]
fn moving_bodies_appearing_expiring_and_reordering_keep_their_identity() {
    let s = scene("");
    let quad = s.vehicle_model(1);
    let flight = straight(
        ORIGIN,
        DVec3::new(0.0, 0.0, 20.0),
        DVec3::new(40.0, 0.0, 20.0),
        10.0,
        10.0,
    );
    // A hovers 5 m beside the path and leaves after 1 s; B waits on the path at x = 30; C (a
    // "lower" key, listed first) appears at 2 s, 3 m beside the path; A comes back rebooted.
    let a = |generation| {
        body(
            "vehicle:5",
            BodySource::Vehicle {
                vehicle: 5,
                component_id: 1,
            },
            generation,
            DVec3::new(8.0, 5.0, 20.0),
            quad,
        )
    };
    let b = body(
        "b",
        BodySource::Traffic(7),
        1,
        DVec3::new(30.0, 0.0, 20.0),
        quad,
    );
    let c = body(
        "c",
        BodySource::Scripted(0),
        0,
        DVec3::new(22.0, 3.0, 20.0),
        quad,
    );
    for mode in [Mode::Paper, Mode::Exact, Mode::Reference] {
        let mut pipeline = Pipeline::new(&s, config(mode));
        let mut events = Vec::new();
        for (i, now) in flight.iter().enumerate() {
            let t = now.t_s - flight[0].t_s;
            let mut dynamic = Vec::new();
            if t >= 2.0 {
                dynamic.push(c.clone());
            }
            if t < 1.0 {
                dynamic.push(a(1));
            } else if t > 2.5 {
                dynamic.push(a(2));
            }
            dynamic.push(b.clone());
            let previous = i.checked_sub(1).map(|j| &flight[j]);
            pipeline.step(
                &s,
                VehicleKey::new(1),
                previous,
                now,
                &dynamic.clone().into(),
                &mut events,
            );
        }
        pipeline.finish(&mut events);
        let hits = collisions(&events);
        assert_eq!(hits.len(), 1, "{mode:?}: {hits:?}");
        assert_eq!(hits[0].0, "b", "{mode:?}");
        if mode != Mode::Reference {
            for e in &events {
                if let EventKind::NearMiss {
                    obstacle,
                    closest_m,
                    ..
                } = &e.kind
                {
                    let want = match obstacle.as_str() {
                        "vehicle:5" => 5.0,
                        "c" => 3.0,
                        other => panic!("{mode:?}: near miss on {other}"),
                    };
                    // Quad to quad: the centres' distance less about two half-widths.
                    assert!(*closest_m < want && *closest_m > want - 1.0, "{e:?}");
                }
            }
        }
    }
}

/// A companion vehicle whose track expires, then a new vehicle with a lower system id, through
/// a session: no panic, every collision on the right vehicle and body.
#[test]
fn a_session_survives_expiry_and_a_new_lower_sysid() {
    let s = scene(
        "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [1.0, 40.0, 40.0] }\nposition_enu_m = [60.0, 0.0, 0.0]\n",
    );
    let plane = LocalTangentPlane::new(s.origin);
    let mut session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    let mut seq = [0u8; 3];
    // Vehicle 9 hovers near the path for 2 s and goes silent (expires after 10 s); vehicle 1
    // flies east into the wall; vehicle 3 appears at 15 s 4 m beside vehicle 1's path.
    for i in 0..400u32 {
        let t = 1000.0 + f64::from(i) * 0.1;
        let x = f64::from(i) * 0.2;
        let ms = 5_000 + i * 100;
        let mut bytes = position_frames(
            &plane,
            1,
            &mut seq[0],
            ms,
            DVec3::new(x, 0.0, 20.0),
            DVec3::X * 2.0,
        );
        if i < 20 {
            bytes.extend(position_frames(
                &plane,
                9,
                &mut seq[1],
                ms,
                DVec3::new(2.0, 4.0, 20.0),
                DVec3::ZERO,
            ));
        }
        if i >= 150 {
            bytes.extend(position_frames(
                &plane,
                3,
                &mut seq[2],
                ms,
                DVec3::new(x + 10.0, 4.0, 20.0),
                DVec3::X * 2.0,
            ));
        }
        feed(&mut session, t, &bytes);
    }
    session.finish().unwrap();
    assert!(session.world().expired >= 1, "vehicle 9 expired");
    let on_1 = collisions_on(session.notable(), 1);
    assert_eq!(on_1.len(), 1, "{on_1:?}");
    assert_eq!(on_1[0].0, "wall");
    let on_3 = collisions_on(session.notable(), 3);
    assert_eq!(on_3.len(), 1, "{on_3:?}");
    assert_eq!(on_3[0].0, "wall");
}

/// Samples that arrive in one TCP read share a receive time; their interval comes from the
/// vehicle's clock, so a 200 m/s pass through a 1 m wall between them is swept and found.
#[test]
fn two_samples_in_one_tcp_read_are_swept_apart() {
    let s = scene(
        "[[obstacle]]\nid = \"wall\"\nkind = \"building\"\nshape = { box = [1.0, 40.0, 40.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let plane = LocalTangentPlane::new(s.origin);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    runtime.spawn(async move {
        use tokio::io::AsyncWriteExt;
        let (mut stream, _) = listener.accept().await.unwrap();
        let mut seq = 0u8;
        // Pairs 100 ms apart on the vehicle's clock, 20 m apart, each pair in one write; the
        // wall is crossed inside the second pair.
        for pair in 0..5u32 {
            let mut bytes = Vec::new();
            for k in 0..2u32 {
                let n = pair * 2 + k;
                let x = -50.0 + 20.0 * f64::from(n) + 5.0;
                bytes.extend(position_frames(
                    &plane,
                    1,
                    &mut seq,
                    10_000 + 100 * n,
                    DVec3::new(x, 0.0, 10.0),
                    DVec3::X * 200.0,
                ));
            }
            stream.write_all(&bytes).await.unwrap();
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    });
    let address = ConnectAddress::TcpOut(addr.into());
    let link = runtime.block_on(Link::open(&address)).unwrap();
    let session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    // The server sends for about 2 s, then closes; savsim would reconnect, and stops at 4 s.
    let run = crate::common::run_live(&runtime, vec![link], Duration::from_secs(4), session, None);
    let session = run.session;
    assert_eq!(session.stats().count_of(33), 10);
    let hits = collisions_on(session.notable(), 1);
    assert_eq!(hits.len(), 1, "{hits:?}");
    assert_eq!(hits[0].0, "wall");
}

/// `--near-miss-m 0`: a box the vehicle already overlaps at its first sample is a collision.
#[test]
fn near_miss_zero_still_reports_an_overlap_at_the_first_sample() {
    let s = scene(
        "[[obstacle]]\nid = \"cube\"\nkind = \"building\"\nshape = { box = [10.0, 10.0, 10.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let flight = straight(
        ORIGIN,
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::new(0.0, 20.0, 5.0),
        5.0,
        10.0,
    );
    for mode in [Mode::Box, Mode::Mesh, Mode::Exact, Mode::Reference] {
        let mut pipeline = Pipeline::new(
            &s,
            CollisionConfig {
                near_miss_m: 0.0,
                ..config(mode)
            },
        );
        let (_, events) = run_samples(&mut pipeline, &s, 1, &flight, &[]);
        let hits = collisions(&events);
        assert_eq!(hits.len(), 1, "{mode:?}: {hits:?}");
        assert!((hits[0].1 - flight[0].t_s).abs() < 1e-9, "{mode:?}");
    }
}

/// A reboot in the middle of a contact: the vehicle's state starts again (the contact that
/// still holds is a new collision, counted once), and nothing of the old life carries over.
#[test]
fn a_reboot_in_the_middle_of_a_contact_starts_a_new_episode() {
    let s = scene(
        "[[obstacle]]\nid = \"hangar\"\nkind = \"building\"\nshape = { box = [40.0, 40.0, 20.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    );
    let plane = LocalTangentPlane::new(s.origin);
    let mut session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    let mut seq = 0u8;
    // Inside the hangar from the start; rebooted at 3 s (time_boot_ms back to 1 s).
    for i in 0..60u32 {
        let t = 1000.0 + f64::from(i) * 0.1;
        let ms = if i < 30 {
            200_000 + i * 100
        } else {
            1_000 + (i - 30) * 100
        };
        let p = DVec3::new(f64::from(i) * 0.05, 0.0, 10.0);
        feed(
            &mut session,
            t,
            &position_frames(&plane, 1, &mut seq, ms, p, DVec3::X * 0.5),
        );
    }
    session.finish().unwrap();
    let hits = collisions_on(session.notable(), 1);
    assert_eq!(hits.len(), 2, "{hits:?}");
    assert!((hits[1].1 - 1003.0).abs() < 1e-6, "{hits:?}");
    let summary = session.summary("test", "frames");
    assert_eq!(summary["collision"]["state_resets"], 1);
    assert_eq!(summary["vehicles"][0]["boot_resets"], 1);
}

/// Two MAVLink vehicles flying at each other collide with each other: each is told, and the
/// times agree.
#[test]
fn vehicles_collide_with_each_other() {
    let s = scene("");
    let plane = LocalTangentPlane::new(s.origin);
    let mut session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    let mut seq = [0u8; 2];
    for i in 0..100u32 {
        let t = 1000.0 + f64::from(i) * 0.1;
        let ms = 50_000 + i * 100;
        let d = f64::from(i) * 0.5;
        let mut bytes = position_frames(
            &plane,
            1,
            &mut seq[0],
            ms,
            DVec3::new(-30.0 + d, 0.0, 30.0),
            DVec3::X * 5.0,
        );
        bytes.extend(position_frames(
            &plane,
            2,
            &mut seq[1],
            ms,
            DVec3::new(30.0 - d, 0.0, 30.0),
            DVec3::NEG_X * 5.0,
        ));
        feed(&mut session, t, &bytes);
    }
    session.finish().unwrap();
    let on_1 = collisions_on(session.notable(), 1);
    let on_2 = collisions_on(session.notable(), 2);
    assert_eq!(on_1.len(), 1, "{on_1:?}");
    assert_eq!(on_2.len(), 1, "{on_2:?}");
    assert_eq!(on_1[0].0, "vehicle:2");
    assert_eq!(on_2[0].0, "vehicle:1");
    // Nose to nose: the centres meet at 6 s; contact one quad length (0.62 m) earlier at 10 m/s
    // closing. Vehicle 2's tick sees vehicle 1 where its report says; both within a tick.
    for (_, t) in on_1.iter().chain(&on_2) {
        assert!((t - 1006.0).abs() < 0.15, "{on_1:?} {on_2:?}");
    }
}

/// A tessellated box as a Wavefront OBJ (each face split into `n` x `n` cells: a modelled
/// building's 12 n^2 triangles), `size` metres, standing on z = 0.
fn box_obj(size: [f64; 3], n: usize) -> String {
    let mut obj = String::new();
    let mut count = 0;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0.0, 1.0] {
            let base = count;
            for j in 0..=n {
                for i in 0..=n {
                    let mut p = [0.0; 3];
                    p[axis] = side * size[axis];
                    p[u] = size[u] * i as f64 / n as f64;
                    p[v] = size[v] * j as f64 / n as f64;
                    obj += &format!(
                        "v {} {} {}\n",
                        p[0] - size[0] / 2.0,
                        p[1] - size[1] / 2.0,
                        p[2]
                    );
                    count += 1;
                }
            }
            for j in 0..n {
                for i in 0..n {
                    let a = base + j * (n + 1) + i + 1;
                    let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
                    obj += &format!("f {a} {b} {d}\nf {a} {d} {c}\n");
                }
            }
        }
    }
    obj
}

/// A street of 24 loaded meshes (models from files: the one kind of exact shape that is a
/// triangle mesh, about 0.1 MiB each), every third across the street, and a flight along it.
fn street_of_meshes(dir: &std::path::Path) -> (Scene, Vec<TrackSample>) {
    let mut body = String::new();
    for k in 0..24 {
        let size = [12.0 + k as f64 * 0.25, 10.0, 20.0 + (k % 5) as f64 * 4.0];
        std::fs::write(dir.join(format!("b{k}.obj")), box_obj(size, 10)).unwrap();
        // Either side of the street (y = +-12 m), every third one across it (a collision).
        let y = match k % 3 {
            0 => 0.0,
            1 => 12.0,
            _ => -12.0,
        };
        body += &format!(
            "[[obstacle]]\nid = \"b{k}\"\nkind = \"building\"\nshape = {{ mesh = \"b{k}.obj\", up = \"z\" }}\nposition_enu_m = [{}, {y}, 0.0]\n",
            40.0 * k as f64
        );
    }
    let path = dir.join("street.toml");
    std::fs::write(
        &path,
        format!(
            "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n{body}",
            ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN.alt_m
        ),
    )
    .unwrap();
    let flight = straight(
        ORIGIN,
        DVec3::new(-30.0, 3.0, 12.0),
        DVec3::new(960.0, 3.0, 12.0),
        20.0,
        10.0,
    );
    (savsim::scene::load(&path).unwrap(), flight)
}

/// A mesh budget smaller than the flight needs: the street of meshes under 0.3 MiB. Meshes are
/// evicted and rebuilt, the held bytes stay within the budget, and nothing is missed against
/// the reference.
#[test]
fn a_mesh_budget_smaller_than_the_flight_needs_misses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (s, flight) = street_of_meshes(dir.path());
    let mut reference = Pipeline::new(&s, config(Mode::Reference));
    let truth = run_samples(&mut reference, &s, 1, &flight, &[]).1;
    let truth = collisions(&truth);
    // Every third building stands across the street; a loaded mesh is a surface, so its
    // near wall and its far wall are each a contact.
    assert_eq!(truth.len(), 16, "{truth:?}");
    let budget_mib = 0.3;
    let mut exact = Pipeline::new(
        &s,
        CollisionConfig {
            mesh_budget_mib: budget_mib,
            ..config(Mode::Exact)
        },
    );
    let found = run_samples(&mut exact, &s, 1, &flight, &[]).1;
    let found = collisions(&found);
    assert_eq!(found.len(), truth.len(), "{found:?} vs {truth:?}");
    for (a, b) in found.iter().zip(&truth) {
        assert_eq!(a.0, b.0);
        assert!((a.1 - b.1).abs() <= 1e-3, "{a:?} vs {b:?}");
    }
    assert!(
        exact.meshes().counts().evicted > 0,
        "the budget forced evictions"
    );
    let budget = (budget_mib * 1024.0 * 1024.0) as usize;
    assert!(
        exact.meshes().counts().peak_bytes <= budget + 200_000,
        "held {} at most, budget {budget}",
        exact.meshes().counts().peak_bytes
    );
    assert!(
        exact.meshes().counts().bytes <= budget,
        "held {}",
        exact.meshes().counts().bytes
    );
}

fn turning_flight(yaw_rate_radps: f64, roll_rad: f64, climb_mps: f64) -> Vec<TrackSample> {
    // 10 Hz, 12 m/s along x past a wall corner, yawing and rolling as it goes.
    (0..40)
        .map(|i| {
            let t = f64::from(i) * 0.1;
            let p = DVec3::new(-20.0 + 12.0 * t, 0.0, 10.0 + climb_mps * t);
            let mut s = sample(ORIGIN, 1000.0 + t, p, DVec3::new(12.0, 0.0, climb_mps));
            s.attitude.enu_from_frd = DQuat::from_rotation_z(yaw_rate_radps * t)
                * DQuat::from_rotation_x(std::f64::consts::PI + roll_rad * (t * 3.0).sin());
            s
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

    /// Turning, rolling and climbing sweeps past a corner (screw motion in the contact layer,
    /// dense sub-steps in the reference): the same collisions, within 1 ms. The corner's face
    /// is either well inside the spinning quad's reach (0.25-0.32 m, with its yaw) or clear
    /// of it: a graze that dips under a millimetre in and out is below the reference's own
    /// resolution (1 cm of travel, 0.1 degree of turn) and is not compared here.
    #[test]
    fn rotating_sweeps_agree_with_the_reference(
        yaw_rate in -3.0f64..3.0,
        roll in -0.6f64..0.6,
        climb in -2.0f64..2.0,
        offset in prop_oneof![-0.6f64..0.2, 0.36f64..0.6],
    ) {
        let s = scene(&format!(
            "[[obstacle]]\nid = \"corner\"\nkind = \"building\"\nshape = {{ blocks = [[0.0, 0.0, 0.0, 6.0, 1.0, 30.0], [0.0, 0.0, 0.0, 1.0, 6.0, 30.0]] }}\nposition_enu_m = [10.0, {offset}, 0.0]\n",
        ));
        let flight = turning_flight(yaw_rate, roll, climb);
        // A contact that flickers (touch, part, touch again within 5 ms: a rolling rotor tip
        // dipping under a millimetre) is below both sides' resolution: counted once.
        let run = |mode| {
            let mut p = Pipeline::new(&s, config(mode));
            let events = run_samples(&mut p, &s, 1, &flight, &[]).1;
            let mut hits: Vec<(String, f64)> = Vec::new();
            for (o, t) in collisions(&events) {
                if !hits.last().is_some_and(|(p, last)| p == o && t - *last < 5e-3) {
                    hits.push((o.to_owned(), t));
                }
            }
            hits
        };
        let truth = run(Mode::Reference);
        let exact = run(Mode::Exact);
        prop_assert_eq!(truth.len(), exact.len(), "{:?} vs {:?}", exact, truth);
        for (a, b) in exact.iter().zip(&truth) {
            prop_assert_eq!(&a.0, &b.0);
            prop_assert!((a.1 - b.1).abs() <= 1e-3, "{:?} vs {:?}", a, b);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, rng_seed: proptest::test_runner::RngSeed::Fixed(12), ..ProptestConfig::default() })]

    /// The same turning, rolling and climbing flights low over generated hills (terrain as a
    /// height field in the contact layer, as triangles of its own in the reference): the same
    /// collisions, within 1 ms.
    #[test]
    fn rotating_sweeps_over_terrain_agree_with_the_reference(
        yaw_rate in -3.0f64..3.0,
        roll in -0.6f64..0.6,
        climb in -3.0f64..1.0,
        seed in 0u64..1000,
        ground_m in 0.0f64..12.0,
    ) {
        let s = scene(&format!(
            "[[terrain]]\nid = \"hills\"\ngenerated = {{ seed = {seed}, size_m = [80.0, 40.0], cell_m = 5.0, relief_m = 8.0 }}\npatch_cells = 4\nposition_enu_m = [-30.0, -20.0, {}]\n",
            ground_m - 8.0
        ));
        let flight = turning_flight(yaw_rate, roll, climb);
        let run = |mode| {
            let mut p = Pipeline::new(&s, config(mode));
            let events = run_samples(&mut p, &s, 1, &flight, &[]).1;
            let mut hits: Vec<(String, f64)> = Vec::new();
            for (o, t) in collisions(&events) {
                if !hits.last().is_some_and(|(p, last)| p == o && t - *last < 5e-3) {
                    hits.push((o.to_owned(), t));
                }
            }
            hits
        };
        // Patches share their edges: a touch there is a contact with both at one instant, in
        // either order. Compared patch by patch.
        let by_patch = |mut hits: Vec<(String, f64)>| {
            hits.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
            hits
        };
        let truth = by_patch(run(Mode::Reference));
        let exact = by_patch(run(Mode::Exact));
        prop_assert_eq!(truth.len(), exact.len(), "{:?} vs {:?}", exact, truth);
        for (a, b) in exact.iter().zip(&truth) {
            prop_assert_eq!(&a.0, &b.0);
            prop_assert!((a.1 - b.1).abs() <= 1e-3, "{:?} vs {:?}", a, b);
        }
    }
}

/// 250 m/s at 5 Hz (50 m between samples) low over hills: the vehicle leaves the ground and
/// enters it again within one interval; each entry is a collision, as in the reference.
#[test]
fn a_fast_low_pass_counts_every_reentry_into_the_ground() {
    let s = scene(
        "[[terrain]]\nid = \"hills\"\ngenerated = { seed = 9, size_m = [3000.0, 3000.0], cell_m = 20.0, relief_m = 200.0 }\npatch_cells = 16\nposition_enu_m = [-1500.0, -1500.0, 0.0]\n",
    );
    let ground = |x: f64, y: f64| s.ground_height_enu_m(x, y).unwrap();
    let z = ground(0.0, 0.0) + 5.0;
    let flight = straight(
        ORIGIN,
        DVec3::new(-1400.0, 0.0, z),
        DVec3::new(1400.0, 0.0, z),
        250.0,
        5.0,
    );
    let run = |mode| {
        let mut p = Pipeline::new(&s, config(mode));
        let events = run_samples(&mut p, &s, 1, &flight, &[]).1;
        collisions(&events)
            .into_iter()
            .map(|(o, t)| (o.to_owned(), t))
            .collect::<Vec<_>>()
    };
    let truth = run(Mode::Reference);
    let exact = run(Mode::Exact);
    assert!(
        truth.len() >= 3,
        "the pass must enter the ground often: {truth:?}"
    );
    assert_eq!(exact.len(), truth.len(), "{exact:?} vs {truth:?}");
    for (a, b) in exact.iter().zip(&truth) {
        assert_eq!(a.0, b.0);
        assert!((a.1 - b.1).abs() <= 1e-3, "{a:?} vs {b:?}");
    }
}

/// A session on a clone of one pipeline built once with every mesh resident (what the fuzz
/// targets share between inputs) reports what a session of its own reports, builds no mesh
/// again, and leaves the shared pipeline as it was for the next run.
#[test]
fn a_session_on_a_shared_pipeline_reports_what_a_fresh_one_does() {
    let s = Arc::new(scene(concat!(
        "[[obstacle]]\nid = \"u-plan\"\nkind = \"building\"\n",
        "shape = { blocks = [[-20.0, -20.0, 0.0, 20.0, -10.0, 30.0], [-20.0, -20.0, 0.0, -10.0, 20.0, 30.0], [10.0, -20.0, 0.0, 20.0, 20.0, 30.0]], tessellate_m = 3 }\n",
        "position_enu_m = [60.0, 0.0, 0.0]\n",
        "[[obstacle]]\nid = \"mast\"\nkind = \"building\"\nshape = { box = [2.0, 2.0, 40.0] }\n",
        "position_enu_m = [20.0, 4.0, 0.0]\n",
        "[[terrain]]\nid = \"hill\"\nkind = \"mountain\"\n",
        "generated = { seed = 3, size_m = [200, 200], cell_m = 20, relief_m = 10 }\n",
        "position_enu_m = [-50.0, -100.0, -10.0]\n",
    )));
    let plane = LocalTangentPlane::new(s.origin);
    // East at 4 m/s, 15 m up: past the mast 2.5 m away, into the U's west wing at x = 40 m.
    let fly = |session: &mut Session| {
        let mut seq = 0u8;
        for i in 0..300u32 {
            let t = 1000.0 + f64::from(i) * 0.1;
            let p = DVec3::new(f64::from(i) * 0.4, 0.5, 15.0);
            let bytes = position_frames(&plane, 1, &mut seq, 5_000 + i * 100, p, DVec3::X * 4.0);
            feed(session, t, &bytes);
        }
        session.finish().unwrap();
    };
    let mut fresh = Session::new(Some(s.clone()), CollisionConfig::default(), None).unwrap();
    fly(&mut fresh);
    let fresh_pipeline = fresh.pipeline().unwrap();
    assert_eq!(collisions_on(fresh.notable(), 1)[0].0, "u-plan");
    // The terrain's exact shape is a height field and the blocks' a compound: no mesh at all.
    assert_eq!(
        fresh_pipeline.meshes().counts().built,
        0,
        "exact builds no mesh here"
    );

    let mut shared = Pipeline::new(&s, CollisionConfig::default());
    shared.build_every_mesh(&s);
    let built = shared.meshes().counts().built;
    assert_eq!(built, 3);
    for _ in 0..2 {
        let mut session = Session::with_pipeline(s.clone(), shared.clone(), None).unwrap();
        fly(&mut session);
        let pipeline = session.pipeline().unwrap();
        assert_eq!(session.notable(), fresh.notable());
        assert_eq!(pipeline.totals(), fresh_pipeline.totals());
        assert_eq!(
            pipeline.meshes().counts().built,
            built,
            "no mesh was built again"
        );
    }
    assert_eq!(shared.totals().ticks, 0, "the shared pipeline is untouched");
}

/// A swarm large enough for the moving bodies' own broad phase (its `Bvh`): pairs of quads
/// head-on, every other pair level (they collide), the others 3 m apart in height (a near
/// miss), each vehicle an
/// obstacle to every other. `exact` finds what the reference finds, vehicle by vehicle.
#[test]
fn a_swarm_through_the_moving_bodies_broad_phase_agrees_with_the_reference() {
    let s = scene("");
    let pairs = 16;
    let flights: Vec<Vec<TrackSample>> = (0..2 * pairs)
        .map(|k| {
            let (pair, side) = ((k / 2) as f64, if k % 2 == 0 { -1.0 } else { 1.0 });
            let z = 30.0 + if k % 4 == 3 { 3.0 } else { 0.0 };
            let y = pair * 12.0;
            straight(
                ORIGIN,
                DVec3::new(20.0 * side, y, z),
                DVec3::new(-20.0 * side, y, z),
                5.0,
                10.0,
            )
        })
        .collect();
    let ids: Vec<Arc<str>> = (0..flights.len())
        .map(|k| format!("vehicle:{k}").into())
        .collect();
    let model = s.vehicle_model(1);
    let fly = |mode: Mode| -> Vec<Event> {
        let mut pipeline = Pipeline::new(&s, config(mode));
        let mut events = Vec::new();
        for i in 0..flights[0].len() {
            let bodies: Vec<DynamicBody> = flights
                .iter()
                .enumerate()
                .map(|(k, f)| DynamicBody {
                    key: VehicleKey::new(k as u16).as_body(),
                    id: ids[k].clone(),
                    kind: Kind::Dji,
                    threat: 45.0,
                    geometry_index: model,
                    previous: BodyPose::of(&f[i.saturating_sub(1)]),
                    current: BodyPose::of(&f[i]),
                    speed_mps: 5.0,
                })
                .collect();
            let moving = bodies.into();
            for (k, f) in flights.iter().enumerate() {
                let previous = i.checked_sub(1).map(|p| &f[p]);
                pipeline.step(
                    &s,
                    VehicleKey::new(k as u16),
                    previous,
                    &f[i],
                    &moving,
                    &mut events,
                );
            }
        }
        pipeline.finish(&mut events);
        events
    };
    let (found, truth) = (fly(Mode::Exact), fly(Mode::Reference));
    let mut colliding = 0;
    for k in 0..flights.len() as u16 {
        let (f, t) = (collisions_on(&found, k), collisions_on(&truth, k));
        assert_eq!(f.len(), t.len(), "vehicle {k}: {f:?} vs {t:?}");
        for (a, b) in f.iter().zip(&t) {
            assert_eq!(a.0, b.0, "vehicle {k}");
            assert!((a.1 - b.1).abs() <= 1e-3, "vehicle {k}: {a:?} vs {b:?}");
        }
        colliding += usize::from(!t.is_empty());
    }
    // Every other pair is level: 16 vehicles collide, the other 16 pass 3 m apart.
    assert_eq!(colliding, 16);
    let near: Vec<&Event> = found
        .iter()
        .filter(|e| matches!(e.kind, EventKind::NearMiss { .. }))
        .collect();
    assert!(near.len() >= 8, "{near:?}");
}

/// The mesh worker builds the meshes the sensing layer asks for off the tick path; the same
/// meshes are resident at the same decisions whether it runs or not: the same events, the same
/// counts, and no mesh built for a contact on the flight along the street.
#[test]
fn the_mesh_worker_changes_where_meshes_are_built_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let (s, flight) = street_of_meshes(dir.path());
    let run = |worker: bool, budget_mib: f64| {
        let mut p = Pipeline::new(
            &s,
            CollisionConfig {
                mesh_budget_mib: budget_mib,
                ..config(Mode::Exact)
            },
        );
        p.set_mesh_worker(worker);
        let events = run_samples(&mut p, &s, 1, &flight, &[]).1;
        let m = &p.meshes();
        let counts = (
            m.counts().built,
            m.counts().built_on_contact,
            m.counts().evicted,
            m.counts().peak_bytes,
            m.counts().prefetch_refused,
        );
        (events, counts)
    };
    for budget_mib in [512.0, 0.3] {
        let (with, counts_with) = run(true, budget_mib);
        let (without, counts_without) = run(false, budget_mib);
        assert_eq!(with, without, "budget {budget_mib} MiB");
        assert_eq!(counts_with, counts_without, "budget {budget_mib} MiB");
        if budget_mib > 1.0 {
            assert_eq!(
                counts_with.1, 0,
                "every mesh was resident before a contact needed it"
            );
            assert!(counts_with.0 >= 8, "{counts_with:?}");
        }
    }
}

/// The sensing fan is configurable: a tower 50 m ahead and to the right at 45 degrees is seen
/// by the eight-ray ring's second ray (forward, then clockwise) and by none of the paper's six
/// axes; a levelled ring does not see the ground when the vehicle pitches down.
#[test]
fn the_sensing_fan_is_configurable() {
    use savsim::pipeline::{MovingBodies, SensorFan};
    let s = scene(
        "[[obstacle]]\nid = \"tower\"\nkind = \"building\"\nshape = { box = [4.0, 4.0, 60.0] }\nposition_enu_m = [37.36, -37.36, 0.0]\n",
    );
    // Nose east at 20 m up: the tower is south-east, 45 degrees right of the nose.
    let at = sample(ORIGIN, 1000.0, DVec3::new(0.0, 0.0, 20.0), DVec3::X);
    let rays = |fan: SensorFan, sample: &TrackSample| {
        let mut p = Pipeline::new(
            &s,
            CollisionConfig {
                sensor_fan: fan,
                ..config(Mode::Exact)
            },
        );
        let mut events = Vec::new();
        p.step(
            &s,
            VehicleKey::new(1),
            None,
            sample,
            &MovingBodies::default(),
            &mut events,
        );
        p.vehicle(1, 1).unwrap().sensing.rays.clone()
    };
    let six = rays(SensorFan::Axes, &at);
    assert_eq!(six.len(), 6);
    assert!(six.iter().all(|(_, hit)| hit.is_none()), "{six:?}");
    let ring = rays(SensorFan::Ring { rays: 8 }, &at);
    assert_eq!(ring.len(), 10);
    let (dir, hit) = ring[1];
    assert!(
        (dir - DVec3::new(1.0, -1.0, 0.0).normalize()).length() < 1e-9,
        "{dir}"
    );
    // The tower's near corner is at 50.0 - 2 sqrt(2) m along the diagonal.
    let d = hit.expect("the second ray sees the tower").distance_m;
    assert!((d - (52.83 - 2.0 * 2f64.sqrt())).abs() < 0.05, "{d}");
    assert!(ring
        .iter()
        .enumerate()
        .all(|(k, r)| k == 1 || r.1.is_none()));
    // Pitched 30 degrees nose down over flat ground (a scene of terrain): the body ring's
    // forward ray meets the ground, the levelled ring's does not.
    let ground = scene(
        "[[terrain]]\nid = \"flat\"\ngenerated = { seed = 1, size_m = [400.0, 400.0], cell_m = 20.0, relief_m = 0.0 }\nposition_enu_m = [-200.0, -200.0, 0.0]\n",
    );
    let mut pitched = at;
    pitched.attitude.enu_from_frd =
        DQuat::from_rotation_y(30f64.to_radians()) * DQuat::from_rotation_x(std::f64::consts::PI);
    let cast = |fan| {
        let mut p = Pipeline::new(
            &ground,
            CollisionConfig {
                sensor_fan: fan,
                ..config(Mode::Exact)
            },
        );
        let mut events = Vec::new();
        p.step(
            &ground,
            VehicleKey::new(1),
            None,
            &pitched,
            &MovingBodies::default(),
            &mut events,
        );
        p.vehicle(1, 1).unwrap().sensing.rays.clone()
    };
    let body = cast(SensorFan::Ring { rays: 4 });
    let level = cast(SensorFan::LevelRing { rays: 4 });
    let forward_body = body[0]
        .1
        .expect("pitched down, the body's forward ray meets the ground");
    assert!(
        (forward_body.distance_m - 40.0).abs() < 0.05,
        "{forward_body:?}"
    );
    assert!(level[..4].iter().all(|r| r.1.is_none()), "{level:?}");
    assert!(
        (level[4].1.unwrap().distance_m - 20.0).abs() < 0.05,
        "the levelled down ray"
    );
}
