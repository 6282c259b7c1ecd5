//! The dynamics against what a multicopter must do: hover on the command that balances its
//! weight, tilt and yaw the way its rotors push, rest, take off and land on the ground, stop at
//! a wall, converge as the step shrinks, and never leave finite numbers, whatever it is given.

use glam::{DQuat, DVec3};
use proptest::prelude::*;

use super::frame::MAX_ROTORS;
use super::presets::{preset, PRESETS};
use super::step::STEP_RANGE_S;
use super::*;

const AIR: Air = Air {
    wind_ned_mps: DVec3::ZERO,
    home_alt_m: 593.0,
};

/// The output of each rotor that holds `frame` up (its thrust curve solved for its weight at
/// `AIR`'s density, on the ground's altitude).
fn hover_output(frame: &Frame) -> f64 {
    let m = &frame.rotor_model;
    let ratio = m
        .reference_air_density_kgpm3
        .map_or(1.0, |r| air::density_kgpm3(AIR.home_alt_m + 10.0) / r);
    let share = frame.mass_kg * GRAVITY_MPS2 / (frame.rotors.len() as f64 * m.max_thrust_n * ratio);
    // (1 - e) c + e c^2 = share.
    let e = m.thrust_expo;
    let c = if e == 0.0 {
        share
    } else {
        (-(1.0 - e) + ((1.0 - e).powi(2) + 4.0 * e * share).sqrt()) / (2.0 * e)
    };
    (c - m.idle) / (1.0 - m.idle)
}

fn airborne(frame: &Frame) -> Body {
    let mut body = Body::landed(frame, 0.0, 0.3);
    body.position_ned_m.z = -10.0;
    body.on_ground = false;
    let c = hover_output(frame) * (1.0 - frame.rotor_model.idle) + frame.rotor_model.idle;
    body.commands = [c; MAX_ROTORS];
    body
}

fn fly(frame: &Frame, body: &mut Body, outputs: &[f64], seconds: f64, dt_s: f64) -> Imu {
    let mut imu = None;
    for _ in 0..(seconds / dt_s).round() as usize {
        imu = Some(step(frame, body, outputs, true, &AIR, &FlatGround, dt_s).unwrap());
    }
    imu.unwrap()
}

#[test]
fn each_preset_hovers_level_on_the_output_that_balances_its_weight() {
    for name in PRESETS {
        let frame = preset(name).unwrap();
        let mut body = airborne(&frame);
        let imu = fly(&frame, &mut body, &[hover_output(&frame); 4], 10.0, 0.0025);
        assert!(
            (body.position_ned_m.z + 10.0).abs() < 0.01,
            "{name}: {body:?}"
        );
        assert!(body.velocity_ned_mps.length() < 1e-3, "{name}: {body:?}");
        assert!(body.rates_frd_radps.length() < 1e-9, "{name}: {body:?}");
        assert!((body.euler_rad()[2] - 0.3).abs() < 1e-9, "{name}: yaw kept");
        // The IMU reads the thrust holding it up: -g along body z.
        assert!((imu.accel_frd_mps2 - DVec3::new(0.0, 0.0, -GRAVITY_MPS2)).length() < 0.01);
    }
}

