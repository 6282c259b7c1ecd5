//! OpenStreetMap buildings in scenes (`[[osm]]`): every OSM file of ../shared/fixtures/realdata
//! gives the building count pyosmium's libosmium assembles from it, and its heights by the
//! documented policy from the tags pyosmium counted; a building with a hole is hollow (a ray
//! parity test written here); bad files are errors.

use std::path::Path;

use crate::flight_logs::realdata;

/// A scene with `[[osm]]` over `file`, its origin at `lat`, `lon`.
fn scene_over(dir: &Path, file: &Path, lat: f64, lon: f64, extra: &str) -> String {
    let text = format!(
        "[origin]\nlat_deg = {lat}\nlon_deg = {lon}\nalt_m = 100\n\n[[osm]]\nid = \"osm\"\nfile = {:?}\n{extra}",
        file.display()
    );
    let path = dir.join("osm.toml");
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

#[test]
fn every_osm_fixture_gives_the_buildings_libosmium_assembles() {
    let files = realdata("osm");
    if files.is_empty() {
        eprintln!("skipped: ../shared/fixtures/realdata is absent");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (path, reference) in files {
        let b = &reference["bbox_nodes"];
        let (lat, lon) = (
            (b[1].as_f64().unwrap() + b[3].as_f64().unwrap()) / 2.0,
            (b[0].as_f64().unwrap() + b[2].as_f64().unwrap()) / 2.0,
        );
        let scene = savsim::scene::load(Path::new(&scene_over(dir.path(), &path, lat, lon, "")))
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let areas = &reference["assembled_building_areas"];
        let expected =
            areas["from_way"].as_u64().unwrap_or(0) + areas["from_relation"].as_u64().unwrap_or(0);
        let stats = &scene.osm[0];
        eprintln!("{}: {stats:?}; pyosmium {areas}", path.display());
        assert_eq!(stats.buildings as u64, expected, "{}", path.display());
        assert_eq!(scene.obstacles.len() as u64, expected);
        assert_eq!(
            stats.holes as u64,
            areas["inner_rings"].as_u64().unwrap_or(0)
        );
        // Heights: pyosmium's count of the buildings tagging `height` and `building:levels`
        // (none of these files tags both, nor a roof, nor a min_height).
        let tagged = |key: &str| {
            ["building_ways", "building_relations"]
                .iter()
                .map(|k| reference[k][key].as_u64().unwrap())
                .sum::<u64>()
        };
        assert_eq!(stats.height_from_tag as u64, tagged("height"));
        assert_eq!(stats.height_from_levels as u64, tagged("building:levels"));
        assert_eq!(
            stats.height_defaulted as u64,
            expected - tagged("height") - tagged("building:levels")
        );
        for o in &scene.obstacles {
            assert_eq!(o.kind.name(), "building");
            let height = o.aabb_enu_m.max.z - o.aabb_enu_m.min.z;
            // The default 10 m, or 3 m a level (OSM2World's two-level building: 6 m).
            assert!(
                (height - 10.0).abs() < 1e-3 || (height - 6.0).abs() < 1e-3,
                "{}: {height}",
                o.id
            );
        }
        let info = savsim::scene::info::describe(&scene);
        assert!(info.contains(&format!("{expected} buildings")), "{info}");
    }
}

#[test]
fn a_building_with_a_hole_is_hollow_and_heights_follow_the_tags() {
    let dir = tempfile::tempdir().unwrap();
    // A 100 m square courtyard block around the origin with a 40 m square hole, 4 levels and a
    // 2 m roof; and a tower with height 31.5 m on min_height 6.
    let d = 0.000_9; // about 100 m of latitude
    let osm = format!(
        r#"<osm version="0.6">
  <node id="1" lat="{a}" lon="{a}"/><node id="2" lat="{a}" lon="{b}"/><node id="3" lat="{b}" lon="{b}"/><node id="4" lat="{b}" lon="{a}"/>
  <node id="5" lat="{c}" lon="{c}"/><node id="6" lat="{c}" lon="{e}"/><node id="7" lat="{e}" lon="{e}"/><node id="8" lat="{e}" lon="{c}"/>
  <node id="9" lat="0.002" lon="0.002"/><node id="10" lat="0.002" lon="0.0021"/><node id="11" lat="0.0021" lon="0.0021"/>
  <way id="20"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/></way>
  <way id="21"><nd ref="5"/><nd ref="6"/><nd ref="7"/><nd ref="8"/><nd ref="5"/></way>
  <way id="22"><nd ref="9"/><nd ref="10"/><nd ref="11"/><nd ref="9"/><tag k="building" v="yes"/><tag k="height" v="31.5 m"/><tag k="min_height" v="6"/></way>
  <relation id="30"><member type="way" ref="20" role="outer"/><member type="way" ref="21" role="inner"/>
    <tag k="type" v="multipolygon"/><tag k="building" v="apartments"/><tag k="building:levels" v="4"/><tag k="roof:height" v="2"/></relation>
</osm>"#,
        a = -d / 2.0,
        b = d / 2.0,
        c = -d / 5.0,
        e = d / 5.0,
    );
    let file = dir.path().join("block.osm");
    std::fs::write(&file, osm).unwrap();
    let scene = savsim::scene::load(Path::new(&scene_over(
        dir.path(),
        &file,
        0.0,
        0.0,
        "level_m = 3.5",
    )))
    .unwrap();
    let stats = &scene.osm[0];
    assert_eq!(
        (
            stats.buildings,
            stats.height_from_tag,
            stats.height_from_levels
        ),
        (2, 1, 1)
    );
    let block = scene
        .obstacles
        .iter()
        .find(|o| o.id == "osm/relation/30")
        .unwrap();
    assert!((block.aabb_enu_m.max.z - (4.0 * 3.5 + 2.0)).abs() < 1e-3);
    let tower = scene
        .obstacles
        .iter()
        .find(|o| o.id == "osm/way/22")
        .unwrap();
    assert!(
        (tower.aabb_enu_m.min.z - 6.0).abs() < 1e-3 && (tower.aabb_enu_m.max.z - 31.5).abs() < 1e-3
    );
    // The courtyard is empty: a point at its centre, 5 m up, is inside no solid; 30 m east of
    // the centre it is inside the block. Parity of a ray's crossings of the block's triangles
    // (Moller-Trumbore, written here), the ray along +north slightly skewed off the edges.
    let savsim::scene::geometry::GeometrySource::Mesh {
        vertices, indices, ..
    } = &block.geometry.source
    else {
        panic!("a mesh")
    };
    let inside = |east_m: f64| {
        let o = glam::DVec3::new(east_m, 0.0, 5.0) - block.placement.position_enu_m;
        let d = glam::DVec3::new(0.013, 1.0, 0.007).normalize();
        let crossings = indices
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize].as_dvec3());
                let (e1, e2) = (b - a, c - a);
                let p = d.cross(e2);
                let det = e1.dot(p);
                if det.abs() < 1e-12 {
                    return false;
                }
                let s = o - a;
                let u = s.dot(p) / det;
                let q = s.cross(e1);
                let v = d.dot(q) / det;
                let t = e2.dot(q) / det;
                (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t > 0.0
            })
            .count();
        crossings % 2 == 1
    };
    assert!(!inside(0.0), "the courtyard is open");
    assert!(inside(30.0), "the block is solid");
    assert!(!inside(80.0), "outside the block");
}

