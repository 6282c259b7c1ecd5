//! CityJSON city models: a tiny committed one, and the Zurich and Delft files of
//! ../shared/fixtures.

use std::path::Path;

use crate::common::{root, shared_fixtures};

fn city_scene(dir: &Path, file: &Path, anchor: [f64; 3]) -> savsim::scene::Scene {
    let path = dir.join("city.toml");
    std::fs::write(
        &path,
        format!(
            "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n\n[[city]]\nid = \"c\"\nfile = \"{}\"\nanchor_geo = {anchor:?}\n",
            anchor[0],
            anchor[1],
            anchor[2],
            file.display()
        ),
    )
    .unwrap();
    savsim::scene::load(&path).unwrap()
}

#[test]
fn a_tiny_city_loads_with_transform_holes_and_types() {
    let dir = tempfile::tempdir().unwrap();
    let scene = city_scene(
        dir.path(),
        &root().join("tests/fixtures/tiny_city.json"),
        [47.0, 8.0, 0.0],
    );
    let ids: Vec<&str> = scene.obstacles.iter().map(|o| o.id.as_str()).collect();
    assert_eq!(
        ids,
        ["c/courtyard-wall", "c/tower"],
        "vegetation is not loaded"
    );
    let tower = &scene.obstacles[1];
    // A 10 m x 10 m x 30 m box standing on z = 10 m (the transform), 6 quads -> 12 triangles.
    assert_eq!(tower.geometry.triangle_count(), 12);
    let b = tower.aabb_enu_m;
    assert!(
        ((b.max - b.min) - glam::DVec3::new(10.0, 10.0, 30.0)).length() < 1e-3,
        "{b:?}"
    );
    assert!((b.min.z - 10.0).abs() < 1e-3);
    // A wall with a window: the hole is not filled (8 triangles around it, none across it).
    let wall = &scene.obstacles[0];
    assert_eq!(wall.geometry.triangle_count(), 8);
}

#[test]
fn zurich_and_delft_city_models() {
    let Some(fixtures) = shared_fixtures() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let zurich = city_scene(
        dir.path(),
        &fixtures.join("city/cjio__zurich_subset_lod2.json"),
        [47.3905, 8.5394, 0.0],
    );
    assert_eq!(zurich.obstacles.len(), 161, "161 LoD2 building parts");
    let b = zurich.bounds_enu_m();
    // LV95/LN02 heights are AMSL: Zurich's buildings stand at about 400-620 m.
    assert!(b.min.z > 390.0 && b.max.z < 625.0, "{b:?}");
    let delft = city_scene(
        dir.path(),
        &fixtures.join("city/cjio__delft.json"),
        [52.0116, 4.3571, 0.0],
    );
    assert_eq!(
        delft.obstacles.len(),
        163,
        "160 LoD1 buildings and 3 bridges"
    );
    assert!(delft
        .obstacles
        .iter()
        .all(|o| o.geometry.triangle_count() >= 4));
}
