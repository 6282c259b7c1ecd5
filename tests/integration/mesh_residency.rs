//! Which triangle meshes are resident: a budget smaller than the flight needs (evicted and
//! rebuilt, nothing missed against the reference), the mesh worker (it changes where meshes
//! are built and nothing else), and clones of one pipeline sharing the meshes built once.

use std::sync::Arc;

use glam::DVec3;
use savsim::bench::{collisions, run_samples};
use savsim::geo::{Geodetic, LocalTangentPlane};
use savsim::pipeline::{CollisionConfig, Mode, Pipeline};
use savsim::scene::Scene;
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

/// A tessellated box as a Wavefront OBJ (each face split into `n` x `n` cells: a modelled
/// building's 12 n^2 triangles), `size` metres, standing on z = 0.
fn box_obj(size: [f64; 3], n: usize) -> String {
    let mut obj = String::new();
    let mut count = 0;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0.0, 1.0] {
            let base = count;
            for j in 0..=n {
                for i in 0..=n {
                    let mut p = [0.0; 3];
                    p[axis] = side * size[axis];
                    p[u] = size[u] * i as f64 / n as f64;
                    p[v] = size[v] * j as f64 / n as f64;
                    obj += &format!(
                        "v {} {} {}\n",
                        p[0] - size[0] / 2.0,
                        p[1] - size[1] / 2.0,
                        p[2]
                    );
                    count += 1;
                }
            }
            for j in 0..n {
                for i in 0..n {
                    let a = base + j * (n + 1) + i + 1;
                    let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
                    obj += &format!("f {a} {b} {d}\nf {a} {d} {c}\n");
                }
            }
        }
    }
    obj
}

/// A street of 24 loaded meshes (models from files: the one kind of exact shape that is a
/// triangle mesh, about 0.1 MiB each), every third across the street, and a flight along it.
fn street_of_meshes(dir: &std::path::Path) -> (Scene, Vec<TrackSample>) {
    let mut body = String::new();
    for k in 0..24 {
        let size = [12.0 + k as f64 * 0.25, 10.0, 20.0 + (k % 5) as f64 * 4.0];
        std::fs::write(dir.join(format!("b{k}.obj")), box_obj(size, 10)).unwrap();
        // Either side of the street (y = +-12 m), every third one across it (a collision).
        let y = match k % 3 {
            0 => 0.0,
            1 => 12.0,
            _ => -12.0,
        };
        body += &format!(
            "[[obstacle]]\nid = \"b{k}\"\nkind = \"building\"\nshape = {{ mesh = \"b{k}.obj\", up = \"z\" }}\nposition_enu_m = [{}, {y}, 0.0]\n",
            40.0 * k as f64
        );
    }
    let path = dir.join("street.toml");
    std::fs::write(
        &path,
        format!(
            "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n{body}",
            ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN.alt_m
        ),
    )
    .unwrap();
    let flight = straight(
        ORIGIN,
        DVec3::new(-30.0, 3.0, 12.0),
        DVec3::new(960.0, 3.0, 12.0),
        20.0,
        10.0,
    );
    (savsim::scene::load(&path).unwrap(), flight)
}

/// A mesh budget smaller than the flight needs: the street of meshes under 0.3 MiB. Meshes are
/// evicted and rebuilt, the held bytes stay within the budget, and nothing is missed against
/// the reference.
#[test]
fn a_mesh_budget_smaller_than_the_flight_needs_misses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (s, flight) = street_of_meshes(dir.path());
    let mut reference = Pipeline::new(&s, config(Mode::Reference));
    let truth = run_samples(&mut reference, &s, 1, &flight, &[]).1;
    let truth = collisions(&truth);
    // Every third building stands across the street; a loaded mesh is a surface, so its
    // near wall and its far wall are each a contact.
    assert_eq!(truth.len(), 16, "{truth:?}");
    let budget_mib = 0.3;
    let mut exact = Pipeline::new(
        &s,
        CollisionConfig {
            mesh_budget_mib: budget_mib,
            ..config(Mode::Exact)
        },
    );
    let found = run_samples(&mut exact, &s, 1, &flight, &[]).1;
    let found = collisions(&found);
    assert_eq!(found.len(), truth.len(), "{found:?} vs {truth:?}");
    for (a, b) in found.iter().zip(&truth) {
        assert_eq!(a.0, b.0);
        assert!((a.1 - b.1).abs() <= 1e-3, "{a:?} vs {b:?}");
    }
    assert!(
        exact.meshes().counts().evicted > 0,
        "the budget forced evictions"
    );
    let budget = (budget_mib * 1024.0 * 1024.0) as usize;
    assert!(
        exact.meshes().counts().peak_bytes <= budget + 200_000,
        "held {} at most, budget {budget}",
        exact.meshes().counts().peak_bytes
    );
    assert!(
        exact.meshes().counts().bytes <= budget,
        "held {}",
        exact.meshes().counts().bytes
    );
}