#[test]
fn bad_osm_files_are_errors_that_name_the_item() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in [
        ("kml.osm", b"<kml/>".to_vec()),
        ("cut.osm", b"<osm><node id=\"1\" lat=".to_vec()),
        ("junk.osm.pbf", vec![0xff; 100]),
        ("empty.osm.pbf", Vec::new()),
    ] {
        let file = dir.path().join(name);
        std::fs::write(&file, bytes).unwrap();
        let scene = scene_over(dir.path(), &file, 0.0, 0.0, "");
        match savsim::scene::load(Path::new(&scene)) {
            Err(e) => assert!(e.to_string().contains("osm"), "{name}: {e}"),
            // An empty PBF holds no blocks: no buildings, not an error.
            Ok(s) => assert_eq!((name, s.osm[0].buildings), ("empty.osm.pbf", 0)),
        }
    }
    let file = dir.path().join("kml.osm");
    let scene = scene_over(dir.path(), &file, 0.0, 0.0, "level_m = -1");
    assert!(savsim::scene::load(Path::new(&scene))
        .unwrap_err()
        .to_string()
        .contains("level_m"));
}

/// The realdata OSM files cut and bit-flipped at random places: every one reads, or is an
/// error, and never takes the caller down (the `osmpbf` crate panics on some corrupt blocks in
/// a build with overflow checks; `parse_pbf` contains that: found by the `osm_reader` fuzz
/// target).
#[test]
fn real_osm_files_cut_and_corrupted_anywhere_read_or_fail_cleanly() {
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n.max(1) as u64) as usize
    };
    for (path, _) in realdata("osm") {
        let data = std::fs::read(&path).unwrap();
        for _ in 0..24 {
            let mut bad = data[..next(data.len())].to_vec();
            for _ in 0..16 {
                if !bad.is_empty() {
                    let at = next(bad.len());
                    bad[at] ^= 1 << next(8);
                }
            }
            let read = if path.extension().is_some_and(|e| e == "pbf") {
                savsim::scene::osm::parse_pbf(&bad)
            } else {
                std::str::from_utf8(&bad)
                    .map_err(|e| savsim::scene::osm::OsmError::Xml(e.to_string()))
                    .and_then(savsim::scene::osm::parse_xml)
            };
            if let Ok(data) = read {
                let _ = savsim::scene::osm::footprints(&data);
            }
        }
    }
}