/// More thrust on the right rotor rolls the body left; on the front one pitches it nose up;
/// on the counter-clockwise ones yaws it nose right (ArduPilot's motor table and yaw factors).
#[test]
fn rotors_turn_the_body_the_way_their_positions_and_spins_say() {
    let frame = preset("arducopter-quad").unwrap();
    let hover = hover_output(&frame);
    let rates_after = |outputs: [f64; 4]| {
        let mut body = airborne(&frame);
        fly(&frame, &mut body, &outputs, 0.1, 0.0025);
        body.rates_frd_radps
    };
    // Motor 1 at +90 degrees (right), 2 at -90 (left), 3 front, 4 rear; 1 and 2 CCW.
    let right = rates_after([hover + 0.05, hover, hover, hover]);
    assert!(
        right.x < -0.1 && right.y.abs() < 0.05 * right.x.abs(),
        "{right}"
    );
    let front = rates_after([hover, hover, hover + 0.05, hover]);
    assert!(front.y > 0.1 && front.x.abs() < 0.05 * front.y, "{front}");
    let ccw = rates_after([hover + 0.05, hover + 0.05, hover - 0.05, hover - 0.05]);
    assert!(
        ccw.z > 0.01 && ccw.x.abs() < 1e-9 && ccw.y.abs() < 1e-9,
        "{ccw}"
    );
    // The Iris: rotor 0 front-right (CCW), 2 front-left (CW).
    let iris = preset("iris").unwrap();
    let h = hover_output(&iris);
    let mut body = airborne(&iris);
    fly(&iris, &mut body, &[h + 0.05, h, h + 0.05, h], 0.1, 0.0025);
    assert!(body.rates_frd_radps.y > 0.1, "{:?}", body.rates_frd_radps);
}

#[test]
fn it_rests_on_the_ground_takes_off_and_lands_again() {
    let frame = preset("arducopter-quad").unwrap();
    let mut body = Body::landed(&frame, 0.0, 0.0);
    // Armed at idle: it stays, and its IMU reads gravity's reaction.
    let imu = fly(&frame, &mut body, &[0.0; 4], 2.0, 0.0025);
    assert!(body.on_ground && body.position_ned_m.z == -frame.rest_height_m);
    assert!((imu.accel_frd_mps2.z + GRAVITY_MPS2).abs() < 1e-9);
    fly(&frame, &mut body, &[0.8; 4], 2.0, 0.0025);
    assert!(!body.on_ground && body.position_ned_m.z < -5.0, "{body:?}");
    // Rotors off: it falls, lands, and rests level where it landed.
    fly(&frame, &mut body, &[0.0; 4], 10.0, 0.0025);
    assert!(body.on_ground, "{body:?}");
    assert_eq!(body.velocity_ned_mps, DVec3::ZERO);
    assert_eq!(body.position_ned_m.z, -frame.rest_height_m);
}

/// A wall 5 m north: flying at it, the body stops at its surface and slides along it.
#[test]
fn a_wall_stops_the_body_at_its_surface() {
    struct Wall;
    impl Surroundings for Wall {
        fn ground_down_m(&self, _: f64, _: f64) -> f64 {
            0.0
        }
        fn first_contact(&self, from: DVec3, to: DVec3, radius_m: f64) -> Option<(f64, DVec3)> {
            let face = 5.0 - radius_m;
            (to.x > face).then(|| {
                let f = if from.x >= face {
                    0.0
                } else {
                    (face - from.x) / (to.x - from.x)
                };
                (f, DVec3::NEG_X)
            })
        }
    }
    let frame = preset("arducopter-quad").unwrap();
    let mut body = airborne(&frame);
    body.velocity_ned_mps = DVec3::new(15.0, 3.0, 0.0);
    let hover = hover_output(&frame);
    let mut stopped = false;
    for _ in 0..800 {
        step(&frame, &mut body, &[hover; 4], true, &AIR, &Wall, 0.0025).unwrap();
        assert!(
            body.position_ned_m.x <= 5.0 - frame.radius_m + 1e-9,
            "{body:?}"
        );
        stopped |= body.against_obstacle;
    }
    assert!(stopped);
    assert!(body.velocity_ned_mps.x.abs() < 1e-9, "{body:?}");
    assert!(body.position_ned_m.y > 0.5, "it slid along: {body:?}");
}

/// A full-throttle climb and a tilted dash flown at every step from 1 to 10 ms end within a
/// few centimetres of the same flight at 0.5 ms.
#[test]
fn steps_from_1_to_10_ms_converge_on_the_same_flight() {
    for name in PRESETS {
        let frame = preset(name).unwrap();
        let flight = |dt: f64| {
            let mut body = airborne(&frame);
            body.ned_from_frd = DQuat::from_rotation_y(-0.3) * body.ned_from_frd;
            fly(&frame, &mut body, &[0.9; 4], 2.0, dt);
            body.position_ned_m
        };
        let fine = flight(0.0005);
        for dt in [0.001, 0.0025, 0.004, 0.005, 0.01] {
            let d = flight(dt).distance(fine);
            assert!(d < 0.05 + 5.0 * dt, "{name} at {dt} s: {d} m off");
        }
    }
}

