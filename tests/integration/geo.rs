//! Geodesy against PROJ (tests/fixtures/geo_reference.py): 1 mm at 100 and 1000 km, near the
//! poles, across the antimeridian, from -400 m to 20 km.

use glam::DVec3;
use savsim::geo::{Geodetic, LocalTangentPlane};

use crate::common::root;

#[derive(serde::Deserialize)]
struct Case {
    name: String,
    origin: [f64; 3],
    point: [f64; 3],
    origin_ecef_m: [f64; 3],
    point_ecef_m: [f64; 3],
    enu_m: [f64; 3],
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(root().join("tests/fixtures/geo_reference.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn ecef_matches_proj_to_a_millimetre() {
    for c in cases() {
        for (g, want) in [(c.origin, c.origin_ecef_m), (c.point, c.point_ecef_m)] {
            let got = Geodetic::new(g[0], g[1], g[2]).to_ecef_m();
            let err = (got - DVec3::from(want)).length();
            assert!(err < 1e-3, "{}: ECEF off by {err} m", c.name);
        }
    }
}

#[test]
fn enu_matches_proj_to_a_millimetre() {
    for c in cases() {
        let plane = LocalTangentPlane::new(Geodetic::new(c.origin[0], c.origin[1], c.origin[2]));
        let got = plane.enu_m_from_geodetic(&Geodetic::new(c.point[0], c.point[1], c.point[2]));
        let err = (got - DVec3::from(c.enu_m)).length();
        assert!(err < 1e-3, "{}: ENU off by {err} m (got {got:?})", c.name);
        // And back.
        let back = plane.geodetic_from_enu_m(got);
        let again = Geodetic::new(c.point[0], c.point[1], c.point[2]).to_ecef_m();
        assert!(
            (back.to_ecef_m() - again).length() < 1e-3,
            "{}: round trip",
            c.name
        );
    }
}

#[test]
fn the_reference_covers_the_extremes() {
    let c = cases();
    let far = c
        .iter()
        .map(|c| DVec3::from(c.enu_m).length())
        .fold(0.0, f64::max);
    assert!(far > 1.0e6, "a case beyond 1000 km");
    assert!(c.iter().any(|c| c.origin[0].abs() >= 89.9));
    assert!(c
        .iter()
        .any(|c| c.origin[1].signum() != c.point[1].signum() && c.origin[1].abs() > 179.0));
    assert!(c
        .iter()
        .any(|c| c.origin[2] <= -400.0 && c.point[2] >= 20_000.0));
}