/// A 40 m building 40 m square whose `building:part` (10 m tall) covers its north-east
/// quarter: the rest of the outline keeps its volume. A batch row flown at 10 m up through the
/// south-west quarter collides with the outline's piece; one flown at 30 m over the part's
/// quarter (above the 10 m part, inside the 40 m outline's box) does not.
#[test]
fn the_volume_an_outlines_parts_leave_uncovered_collides() {
    let dir = tempfile::tempdir().unwrap();
    // 20 m in degrees at the equator (spherical, near enough: the test needs the quarters).
    let d = 20.0 / 111_320.0;
    let osm = format!(
        r#"<osm version="0.6">
  <node id="1" lat="{m}" lon="{m}"/><node id="2" lat="{m}" lon="{d}"/>
  <node id="3" lat="{d}" lon="{d}"/><node id="4" lat="{d}" lon="{m}"/>
  <node id="5" lat="0" lon="0"/><node id="6" lat="0" lon="{d}"/><node id="7" lat="{d}" lon="0"/>
  <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="building" v="yes"/><tag k="height" v="40"/></way>
  <way id="11"><nd ref="5"/><nd ref="6"/><nd ref="3"/><nd ref="7"/><nd ref="5"/><tag k="building:part" v="yes"/><tag k="height" v="10"/></way>
</osm>"#,
        m = -d
    );
    let file = dir.path().join("quarter.osm");
    std::fs::write(&file, osm).unwrap();
    let scene_path = scene_over(dir.path(), &file, 0.0, 0.0, "");
    let scene = savsim::scene::load(Path::new(&scene_path)).unwrap();
    assert_eq!(
        (scene.osm[0].buildings, scene.osm[0].outlines_trimmed),
        (2, 1)
    );
    let row = |own: &str| savsim::batch::manifest::Run {
        scene: Some(scene_path.clone()),
        own: Some(own.into()),
        intruder: Some("0 500 500 100; 100 500 500 100".into()),
        duration_s: Some(60.0),
        ..savsim::batch::manifest::Run::default()
    };
    let runs = [
        row("0 -40 -10 10; 60 20 -10 10"),
        row("0 10 40 30; 60 10 5 30"),
    ];
    let scenes = savsim::batch::run::Scenes::for_runs(&runs);
    let through_sw = savsim::batch::run::run_one(0, &runs[0], &scenes);
    assert_eq!(through_sw.error, None);
    assert_eq!(through_sw.measured.collisions, 1, "{through_sw:?}");
    assert_eq!(
        through_sw.measured.first_collision_obstacle.as_deref(),
        Some("osm/way/10")
    );
    // Nose first into the west wall at E = -20 m, 1 m/s from E = -40 m.
    let t = through_sw.measured.first_collision_t_s.unwrap();
    assert!((18.0..20.0).contains(&t), "{t}");
    let over_the_part = savsim::batch::run::run_one(1, &runs[1], &scenes);
    assert_eq!(over_the_part.error, None);
    assert_eq!(over_the_part.measured.collisions, 0, "{over_the_part:?}");
}
