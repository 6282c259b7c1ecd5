//! Sweeps that turn, roll and climb (screw motion), past a corner and low over hills, and a
//! fast low pass that enters the ground again and again within one interval: the contact
//! layer's `exact` mode against the reference, collision by collision.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use savsim::bench::{collisions, run_samples};
use savsim::geo::Geodetic;
use savsim::pipeline::{CollisionConfig, Mode, Pipeline};
use savsim::scene::Scene;
use savsim::world::TrackSample;

use crate::common::{sample, scene_at, straight};

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
