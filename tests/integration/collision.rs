//! Golden scenarios, one per step of the algorithm, run through `Pipeline::step` with
//! synthetic flights (tests/integration/common.rs).

use glam::{DQuat, DVec3};
use savsim::bench::{collisions, run_samples};
use savsim::collision::events::{Event, EventKind};
use savsim::collision::sensing::threat::{AhpWeights, PAPER_MATRIX};
use savsim::collision::ColliderKind;
use savsim::geo::Geodetic;
use savsim::pipeline::{
    BodyKey, BodyPose, BodySource, CollisionConfig, DynamicBody, Mode, Pipeline, VehicleKey,
};
use savsim::scene::Scene;
use savsim::world::TrackSample;

use crate::common::{sample, scene_at, straight};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

fn scene(body: &str) -> Scene {
    scene_at(ORIGIN, body)
}

fn obstacle(id: &str, shape: &str, at: [f64; 3]) -> String {
    format!("[[obstacle]]\nid = \"{id}\"\nkind = \"building\"\nshape = {shape}\nposition_enu_m = {at:?}\n")
}

/// Run a flight through a pipeline; every tick sees `dynamic(t_prev, t_now)`.
fn fly_with(
    scene: &Scene,
    mode: Mode,
    flight: &[TrackSample],
    dynamic: &dyn Fn(f64, f64) -> Vec<DynamicBody>,
) -> (Pipeline, Vec<Event>) {
    let mut pipeline = Pipeline::new(
        scene,
        CollisionConfig {
            mode,
            ..CollisionConfig::default()
        },
    );
    let mut events = Vec::new();
    for (i, s) in flight.iter().enumerate() {
        let previous = i.checked_sub(1).map(|j| &flight[j]);
        let bodies = dynamic(previous.map_or(s.t_s, |p| p.t_s), s.t_s);
        pipeline.step(
            scene,
            VehicleKey::new(1),
            previous,
            s,
            &bodies.into(),
            &mut events,
        );
    }
    pipeline.finish(&mut events);
    (pipeline, events)
}

fn fly(scene: &Scene, mode: Mode, flight: &[TrackSample]) -> (Pipeline, Vec<Event>) {
    fly_with(scene, mode, flight, &|_, _| Vec::new())
}

fn swaps<'a>(events: &'a [Event], id: &str) -> Vec<(ColliderKind, ColliderKind, &'a str, f64)> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::ColliderSwap {
                obstacle,
                from,
                to,
                reason,
                distance_m,
                ..
            } if obstacle == id => Some((*from, *to, *reason, *distance_m)),
            _ => None,
        })
        .collect()
}

/// A grid of thin poles that makes the octree split into ~125 m leaves.
fn poles() -> String {
    let mut s = String::new();
    for i in -10..10 {
        for j in -10..10 {
            s += &obstacle(
                &format!("pole{i}_{j}"),
                "{ box = [0.5, 0.5, 5.0] }",
                [i as f64 * 100.0 + 50.0, j as f64 * 100.0 + 50.0, 0.0],
            );
        }
    }
    s
}

