//! The sensor models against their specifications, with formulas written here: over 10^5
//! draws each error follows its stated distribution (Kolmogorov-Smirnov, p > 0.01), a
//! Gauss-Markov error's autocorrelation at one time constant is 1/e, ADS-B reception rates are
//! Appendix Q's, fields of regard end exactly where stated, and every error is a function of
//! the seed and the instant alone.

use glam::{DQuat, DVec3};
use savsim::sensors::device::Model;
use savsim::sensors::draws::Draws;
use savsim::sensors::errors::{GaussMarkov, MarkovState};
use savsim::sensors::range::{BeamReading, BeamTruth, RangeState};
use savsim::sensors::spec::DeviceSpec;
use savsim::sensors::surveillance::{Look, Own, Target, TargetState};
use statrs::distribution::{ContinuousCDF, Normal};

use crate::common::ks;

const N: usize = 100_000;

/// How a device with `key` looks at instant `k` (instants `dt_s` apart) from `own`.
fn look<'a>(draws: &'a Draws, key: u64, (k, dt_s): (u64, f64), own: &'a Own) -> Look<'a> {
    Look {
        draws,
        key,
        k,
        dt_s,
        own,
    }
}

fn device(spec: &str) -> savsim::sensors::device::Device {
    toml::from_str::<DeviceSpec>(spec).unwrap().build().unwrap()
}

/// The depths a D435 pixel reads of a flat wall `z` ahead, its ray `off_deg` from the optical
/// axis, in units of the stereo law's sigma at `z` (z^2 subpixel / (focal baseline), written
/// here): standard normal when the law is applied to the depth.
fn d435_depth_errors(z: f64, off_deg: f64) -> Vec<f64> {
    let d = device("preset = \"realsense-d435\"\nquantum_m = 0.0\ninvalid_ray = 0.0");
    let Model::Range(m) = d.model else { panic!() };
    let draws = Draws::new(42);
    let mut state = RangeState::default();
    let sigma = z * z * 0.08 / (424.0 * 0.05);
    let cos = off_deg.to_radians().cos();
    let truth = [BeamTruth {
        distance_m: Some(z / cos),
        axial_cos: cos,
    }];
    let mut out = [BeamReading::NoData];
    (0..N as u64)
        .map(|k| {
            assert!(m.read(&mut state, &draws, 7, (k, 1.0 / 30.0), &truth, &mut out));
            match out[0] {
                BeamReading::Range(r) => (r * cos - z) / sigma,
                other => panic!("{other:?}"),
            }
        })
        .collect()
}

#[test]
fn a_stereo_cameras_depth_error_is_normal_with_the_z_squared_sigma() {
    let unit = Normal::new(0.0, 1.0).unwrap();
    let (stat, p) = ks(d435_depth_errors(4.0, 0.0), |x| unit.cdf(x));
    assert!(p > 0.01, "KS D = {stat}, p = {p}");
}

/// The stereo law is on the depth along the optical axis (Intel's D400 formula, z): a pixel 40
/// degrees off the axis, of a wall 5 m ahead (6.53 m along its ray), reads depths with the
/// sigma z = 5 m gives (0.094 m; 0.123 m along the ray), not with the one of its slant range
/// (0.161 m along the ray, as it did before).
#[test]
fn a_stereo_cameras_error_off_its_axis_is_the_depths_not_the_slant_ranges() {
    let errors = d435_depth_errors(5.0, 40.0);
    let n = errors.len() as f64;
    let sd = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    assert!((sd - 1.0).abs() < 0.01, "depth sigma {sd} of the law's");
    let unit = Normal::new(0.0, 1.0).unwrap();
    let (stat, p) = ks(errors, |x| unit.cdf(x));
    assert!(p > 0.01, "KS D = {stat}, p = {p}");
}