/// The mesh worker builds the meshes the sensing layer asks for off the tick path; the same
/// meshes are resident at the same decisions whether it runs or not: the same events, the same
/// counts, and no mesh built for a contact on the flight along the street.
#[test]
fn the_mesh_worker_changes_where_meshes_are_built_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let (s, flight) = street_of_meshes(dir.path());
    let run = |worker: bool, budget_mib: f64| {
        let mut p = Pipeline::new(
            &s,
            CollisionConfig {
                mesh_budget_mib: budget_mib,
                ..config(Mode::Exact)
            },
        );
        p.set_mesh_worker(worker);
        let events = run_samples(&mut p, &s, 1, &flight, &[]).1;
        let m = &p.meshes();
        let counts = (
            m.counts().built,
            m.counts().built_on_contact,
            m.counts().evicted,
            m.counts().peak_bytes,
            m.counts().prefetch_refused,
        );
        (events, counts)
    };
    for budget_mib in [512.0, 0.3] {
        let (with, counts_with) = run(true, budget_mib);
        let (without, counts_without) = run(false, budget_mib);
        assert_eq!(with, without, "budget {budget_mib} MiB");
        assert_eq!(counts_with, counts_without, "budget {budget_mib} MiB");
        if budget_mib > 1.0 {
            assert_eq!(
                counts_with.1, 0,
                "every mesh was resident before a contact needed it"
            );
            assert!(counts_with.0 >= 8, "{counts_with:?}");
        }
    }
}

/// A session on a clone of one pipeline built once with every mesh resident (what the fuzz
/// targets share between inputs) reports what a session of its own reports, builds no mesh
/// again, and leaves the shared pipeline as it was for the next run.
#[test]
fn a_session_on_a_shared_pipeline_reports_what_a_fresh_one_does() {
    let s = Arc::new(scene(concat!(
        "[[obstacle]]\nid = \"u-plan\"\nkind = \"building\"\n",
        "shape = { blocks = [[-20.0, -20.0, 0.0, 20.0, -10.0, 30.0], [-20.0, -20.0, 0.0, -10.0, 20.0, 30.0], [10.0, -20.0, 0.0, 20.0, 20.0, 30.0]], tessellate_m = 3 }\n",
        "position_enu_m = [60.0, 0.0, 0.0]\n",
        "[[obstacle]]\nid = \"mast\"\nkind = \"building\"\nshape = { box = [2.0, 2.0, 40.0] }\n",
        "position_enu_m = [20.0, 4.0, 0.0]\n",
        "[[terrain]]\nid = \"hill\"\nkind = \"mountain\"\n",
        "generated = { seed = 3, size_m = [200, 200], cell_m = 20, relief_m = 10 }\n",
        "position_enu_m = [-50.0, -100.0, -10.0]\n",
    )));
    let plane = LocalTangentPlane::new(s.origin);
    // East at 4 m/s, 15 m up: past the mast 2.5 m away, into the U's west wing at x = 40 m.
    let fly = |session: &mut Session| {
        let mut seq = 0u8;
        for i in 0..300u32 {
            let t = 1000.0 + f64::from(i) * 0.1;
            let p = DVec3::new(f64::from(i) * 0.4, 0.5, 15.0);
            let bytes = position_frames(&plane, 1, &mut seq, 5_000 + i * 100, p, DVec3::X * 4.0);
            feed(session, t, &bytes);
        }
        session.finish().unwrap();
    };
    let mut fresh = Session::new(Some(s.clone()), CollisionConfig::default(), None).unwrap();
    fly(&mut fresh);
    let fresh_pipeline = fresh.pipeline().unwrap();
    assert_eq!(collisions_on(fresh.notable(), 1)[0].0, "u-plan");
    // The terrain's exact shape is a height field and the blocks' a compound: no mesh at all.
    assert_eq!(
        fresh_pipeline.meshes().counts().built,
        0,
        "exact builds no mesh here"
    );

    let mut shared = Pipeline::new(&s, CollisionConfig::default());
    shared.build_every_mesh(&s);
    let built = shared.meshes().counts().built;
    assert_eq!(built, 3);
    for _ in 0..2 {
        let mut session = Session::with_pipeline(s.clone(), shared.clone(), None).unwrap();
        fly(&mut session);
        let pipeline = session.pipeline().unwrap();
        assert_eq!(session.notable(), fresh.notable());
        assert_eq!(pipeline.totals(), fresh_pipeline.totals());
        assert_eq!(
            pipeline.meshes().counts().built,
            built,
            "no mesh was built again"
        );
    }
    assert_eq!(shared.totals().ticks, 0, "the shared pipeline is untouched");
}
