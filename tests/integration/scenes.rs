//! The scene file: the minimal form loads as written; bad files name file, item and field.

use std::path::Path;

use savsim::scene::{parse, Kind};

const MINIMAL: &str = r#"
[origin]
lat_deg = -35.363261
lon_deg = 149.165230
alt_m = 584.0

[[obstacle]]
id = "tower-1"
kind = "building"
shape = { box = [20.0, 20.0, 120.0] }      # size east, north, up in metres
position_enu_m = [100.0, 250.0, 0.0]        # base centre
yaw_deg = 0.0
"#;

#[test]
fn the_minimal_scene_loads_as_written() {
    let scene = parse(MINIMAL, Path::new("min.toml"), "min").unwrap();
    let o = &scene.obstacles[0];
    assert_eq!(
        (o.id.as_str(), o.kind, o.threat),
        ("tower-1", Kind::Building, 60.0)
    );
    assert_eq!(o.aabb_enu_m.min.to_array(), [90.0, 240.0, 0.0]);
    assert_eq!(o.aabb_enu_m.max.to_array(), [110.0, 260.0, 120.0]);
}

#[test]
fn geodetic_positions_threat_overrides_and_yaw() {
    let text = r#"
[origin]
lat_deg = 47.0
lon_deg = 8.0
alt_m = 400.0

[threat]
tree = 55.0

[[obstacle]]
id = "pine"
kind = "tree"
shape = { box = [2.0, 2.0, 20.0] }
position_geo = [47.0, 8.0, 450.0]

[[obstacle]]
id = "slab"
kind = "building"
threat = 99.0
shape = { box = [40.0, 2.0, 10.0] }
position_enu_m = [0.0, 0.0, 0.0]
yaw_deg = 90.0
"#;
    let scene = parse(text, Path::new("g.toml"), "g").unwrap();
    let pine = &scene.obstacles[0];
    assert!((pine.aabb_enu_m.min.z - 50.0).abs() < 1e-6);
    assert_eq!(pine.threat, 55.0);
    let slab = &scene.obstacles[1];
    assert_eq!(slab.threat, 99.0);
    // Turned 90 degrees: now long north-south.
    assert!(
        (slab.aabb_enu_m.max.y - 20.0).abs() < 1e-6 && (slab.aabb_enu_m.max.x - 1.0).abs() < 1e-6
    );
}