#[test]
fn ahp_weights_and_consistency_match_hand_computation() {
    // Row products 3.5, 15/28, 8/15; cube roots normalised; lambda_max = mean((A w)_i / w_i).
    let w = AhpWeights::from_matrix(PAPER_MATRIX).unwrap();
    for (got, want) in
        w.w.iter()
            .zip([0.483_314_704_731, 0.258_534_439_043, 0.258_150_856_226])
    {
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
    assert!((w.lambda_max - 3.049_334_106_899).abs() < 1e-9);
    assert!((w.cr - 0.042_529_402_499).abs() < 1e-9);
    // A perfectly consistent matrix has CR 0; an inconsistent one is flagged.
    assert!(
        AhpWeights::from_matrix([[1.0, 2.0, 4.0], [0.5, 1.0, 2.0], [0.25, 0.5, 1.0]])
            .unwrap()
            .cr
            .abs()
            < 1e-12
    );
    assert!(
        AhpWeights::from_matrix([
            [1.0, 9.0, 1.0 / 9.0],
            [1.0 / 9.0, 1.0, 9.0],
            [9.0, 1.0 / 9.0, 1.0]
        ])
        .unwrap()
        .cr > 0.1
    );
    assert!(AhpWeights::from_matrix([[1.0, 0.0, 1.0]; 3]).is_none());
}

#[test]
fn crossing_node_boundaries_drops_the_old_nodes_colliders() {
    let s = scene(&poles());
    let flight = straight(
        ORIGIN,
        DVec3::new(-600.0, 0.0, 2.0),
        DVec3::new(600.0, 0.0, 2.0),
        20.0,
        10.0,
    );
    let (pipeline, events) = fly(&s, Mode::Paper, &flight);
    assert!(pipeline.octree().depth() >= 4);
    // Every obstacle's swaps chain (from = previous to), start from none, and some end in none.
    let mut left = 0;
    for o in &s.obstacles {
        let mut state = ColliderKind::None;
        for (from, to, reason, _) in swaps(&events, &o.id) {
            assert_eq!(from, state, "{}", o.id);
            state = to;
            left += usize::from(reason == "left");
        }
    }
    assert!(left > 10, "nodes were left: {left}");
    assert!(collisions(&events).is_empty());
}

#[test]
fn an_obstacle_just_across_a_node_face_is_not_hidden() {
    let base = poles();
    let s0 = scene(&base);
    let probe = Pipeline::new(&s0, CollisionConfig::default());
    let p = DVec3::new(10.0, 20.0, 3.0);
    let leaf = probe.octree().node_aabb(probe.octree().leaf_at(p).unwrap());
    let face_x = leaf.max.x;
    // A wall whose west face is 5 cm beyond the leaf's east face.
    let wall = obstacle(
        "wall",
        "{ box = [4.0, 20.0, 30.0] }",
        [face_x + 2.05, p.y, 0.0],
    );
    let s = scene(&format!("{base}{wall}"));
    // Fly east and stop with the centre 10 cm inside the leaf: the 0.62 m quad overlaps the wall.
    let stop = DVec3::new(face_x - 0.10, p.y, p.z);
    let flight = straight(ORIGIN, stop - DVec3::new(30.0, 0.0, 0.0), stop, 2.0, 10.0);
    let pipeline = Pipeline::new(&s, CollisionConfig::default());
    assert_eq!(
        pipeline
            .octree()
            .node_aabb(pipeline.octree().leaf_at(stop).unwrap())
            .max
            .x,
        face_x
    );
    let hit = |mode| {
        collisions(&fly(&s, mode, &flight).1)
            .iter()
            .any(|(o, _)| *o == "wall")
    };
    assert!(!hit(Mode::Paper), "the paper only sees its own node");
    assert!(hit(Mode::Exact));
    assert!(hit(Mode::Reference));
}

#[test]
fn approach_and_retreat_cross_300_and_800_m() {
    // Four far corners keep the octree one big leaf; the tower is 1 km north.
    let mut body = String::new();
    for (i, (x, y)) in [
        (-3000.0, -3000.0),
        (3000.0, -3000.0),
        (-3000.0, 3000.0),
        (3000.0, 3000.0),
    ]
    .iter()
    .enumerate()
    {
        body += &obstacle(
            &format!("corner{i}"),
            "{ box = [1.0, 1.0, 1.0] }",
            [*x, *y, 0.0],
        );
    }
    body += &obstacle("tower", "{ box = [20.0, 20.0, 200.0] }", [0.0, 1000.0, 0.0]);
    let s = scene(&body);
    let mut flight = straight(
        ORIGIN,
        DVec3::new(0.0, -200.0, 50.0),
        DVec3::new(0.0, 750.0, 50.0),
        25.0,
        10.0,
    );
    let t0 = flight.last().unwrap().t_s;
    let back = straight(
        ORIGIN,
        DVec3::new(0.0, 750.0, 50.0),
        DVec3::new(0.0, -300.0, 50.0),
        25.0,
        10.0,
    );
    flight.extend(back.into_iter().skip(1).map(|mut x| {
        x.t_s += t0 - 1000.0 + 0.1;
        x
    }));
    for mode in [Mode::Paper, Mode::Exact] {
        let (_, events) = fly(&s, mode, &flight);
        let mut tower = swaps(&events, "tower");
        let kinds: Vec<_> = tower.iter().map(|(f, t, r, _)| (*f, *t, *r)).collect();
        // The paper reports its node giving the tower a box; the sensor reports only what the
        // rays (threat) and the distance (far) changed.
        let mut expected = vec![
            (ColliderKind::Box, ColliderKind::Mesh, "threat"),
            (ColliderKind::Mesh, ColliderKind::Box, "far"),
        ];
        if mode == Mode::Paper {
            expected.insert(0, (ColliderKind::None, ColliderKind::Box, "node"));
            tower.remove(0);
        }
        assert_eq!(kinds, expected, "{mode:?}");
        assert!(
            tower[0].3 < 300.0 && tower[0].3 > 290.0,
            "{mode:?}: mesh at {} m",
            tower[0].3
        );
        assert!(
            tower[1].3 > 800.0 && tower[1].3 < 803.0,
            "{mode:?}: box at {} m",
            tower[1].3
        );
    }
}

#[test]
fn a_fast_mover_does_not_tunnel_through_a_thin_wall() {
    let s = scene(&obstacle(
        "wall",
        "{ box = [0.5, 100.0, 100.0] }",
        [0.0, 0.0, 0.0],
    ));
    // 250 m/s, 10 Hz: 25 m between samples, none of them near the wall.
    let flight = straight(
        ORIGIN,
        DVec3::new(-512.3, 0.0, 50.0),
        DVec3::new(487.7, 0.0, 50.0),
        250.0,
        10.0,
    );
    assert!(flight.iter().all(|x| x.position_enu_m.x.abs() > 5.0));
    for mode in [Mode::Box, Mode::Mesh, Mode::Paper] {
        assert!(
            collisions(&fly(&s, mode, &flight).1).is_empty(),
            "{mode:?} checks samples only"
        );
    }
    // The quad reaches 0.31 m ahead of its centre: first contact when the centre is at -0.56 m.
    let expected_t = 1000.0 + (512.3 - 0.25 - 0.31) / 250.0;
    for mode in [Mode::Exact, Mode::Reference] {
        let (_, events) = fly(&s, mode, &flight);
        let c = collisions(&events);
        assert_eq!(c.len(), 1, "{mode:?}: {c:?}");
        assert!(
            (c[0].1 - expected_t).abs() < 2e-3,
            "{mode:?}: {} vs {expected_t}",
            c[0].1
        );
    }
}

#[test]
fn a_concave_building_box_says_hit_mesh_says_clear() {
    // A U with a 30 m courtyard open to the north; the flight goes down the courtyard.
    let u = "{ blocks = [[-25.0, -25.0, 0.0, 25.0, -15.0, 40.0], [-25.0, -25.0, 0.0, -15.0, 25.0, 40.0], [15.0, -25.0, 0.0, 25.0, 25.0, 40.0]] }";
    let s = scene(&obstacle("u", u, [0.0, 0.0, 0.0]));
    let flight = straight(
        ORIGIN,
        DVec3::new(0.0, 100.0, 20.0),
        DVec3::new(0.0, -10.0, 20.0),
        10.0,
        10.0,
    );
    assert_eq!(
        collisions(&fly(&s, Mode::Box, &flight).1).len(),
        1,
        "the box is a false collision"
    );
    for mode in [Mode::Mesh, Mode::Exact, Mode::Reference] {
        assert!(collisions(&fly(&s, mode, &flight).1).is_empty(), "{mode:?}");
    }
    // Flying on into the back wall is a real collision in every mode.
    let into = straight(
        ORIGIN,
        DVec3::new(0.0, 100.0, 20.0),
        DVec3::new(0.0, -20.0, 20.0),
        10.0,
        10.0,
    );
    for mode in [Mode::Box, Mode::Mesh, Mode::Exact, Mode::Reference] {
        assert_eq!(collisions(&fly(&s, mode, &into).1).len(), 1, "{mode:?}");
    }
}

#[test]
fn a_traffic_aircraft_on_a_collision_course() {
    let s = scene(&obstacle(
        "far",
        "{ box = [1.0, 1.0, 1.0] }",
        [5000.0, 5000.0, 0.0],
    ));
    let airliner = s.kind_model(savsim::scene::Kind::A320);
    // The UAV flies east at 10 m/s; the airliner flies west at 70 m/s at the same height.
    let flight = straight(
        ORIGIN,
        DVec3::new(0.0, 0.0, 300.0),
        DVec3::new(400.0, 0.0, 300.0),
        10.0,
        10.0,
    );
    let start = flight[0].t_s;
    let pose = move |t: f64| {
        let x = 2000.0 - 70.0 * (t - start);
        BodyPose {
            position_enu_m: DVec3::new(x, 0.0, 300.0),
            enu_from_body: glam::DQuat::from_rotation_z(std::f64::consts::PI)
                * glam::DQuat::from_rotation_x(std::f64::consts::PI),
        }
    };
    let dynamic = move |t0: f64, t1: f64| {
        vec![DynamicBody {
            key: BodyKey {
                source: BodySource::Scripted(0),
                generation: 0,
            },
            id: "airliner".into(),
            kind: savsim::scene::Kind::A320,
            threat: 75.0,
            geometry_index: airliner,
            previous: pose(t0),
            current: pose(t1),
            speed_mps: 70.0,
        }]
    };
    // They meet when 2000 - 70 t = 10 t (less half the airliner's length).
    let expected = start + (2000.0 - 18.8 - 0.31) / 80.0;
    for mode in [Mode::Exact, Mode::Reference] {
        let (_, events) = fly_with(&s, mode, &flight, &dynamic);
        let c = collisions(&events);
        assert_eq!(c.first().map(|x| x.0), Some("airliner"), "{mode:?}: {c:?}");
        assert!(
            (c[0].1 - expected).abs() < 0.05,
            "{mode:?}: {} vs {expected}",
            c[0].1
        );
        if mode == Mode::Exact {
            let to_mesh = swaps(&events, "airliner")
                .into_iter()
                .find(|s| s.1 == ColliderKind::Mesh);
            assert!(
                to_mesh.is_some_and(|s| s.2 == "threat"),
                "the airliner ahead is a threat: {events:?}"
            );
        }
    }
}

#[test]
fn a_telemetry_gap_is_reported_not_swept() {
    let s = scene(&obstacle(
        "wall",
        "{ box = [0.5, 100.0, 100.0] }",
        [0.0, 0.0, 0.0],
    ));
    let a = sample(
        ORIGIN,
        1000.0,
        DVec3::new(-100.0, 0.0, 50.0),
        DVec3::X * 20.0,
    );
    let b = sample(
        ORIGIN,
        1010.0,
        DVec3::new(100.0, 0.0, 50.0),
        DVec3::X * 20.0,
    );
    let (_, events) = fly(&s, Mode::Exact, &[a, b]);
    assert!(collisions(&events).is_empty());
    assert!(events.iter().any(
        |e| matches!(e.kind, EventKind::TelemetryGap { gap_s, .. } if (gap_s - 10.0).abs() < 1e-9)
    ));
}

#[test]
fn far_from_the_scene_origin_precision_holds() {
    // A wall 1000 km east of the origin, a vehicle stopping 0.30 m and 0.33 m short of contact.
    let s = scene(&obstacle(
        "far-wall",
        "{ box = [1.0, 50.0, 50.0] }",
        [1.0e6, 2.0e5, 0.0],
    ));
    for (gap_m, hit) in [(-0.01, true), (0.02, false)] {
        // Quad half-length 0.31 m; wall face at 1e6 - 0.5.
        let stop = DVec3::new(1.0e6 - 0.5 - 0.31 - gap_m, 2.0e5, 10.0);
        let flight = straight(ORIGIN, stop - DVec3::X * 5.0, stop, 1.0, 10.0);
        for mode in [Mode::Mesh, Mode::Exact, Mode::Reference] {
            assert_eq!(
                !collisions(&fly(&s, mode, &flight).1).is_empty(),
                hit,
                "{mode:?} gap {gap_m}"
            );
        }
    }
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
                mode,
                near_miss_m: 0.0,
                ..CollisionConfig::default()
            },
        );
        let (_, events) = run_samples(&mut pipeline, &s, 1, &flight, &[]);
        let hits = collisions(&events);
        assert_eq!(hits.len(), 1, "{mode:?}: {hits:?}");
        assert!((hits[0].1 - flight[0].t_s).abs() < 1e-9, "{mode:?}");
    }
}