#[test]
fn adsb_vertical_rate_errors_are_laplace_and_positions_gauss_markov() {
    let d =
        device("preset = \"adsb-1090es\"\nannex10_altimetry = false\naltitude_quantum_ft = 0.0");
    let Model::Adsb(m) = d.model else { panic!() };
    let b = 2.0203 * 0.3048;
    let own = Own {
        position_enu_m: DVec3::ZERO,
        velocity_enu_mps: DVec3::ZERO,
        enu_from_frd: DQuat::IDENTITY,
    };
    // A target 1 km away: every report is received with chance 0.632 a second at 1 Hz; keep
    // those that are, one target per run (its own seed) so the Gauss-Markov errors are
    // independent draws of the stationary distribution.
    let (mut vertical, mut north) = (Vec::new(), Vec::new());
    let mut seed = 0u64;
    while vertical.len() < N {
        seed += 1;
        let draws = Draws::new(seed);
        let target = Target {
            key: 1,
            position_enu_m: DVec3::new(1000.0, 0.0, 100.0),
            velocity_enu_mps: DVec3::new(-10.0, 0.0, 0.0),
            altitude_m: 100.0,
        };
        let mut state = TargetState::default();
        if let Some(r) = m.report(&mut state, &look(&draws, 3, (0, 0.5), &own), &target) {
            vertical.push(r.velocity_enu_mps.z);
            north.push(r.position_enu_m.y / m.position.sigma);
        }
    }
    // Laplace of scale b, written here.
    let laplace = |x: f64| {
        if x < 0.0 {
            0.5 * (x / b).exp()
        } else {
            1.0 - 0.5 * (-x / b).exp()
        }
    };
    let (stat, p) = ks(vertical, laplace);
    assert!(p > 0.01, "vertical rate: KS D = {stat}, p = {p}");
    let unit = Normal::new(0.0, 1.0).unwrap();
    let (stat, p) = ks(north, |x| unit.cdf(x));
    assert!(p > 0.01, "north: KS D = {stat}, p = {p}");
    // NACp 8 -> 92.6 m / 2.448; NACv 2 -> 3 m/s / 2.448.
    assert!((m.position.sigma - 37.83).abs() < 0.01);
    assert!((m.velocity.sigma - 1.2255).abs() < 0.001);
}

#[test]
fn a_gauss_markov_errors_autocorrelation_at_one_time_constant_is_one_over_e() {
    let gm = GaussMarkov {
        sigma: 3.0,
        tau_s: 1.0,
    };
    let dt = 0.1;
    let lag = 10;
    let draws = Draws::new(9);
    let mut state = MarkovState::default();
    let e: Vec<f64> = (0..1_000_000u64)
        .map(|k| gm.at(&mut state, &draws, 5, k, dt))
        .collect();
    let n = e.len() as f64;
    let mean = e.iter().sum::<f64>() / n;
    let var = e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let cov = e
        .windows(lag + 1)
        .map(|w| (w[0] - mean) * (w[lag] - mean))
        .sum::<f64>()
        / (n - lag as f64);
    let rho = cov / var;
    assert!(
        (rho - (-1f64).exp()).abs() < 0.02,
        "autocorrelation at tau: {rho}"
    );
    assert!(
        (var.sqrt() - 3.0).abs() < 0.05,
        "stationary sigma {}",
        var.sqrt()
    );
}

#[test]
fn adsb_reception_is_appendix_qs_by_range() {
    let d = device("preset = \"adsb-uat\"");
    let Model::Adsb(m) = d.model else { panic!() };
    let own = Own {
        position_enu_m: DVec3::ZERO,
        velocity_enu_mps: DVec3::ZERO,
        enu_from_frd: DQuat::IDENTITY,
    };
    let nm = 1852.0;
    // 1 - 0.05^(1/3) and 1 - 0.05^(1/7), written here; nothing beyond 20 NM.
    for (range_nm, want) in [
        (5.0, 1.0 - 0.05f64.powf(1.0 / 3.0)),
        (15.0, 1.0 - 0.05f64.powf(1.0 / 7.0)),
        (25.0, 0.0),
    ] {
        let draws = Draws::new(11);
        let mut state = TargetState::default();
        let target = Target {
            key: 2,
            position_enu_m: DVec3::new(range_nm * nm, 0.0, 0.0),
            velocity_enu_mps: DVec3::ZERO,
            altitude_m: 0.0,
        };
        let got: Vec<bool> = (0..N as u64)
            .map(|k| {
                m.report(&mut state, &look(&draws, 1, (k, 1.0), &own), &target)
                    .is_some()
            })
            .collect();
        let rate = got.iter().filter(|g| **g).count() as f64 / N as f64;
        assert!(
            (rate - want).abs() <= 0.01 * want.max(0.01),
            "{range_nm} NM: {rate} received, want {want}"
        );
        if want > 0.0 {
            // At least one in every window (3 s, 7 s): 95% of windows.
            let window = if range_nm < 10.0 { 3 } else { 7 };
            let hit = got.windows(window).filter(|w| w.iter().any(|g| *g)).count() as f64
                / (N - window + 1) as f64;
            assert!((hit - 0.95).abs() < 0.01, "{range_nm} NM: {hit} of windows");
        }
    }
}

