//! Terrain from elevation files: SRTM tiles and ArduPilot .DAT grids, real flights over them.

use std::path::{Path, PathBuf};

use savsim::scene::terrain::Elevation;

use crate::common::{have_pymavlink, python, root, shared_fixtures};

fn scene_file(dir: &Path, origin: [f64; 3], terrain: &str) -> PathBuf {
    let path = dir.join("scene.toml");
    std::fs::write(
        &path,
        format!(
            "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n\n[[vehicle]]\nmodel = \"fixed_wing\"\n\n{terrain}",
            origin[0], origin[1], origin[2]
        ),
    )
    .unwrap();
    path
}

fn replay(scene: &Path, flight: &Path) -> serde_json::Value {
    let scene = savsim::scene::load(scene).unwrap();
    crate::common::replay_into_session(flight, Some(scene)).summary("replay", "test")
}

fn cmac_terrain(fixtures: &Path) -> String {
    format!(
        "[[terrain]]\nid = \"cmac\"\nfile = \"{}\"\n",
        fixtures
            .join("terrain/ardupilot_terrain_S36E149.DAT")
            .display()
    )
}

#[test]
fn the_vtol_flight_clears_the_cmac_terrain_by_what_the_raw_grid_says() {
    let Some(fixtures) = shared_fixtures() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(
        dir.path(),
        [-35.363261, 149.165230, 584.0],
        &cmac_terrain(&fixtures),
    );
    let flight = fixtures.join("tlogs/UAVLogViewer__vtol.tlog");
    let s = replay(&scene, &flight);
    assert_eq!(s["collision"]["collisions"], 0, "{}", s["collision"]);
    let ours = s["collision"]["terrain_clearance_min_m"].as_f64().unwrap();
    if !have_pymavlink() {
        return;
    }
    let out = python(
        &root().join("tests/fixtures/terrain_clearance.py"),
        &[
            flight.to_str().unwrap(),
            fixtures
                .join("terrain/ardupilot_terrain_S36E149.DAT")
                .to_str()
                .unwrap(),
        ],
    );
    let theirs: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let theirs = theirs["min_clearance_m"].as_f64().unwrap();
    assert!((2.0..2.8).contains(&theirs), "the raw grid says {theirs} m");
    assert!(
        (ours - theirs).abs() < 0.05,
        "savsim {ours} m, raw grid {theirs} m"
    );
}

#[test]
fn samples_near_0_m_before_the_altitude_reference_are_not_collisions() {
    let Some(fixtures) = shared_fixtures() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(
        dir.path(),
        [-35.363261, 149.165230, 584.0],
        &cmac_terrain(&fixtures),
    );
    let s = replay(
        &scene,
        &fixtures.join("tlogs/dronekit-python__flight_replay_flight.tlog"),
    );
    let c = &s["collision"];
    assert_eq!(c["collisions"], 0, "{c}");
    // The early samples report ~1 m AMSL over ground at ~585 m: skipped as implausible.
    assert!(c["implausible_samples"].as_u64().unwrap() > 100, "{c}");
    assert!(c["terrain_clearance_min_m"].as_f64().unwrap() > 0.0, "{c}");
}

#[test]
fn mount_washington_from_srtm() {
    let Some(fixtures) = shared_fixtures() else {
        return;
    };
    let tile = fixtures.join("terrain/srtm3_N44W072.hgt");
    let dir = tempfile::tempdir().unwrap();
    let e = Elevation::read(&tile, &savsim::scene::Disk).unwrap();
    let summit = e.height_amsl_m(44.2706, -71.3033).unwrap();
    assert!((1850.0..1920.0).contains(&summit), "summit {summit} m");
    let scene = scene_file(
        dir.path(),
        [44.2706, -71.3033, 1900.0],
        &format!("[[terrain]]\nid = \"washington\"\nfile = \"{}\"\narea = {{ size_m = [6000.0, 6000.0] }}\ncell_m = 90.0\n", tile.display()),
    );
    let scene = savsim::scene::load(&scene).unwrap();
    assert!(scene.obstacles.len() >= 4, "split into patches");
    let b = scene.bounds_enu_m();
    // Relief around the summit: from the valleys to the top (heights relative to 1900 m).
    assert!(b.max.z > -60.0 && b.max.z < 20.0, "{b:?}");
    assert!(b.min.z < -800.0, "{b:?}");
}