fn error_of(text: &str) -> String {
    parse(text, Path::new("scenes/bad.toml"), "bad")
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_scenes_name_the_file_the_obstacle_and_the_field() {
    let origin = "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n";
    for (body, want) in [
        ("[[obstacle]]\nid = \"a\"\nkind = \"building\"\nshape = { box = [1.0, -1.0, 1.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\n", vec!["scenes/bad.toml", "obstacle \"a\"", "shape", "not positive"]),
        ("[[obstacle]]\nid = \"b\"\nkind = \"building\"\nshape = { box = [1.0, 1.0, 1.0] }\n", vec!["obstacle \"b\"", "position_enu_m"]),
        ("[[obstacle]]\nid = \"c\"\nkind = \"building\"\nshape = { box = [1.0, 1.0, 1.0] }\nposition_enu_m = [0.0, 0.0]\n", vec!["obstacle \"c\"", "position_enu_m"]),
        ("[[obstacle]]\nid = \"d\"\nkind = \"building\"\nshape = { mesh = \"missing.obj\" }\nposition_enu_m = [0.0, 0.0, 0.0]\n", vec!["obstacle \"d\"", "shape", "missing.obj"]),
        ("[[obstacle]]\nid = \"e\"\nkind = \"building\"\nshape = { box = [1.0, 1.0, 1.0], mesh = \"x.obj\" }\nposition_enu_m = [0.0, 0.0, 0.0]\n", vec!["obstacle \"e\"", "exactly one"]),
        ("[[obstacle]]\nid = \"f\"\nkind = \"building\"\nshape = { box = [1.0, 1.0, 1.0] }\nposition_enu_m = [0.0, 0.0, 0.0]\ncolour = \"red\"\n", vec!["obstacle \"f\"", "colour"]),
        ("[[dynamic]]\nid = \"g\"\nkind = \"a320\"\nwaypoints = [{ t_s = 5.0, position_enu_m = [0.0, 0.0, 0.0] }, { t_s = 1.0, position_enu_m = [1.0, 0.0, 0.0] }]\n", vec!["dynamic \"g\"", "waypoints", "increasing"]),
        ("[[vehicle]]\nmodel = \"zeppelin\"\n", vec!["vehicle #1", "unknown model"]),
    ] {
        let e = error_of(&format!("{origin}{body}"));
        for w in want {
            assert!(e.contains(w), "{e:?} lacks {w:?}");
        }
    }
    assert!(
        error_of("[origin]\nlat_deg = 91.0\nlon_deg = 0.0\nalt_m = 0.0\n").contains("[origin]")
    );
    assert!(error_of("origin = 3").contains("scenes/bad.toml"));
    assert!(error_of("[[obstacle]\n").contains("scenes/bad.toml"));
}

#[test]
fn mesh_files_load_with_scale_and_up_axis() {
    let dir = tempfile::tempdir().unwrap();
    // A unit tetrahedron, Y up, and a duplicate + degenerate triangle that must be dropped.
    std::fs::write(
        dir.path().join("t.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\nf 1 1 2\n",
    )
    .unwrap();
    let scene_path = dir.path().join("s.toml");
    std::fs::write(
        &scene_path,
        "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n[[obstacle]]\nid = \"t\"\nkind = \"tree\"\n\
         shape = { mesh = \"t.obj\", scale = 10.0 }\nposition_enu_m = [0.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let scene = savsim::scene::load(&scene_path).unwrap();
    let o = &scene.obstacles[0];
    assert_eq!(o.geometry.triangle_count(), 4);
    // Y up: the file's y (1 -> 10 m) is up; its z (1) points south.
    assert!((o.aabb_enu_m.max.z - 10.0).abs() < 1e-5);
    assert!((o.aabb_enu_m.min.y + 10.0).abs() < 1e-5);
}

#[test]
fn the_bundled_scenes_load() {
    for name in ["scenes/city.toml", "scenes/mountain.toml"] {
        let path = crate::common::root().join(name);
        let scene = savsim::scene::load(&path).unwrap();
        assert!(scene.obstacles.len() > 1000, "{name}");
    }
}

#[test]
fn generators_are_deterministic() {
    let o = savsim::scene::gen::DEFAULT_ORIGIN;
    assert_eq!(
        savsim::scene::gen::city(3, o),
        savsim::scene::gen::city(3, o)
    );
    assert_ne!(
        savsim::scene::gen::city(3, o),
        savsim::scene::gen::city(4, o)
    );
    let bundled = std::fs::read_to_string(crate::common::root().join("scenes/city.toml")).unwrap();
    assert_eq!(
        bundled,
        savsim::scene::gen::city(5, o),
        "scenes/city.toml is `scene gen city --seed 5`"
    );
}

#[test]
fn aircraft_meshes_from_obj_and_gltf_become_traffic_models() {
    let Some(fixtures) = crate::common::shared_fixtures() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let m = fixtures.join("models");
    let text = format!(
        "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n\
         [[vehicle]]\nmodel = {{ mesh = \"{quad}\", scale = 0.5 }}\n\
         [[dynamic]]\nid = \"jet\"\nkind = \"a320\"\nmodel = {{ mesh = \"{plane}\", scale = 10.0 }}\n\
         waypoints = [{{ t_s = 0.0, position_enu_m = [0.0, 0.0, 100.0] }}]\n\
         [[dynamic]]\nid = \"px4\"\nkind = \"dji\"\nmodel = {{ mesh = \"{px4}\", scale = 1.0 }}\n\
         waypoints = [{{ t_s = 0.0, position_enu_m = [0.0, 0.0, 100.0] }}]\n\
         [[dynamic]]\nid = \"balloon\"\nkind = \"balloon\"\nmodel = {{ mesh = \"{balloon}\", scale = 5.0 }}\n\
         waypoints = [{{ t_s = 0.0, position_enu_m = [0.0, 0.0, 100.0] }}]\n",
        quad = m.join("UAVLogViewer__quad.glb").display(),
        plane = m.join("UAVLogViewer__plane.glb").display(),
        px4 = m.join("mavsim-viewer__px4_fixed_wing.obj").display(),
        balloon = m.join("PtahRenderer__balloon.obj").display(),
    );
    let path = dir.path().join("models.toml");
    std::fs::write(&path, text).unwrap();
    let scene = savsim::scene::load(&path).unwrap();
    let vehicle = &scene.geometries[scene.vehicle_model(1)];
    assert!(
        vehicle.triangle_count() > 100,
        "quad.glb: {}",
        vehicle.triangle_count()
    );
    for d in &scene.dynamic {
        assert!(
            d.geometry.triangle_count() > 100,
            "{}: {}",
            d.id,
            d.geometry.triangle_count()
        );
        let size = d.geometry.local_aabb.maxs - d.geometry.local_aabb.mins;
        assert!(
            size.max_element() > 0.1 && size.max_element() < 1.0e4,
            "{}: {size:?}",
            d.id
        );
    }
}

#[test]
fn collada_models_come_in_metres_and_z_up() {
    let Some(fixtures) = crate::common::shared_fixtures() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let obstacle = |id: &str, file: &str| {
        format!(
            "[[obstacle]]\nid = \"{id}\"\nkind = \"building\"\nshape = {{ mesh = \"{}\" }}\nposition_enu_m = [0.0, 0.0, 0.0]\n",
            fixtures.join(file).display()
        )
    };
    let text = format!(
        "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nalt_m = 0.0\n{}{}",
        obstacle("office", "city/gazebo_models__office_building.dae"),
        obstacle("quadrotor", "models/gazebo_models__quadrotor_base.dae"),
    ) + &format!(
        "[[dynamic]]\nid = \"cessna\"\nkind = \"dji\"\nmodel = {{ mesh = \"{}\" }}\n\
         waypoints = [{{ t_s = 0.0, position_enu_m = [0.0, 0.0, 100.0] }}]\n",
        fixtures
            .join("models/gazebo_models__cessna_body.dae")
            .display()
    );
    let path = dir.path().join("dae.toml");
    std::fs::write(&path, text).unwrap();
    let scene = savsim::scene::load(&path).unwrap();
    let size = |i: usize| {
        let b = scene.obstacles[i].aabb_enu_m;
        b.max - b.min
    };
    // The office building is modelled in inches, Z up: a few storeys, some tens of metres wide.
    let office = size(0);
    assert!(
        office.z > 5.0 && office.z < 60.0 && office.x > 5.0 && office.x < 100.0,
        "{office:?}"
    );
    // The quadrotor is in metres: well under two metres across, flatter than it is wide.
    let quad = size(1);
    assert!(quad.x < 2.0 && quad.y < 2.0 && quad.z < quad.x, "{quad:?}");
    // The Cessna (inches, nodes instanced from <library_nodes>): a light aircraft, 11 m span.
    let cessna = scene.dynamic[0].geometry.local_aabb;
    let span = cessna.maxs - cessna.mins;
    assert!(
        span.max_element() > 9.0 && span.max_element() < 13.0 && span.z < 4.0,
        "{span:?}"
    );
}