/// The sensing fan is configurable: a tower 50 m ahead and to the right at 45 degrees is seen
/// by the eight-ray ring's second ray (forward, then clockwise) and by none of the paper's six
/// axes; a levelled ring does not see the ground when the vehicle pitches down.
#[test]
fn a_tick_says_beforehand_whether_it_senses() {
    // Exact mode at 20 Hz: a frame at the first sample, none 0.03 s later, one 0.05 s after
    // the first; a new generation is a new vehicle (a frame is due); box mode never senses.
    let s = scene("");
    let mut p = Pipeline::new(&s, CollisionConfig::default());
    let key = VehicleKey::new(1);
    let first = sample(ORIGIN, 1000.0, DVec3::new(0.0, 0.0, 20.0), DVec3::X);
    assert!(p.senses_at(key, first.t_s));
    let mut events = Vec::new();
    let report = p.step(&s, key, None, &first, &Default::default(), &mut events);
    assert!(report.sensed);
    for (dt, due) in [(0.03, false), (0.0499, false), (0.05, true), (-0.1, true)] {
        assert_eq!(p.senses_at(key, first.t_s + dt), due, "{dt}");
        let mut later = first;
        later.t_s += dt;
        let mut q = p.clone();
        let report = q.step(
            &s,
            key,
            Some(&first),
            &later,
            &Default::default(),
            &mut events,
        );
        assert_eq!(report.sensed, due, "{dt}");
    }
    let reborn = VehicleKey {
        generation: key.generation + 1,
        ..key
    };
    assert!(p.senses_at(reborn, first.t_s + 0.01));
    let boxes = Pipeline::new(
        &s,
        CollisionConfig {
            mode: Mode::Box,
            ..CollisionConfig::default()
        },
    );
    assert!(!boxes.senses_at(key, first.t_s));
}

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
                mode: Mode::Exact,
                sensor_fan: fan,
                ..CollisionConfig::default()
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
                mode: Mode::Exact,
                sensor_fan: fan,
                ..CollisionConfig::default()
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
