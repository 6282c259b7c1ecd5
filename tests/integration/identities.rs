//! Identities that outlive a tick: moving bodies that come, go, reorder and reboot keep their
//! own events; a track that expires and a new vehicle with a lower system id; a reboot in the
//! middle of a contact; vehicles colliding with each other; a swarm through the moving bodies'
//! broad phase against the reference.

use std::sync::Arc;

use glam::{DQuat, DVec3};
use savsim::bench::collisions;
use savsim::collision::events::{Event, EventKind};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::{
    BodyKey, BodyPose, BodySource, CollisionConfig, DynamicBody, Mode, Pipeline, VehicleKey,
};
use savsim::scene::{Kind, Scene};
use savsim::session::Session;
use savsim::world::TrackSample;

use crate::common::{collisions_on, feed, position_frames, scene_at, straight};

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

/// Two vehicles that share a system id (a fleet past 250 vehicles numbers them by component)
/// keep their own closest approaches: 7/1 passes vehicle 8 40 m off, 7/2 100 m off. They were
/// one entry, the closer, keyed by system id alone.
#[test]
fn vehicles_sharing_a_system_id_keep_their_own_closest_approaches() {
    let s = scene("");
    let plane = LocalTangentPlane::new(s.origin);
    let mut session = Session::new(Some(Arc::new(s)), CollisionConfig::default(), None).unwrap();
    let nose_east = [0.0, 0.0, std::f64::consts::FRAC_PI_2];
    let mut seq = 0u8;
    let mut frames = |sysid: u8, compid: u8, ms: u32, p: DVec3, v: DVec3| {
        let mut bytes = Vec::new();
        for m in crate::common::pose_messages(&plane, ms, p, v, nose_east) {
            bytes.extend(crate::common::frame_v2(sysid, compid, seq, &m));
            seq = seq.wrapping_add(1);
        }
        bytes
    };
    for i in 0..200u32 {
        let t = 1000.0 + f64::from(i) * 0.1;
        let ms = 50_000 + i * 100;
        let x = -100.0 + f64::from(i);
        let mut bytes = frames(7, 1, ms, DVec3::new(x, 40.0, 30.0), DVec3::X * 10.0);
        bytes.extend(frames(
            7,
            2,
            ms,
            DVec3::new(x, 100.0, 30.0),
            DVec3::X * 10.0,
        ));
        bytes.extend(frames(8, 1, ms, DVec3::new(0.0, 0.0, 30.0), DVec3::ZERO));
        feed(&mut session, t, &bytes);
    }
    session.finish().unwrap();
    let summary = session.summary("test", "");
    let to_8 = |component: u64| -> Vec<f64> {
        summary["approaches"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["vehicle"] == 7 && a["component"] == component)
            .filter(|a| a["track"].as_str().is_some_and(|t| t.contains('8')))
            .map(|a| a["distance_m"].as_f64().unwrap())
            .collect()
    };
    let (one, two) = (to_8(1), to_8(2));
    assert_eq!(one.len(), 1, "{}", summary["approaches"]);
    assert_eq!(two.len(), 1, "{}", summary["approaches"]);
    assert!((one[0] - 40.0).abs() < 0.5, "{one:?}");
    assert!((two[0] - 100.0).abs() < 0.5, "{two:?}");
}