#[test]
fn bad_frames_and_steps_are_errors_that_say_why() {
    let mut frame = preset("iris").unwrap();
    frame.mass_kg = 0.0;
    assert!(frame
        .check()
        .unwrap_err()
        .to_string()
        .contains("mass_kg = 0"));
    frame.mass_kg = -1.0;
    assert!(frame.check().is_err());
    let mut nan = preset("iris").unwrap();
    nan.rotor_model.max_thrust_n = f64::NAN;
    assert!(nan
        .check()
        .unwrap_err()
        .to_string()
        .contains("max_thrust_n"));
    let mut twice = preset("iris").unwrap();
    twice.rotors[1].output = 0;
    assert!(twice
        .check()
        .unwrap_err()
        .to_string()
        .contains("used twice"));
    assert!(Frame::from_toml("name = 'x'\nmass_kg = 1").is_err());
    let frame = preset("iris").unwrap();
    let mut body = Body::landed(&frame, 0.0, 0.0);
    for dt in [0.0, 1.0, f64::NAN, -0.001] {
        let e = step(&frame, &mut body, &[0.5; 4], true, &AIR, &FlatGround, dt);
        assert!(matches!(e, Err(StepError::Step(_))), "{dt}: {e:?}");
    }
    let e = step(
        &frame,
        &mut body,
        &[0.5, f64::NAN],
        true,
        &AIR,
        &FlatGround,
        0.004,
    );
    assert_eq!(e, Err(StepError::Output(1)));
    assert_eq!(
        body,
        Body::landed(&frame, 0.0, 0.0),
        "an error leaves the body as it was"
    );
}

#[test]
fn presets_written_as_toml_read_back_the_same() {
    for name in PRESETS {
        let frame = preset(name).unwrap();
        let text = toml::to_string(&frame).unwrap();
        assert_eq!(Frame::from_toml(&text).unwrap(), frame, "{text}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Any outputs (0..1), any step in range, any wind to 30 m/s, any start from hover to
    /// 30 m/s at any attitude: every state stays finite and every speed bounded.
    #[test]
    fn any_flight_stays_finite(
        preset_index in 0usize..PRESETS.len(),
        outputs in prop::collection::vec(prop::collection::vec(0.0f64..=1.0, 4), 1..40),
        dt_s in STEP_RANGE_S.0..=STEP_RANGE_S.1,
        wind in prop::array::uniform3(-30.0f64..30.0),
        velocity in prop::array::uniform3(-30.0f64..30.0),
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in 0.0f64..std::f64::consts::TAU,
        rates in prop::array::uniform3(-20.0f64..20.0),
    ) {
        let frame = preset(PRESETS[preset_index]).unwrap();
        let mut body = Body::landed(&frame, 0.0, 0.0);
        body.position_ned_m.z = -50.0;
        body.on_ground = false;
        body.velocity_ned_mps = DVec3::from_array(velocity);
        body.ned_from_frd = DQuat::from_axis_angle(
            DVec3::from_array(axis).try_normalize().unwrap_or(DVec3::Z),
            angle,
        );
        body.rates_frd_radps = DVec3::from_array(rates);
        let air = Air { wind_ned_mps: DVec3::from_array(wind), home_alt_m: 593.0 };
        for out in &outputs {
            for _ in 0..(0.05 / dt_s).ceil() as usize {
                step(&frame, &mut body, out, true, &air, &FlatGround, dt_s).unwrap();
                prop_assert!(body.is_finite());
                prop_assert!(body.velocity_ned_mps.length() < 300.0, "{:?}", body);
                prop_assert!((body.ned_from_frd.length() - 1.0).abs() < 1e-9);
            }
        }
    }
}