#[test]
fn srtm_voids_are_filled_and_areas_beyond_the_file_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes: Vec<u8> = (0..1201 * 1201)
        .flat_map(|_| 250i16.to_be_bytes())
        .collect();
    for i in [700_000usize, 700_001, 701_201] {
        bytes[2 * i..2 * i + 2].copy_from_slice(&(-32768i16).to_be_bytes());
    }
    std::fs::write(dir.path().join("N10E020.hgt"), &bytes).unwrap();
    let terrain = "[[terrain]]\nid = \"t\"\nfile = \"N10E020.hgt\"\narea = { size_m = [3000.0, 3000.0] }\ncell_m = 100.0\n";
    let scene = scene_file(dir.path(), [10.5, 20.5, 250.0], terrain);
    let s = savsim::scene::load(&scene).unwrap();
    let b = s.bounds_enu_m();
    // Flat 250 m everywhere (voids filled, never -32768 m), minus the curvature drop at 2 km.
    assert!(b.min.z > -1.0 && b.max.z < 0.01, "{b:?}");
    let outside = scene_file(dir.path(), [10.999, 20.5, 250.0], terrain);
    let e = savsim::scene::load(&outside).unwrap_err().to_string();
    assert!(
        e.contains("N10E020.hgt") && e.contains("no elevation data"),
        "{e}"
    );
    std::fs::write(dir.path().join("N10E020.hgt"), b"short").unwrap();
    let e = savsim::scene::load(&scene).unwrap_err().to_string();
    assert!(e.contains("neither"), "{e}");
}

/// Write a small geographic GeoTIFF (i16, 0.001 degree pixels, pixel-is-area) with a no-data
/// hole, the way GDAL does.
fn write_geotiff(path: &Path, nodata_at: usize) {
    use tiff::encoder::{colortype::GrayI16, TiffEncoder};
    use tiff::tags::Tag;
    let (w, h) = (200u32, 150u32);
    let mut data: Vec<i16> = (0..w * h).map(|i| 300 + (i % w) as i16).collect(); // rises eastwards
    data[nodata_at] = -9999;
    let file = std::fs::File::create(path).unwrap();
    let mut tiff = TiffEncoder::new(file).unwrap();
    let mut image = tiff.new_image::<GrayI16>(w, h).unwrap();
    let e = image.encoder();
    e.write_tag(Tag::ModelPixelScaleTag, &[0.001f64, 0.001, 0.0][..])
        .unwrap();
    e.write_tag(
        Tag::ModelTiepointTag,
        &[0.0f64, 0.0, 0.0, 20.0, 10.15, 0.0][..],
    )
    .unwrap();
    // GeoKeyDirectory: version 1.1.0, 2 keys: model type geographic, raster type area.
    e.write_tag(
        Tag::GeoKeyDirectoryTag,
        &[1u16, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, 1][..],
    )
    .unwrap();
    e.write_tag(Tag::GdalNodata, "-9999").unwrap();
    image.write_data(&data).unwrap();
}

#[test]
fn geotiff_dems_are_georeferenced_and_their_holes_filled() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dem.tif");
    write_geotiff(&path, 75 * 200 + 100);
    let e = Elevation::read(&path, &savsim::scene::Disk).unwrap();
    assert_eq!(e.voids_filled(), 1);
    // Pixel (100, 75)'s centre: lon 20 + 100.5 * 0.001, lat 10.15 - 75.5 * 0.001; the hole is
    // filled from its neighbours (399 and 401 to the west and east, 400 above and below).
    let h = e.height_amsl_m(10.15 - 0.0755, 20.0 + 0.1005).unwrap();
    assert!((h - 400.0).abs() < 1e-6, "{h}");
    // Between two columns: the mean.
    let h = e.height_amsl_m(10.15 - 0.0105, 20.0 + 0.0110).unwrap();
    assert!((h - 310.5).abs() < 1e-6, "{h}");
    assert!(e.height_amsl_m(10.0, 20.1).is_none(), "south of the raster");
    // As a scene's terrain.
    let scene = scene_file(
        dir.path(),
        [10.075, 20.1, 0.0],
        "[[terrain]]\nid = \"dem\"\nfile = \"dem.tif\"\narea = { size_m = [10000.0, 8000.0] }\ncell_m = 100.0\n",
    );
    let s = savsim::scene::load(&scene).unwrap();
    let b = s.bounds_enu_m();
    assert!(b.min.z > 290.0 && b.max.z < 510.0, "{b:?}");
}