#[test]
fn fields_of_regard_end_exactly_where_stated() {
    let own = Own {
        position_enu_m: DVec3::ZERO,
        velocity_enu_mps: DVec3::ZERO,
        // Nose east (FRD x east, y south, z down).
        enu_from_frd: DQuat::from_rotation_x(std::f64::consts::PI),
    };
    let at = |az_deg: f64, el_deg: f64| {
        let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
        // Right of an east nose is south (-y).
        let body = DVec3::new(el.cos() * az.cos(), -el.cos() * az.sin(), el.sin());
        Target {
            key: 4,
            position_enu_m: body * 2000.0,
            velocity_enu_mps: DVec3::ZERO,
            altitude_m: 0.0,
        }
    };
    let radar = device("preset = \"radar-appq\"");
    let Model::Radar(r) = radar.model else {
        panic!()
    };
    let eoir = device("preset = \"eoir-appq\"\nfield_of_regard_deg = [60.0, 20.0]");
    let Model::EoIr(e) = eoir.model else { panic!() };
    let draws = Draws::new(1);
    for (az, el, seen) in [
        (109.99, 0.0, true),
        (110.01, 0.0, false),
        (-109.99, 0.0, true),
        (-110.01, 0.0, false),
        (0.0, 14.99, true),
        (0.0, 15.01, false),
        (0.0, -15.01, false),
    ] {
        let mut s = TargetState::default();
        let got = r.report(&mut s, &look(&draws, 1, (0, 1.0), &own), &at(az, el));
        assert_eq!(got.is_some(), seen, "radar at {az}, {el}");
    }
    for (az, el, seen) in [
        (59.99, 0.0, true),
        (60.01, 0.0, false),
        (0.0, 19.99, true),
        (0.0, 20.01, false),
    ] {
        let mut s = TargetState::default();
        let got = e.report(&mut s, &look(&draws, 1, (0, 0.1), &own), &at(az, el));
        assert_eq!(got.is_some(), seen, "EO/IR at {az}, {el}");
    }
    // A depth camera's outermost rays are at half its field exactly.
    let d435 = device("preset = \"realsense-d435\"");
    let Model::Range(m) = d435.model else {
        panic!()
    };
    let beams = m.beams();
    let azimuths: Vec<f64> = beams
        .iter()
        .map(|b| b[0].y.atan2(b[0].x).to_degrees())
        .collect();
    let widest = azimuths.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!((widest - 43.5).abs() < 1e-9, "{widest}");
}

#[test]
fn errors_are_a_function_of_the_seed_and_the_instant_alone() {
    let d = device("preset = \"adsb-1090es\"");
    let Model::Adsb(m) = d.model else { panic!() };
    let own = Own {
        position_enu_m: DVec3::ZERO,
        velocity_enu_mps: DVec3::ZERO,
        enu_from_frd: DQuat::IDENTITY,
    };
    let target = |x: f64| Target {
        key: 9,
        position_enu_m: DVec3::new(x, 0.0, 50.0),
        velocity_enu_mps: DVec3::X,
        altitude_m: 50.0,
    };
    // One run asks every instant, another every third: the reports at the shared instants
    // carry the same errors (the truth, here the same, may differ in a closed loop).
    let (a, b) = (Draws::new(77), Draws::new(77));
    let (mut sa, mut sb) = (TargetState::default(), TargetState::default());
    for k in 0..300u64 {
        let ra = m.report(&mut sa, &look(&a, 5, (k, 0.5), &own), &target(900.0));
        if k % 3 == 0 {
            let rb = m.report(&mut sb, &look(&b, 5, (k, 0.5), &own), &target(900.0));
            assert_eq!(ra, rb, "instant {k}");
        }
    }
    // Another seed, other errors.
    let c = Draws::new(78);
    let mut sc = TargetState::default();
    let differs = (0..50u64).any(|k| {
        let d77 = Draws::new(77);
        m.report(
            &mut TargetState::default(),
            &look(&d77, 5, (k, 0.5), &own),
            &target(900.0),
        ) != m.report(&mut sc, &look(&c, 5, (k, 0.5), &own), &target(900.0))
    });
    assert!(differs);
}

#[test]
fn bad_device_definitions_name_the_field() {
    for (spec, field) in [
        ("preset = \"tfmini\"\nsigma_m = -1.0", "sigma_m"),
        (
            "preset = \"realsense-d435\"\nfov_deg = [400.0, 58.0]",
            "fov_deg",
        ),
        ("preset = \"tfmini\"\nrate_hz = 0.0", "rate_hz"),
        ("preset = \"tfmini\"\nrate_hz = 1e300", "rate_hz"),
        ("preset = \"tfmini\"\nproportional = nan", "proportional"),
        ("preset = \"laser\"", "preset"),
        ("preset = \"adsb-1090es\"\nnacp = 0", "nacp"),
        ("preset = \"adsb-1090es\"\nfov_deg = [1.0, 1.0]", "fov_deg"),
        ("kind = \"range\"\nrate_hz = 10.0", "range_m"),
        ("preset = \"tfmini\"\nrange_m = [5.0, 1.0]", "range_m"),
        ("preset = \"tfmini\"\ndropout = 1.5", "dropout"),
    ] {
        let err = toml::from_str::<DeviceSpec>(spec)
            .unwrap()
            .build()
            .unwrap_err();
        assert_eq!(err.field, field, "{spec}: {err}");
    }
    // Unknown fields and values of the wrong type are refused by the reader.
    assert!(toml::from_str::<DeviceSpec>("preset = \"tfmini\"\ncolour = 1").is_err());
    assert!(toml::from_str::<DeviceSpec>("rate_hz = \"fast\"").is_err());
}
