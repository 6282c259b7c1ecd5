//! Criterion benches of the collision core's hot pieces, on the bundled city:
//!
//! - `step/<mode>`: one flight of the bench set (a crossing at 40 m), every tick, per mode;
//! - `ray_fan`: the six 300 m rays cast front to back through the octree at a downtown point
//!   (each obstacle hit at its box);
//! - `ray_fan/bvh`: the same six rays through the static `Bvh` the sensing layer casts on.
//! - `broadphase/*`: the obstacles in a 600 m box, by savsim's octree, parry's Bvh and a
//!   linear scan;
//! - `mesh_build/*`: turning a building and an airliner model into parry TriMeshes.
//!
//! `cargo bench --bench core`; figures in docs/accuracy-vs-speed.md.

// criterion_group! makes an undocumented function.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::DVec3;
use parry3d::bounding_volume::Aabb;
use parry3d::partitioning::{Bvh, BvhBuildStrategy};
use savsim::bench::flights::flight_set;
use savsim::bench::run_samples;
use savsim::collision::broad_phase::StaticBroadPhase;
use savsim::collision::sensing::octree::{Octree, OctreeConfig, OctreeWorkspace};
use savsim::pipeline::{CollisionConfig, Mode, Pipeline, SensorFan};
use savsim::scene::{Aabb64, Kind, Scene};

fn city() -> Scene {
    savsim::scene::load(&savsim::bundled::bundled("scenes/city.toml"))
        .expect("the bundled city loads")
}

fn step(c: &mut Criterion) {
    let scene = city();
    let flight = flight_set(&scene)
        .into_iter()
        .find(|f| f.name == "cross-ew-40m")
        .expect("the crossing is in the set");
    let mut group = c.benchmark_group("step");
    group.sample_size(10);
    group.throughput(Throughput::Elements(flight.samples.len() as u64));
    for mode in [
        Mode::Box,
        Mode::Mesh,
        Mode::Paper,
        Mode::Exact,
        Mode::Reference,
    ] {
        let mut pipeline = Pipeline::new(
            &scene,
            CollisionConfig {
                mode,
                ..Default::default()
            },
        );
        let mut vehicle = 0u16;
        group.bench_function(BenchmarkId::from_parameter(mode.name()), |b| {
            b.iter(|| {
                // A fresh vehicle each flight; the mesh cache stays warm, as in a long run.
                vehicle = vehicle.wrapping_add(1);
                run_samples(
                    &mut pipeline,
                    &scene,
                    vehicle,
                    &flight.samples,
                    &flight.traffic,
                )
            })
        });
    }
    group.finish();
}

fn ray_fan(c: &mut Criterion) {
    let scene = city();
    let boxes: Vec<Aabb64> = scene.obstacles.iter().map(|o| o.aabb_enu_m).collect();
    let octree = Octree::build(&boxes, OctreeConfig::default());
    let mut ws = OctreeWorkspace::default();
    let origin = DVec3::new(8.0, 50.0, 40.0);
    let statics = StaticBroadPhase::build(&boxes);
    let axes: Vec<DVec3> = (0..6)
        .map(|k| SensorFan::Axes.direction_enu(k, glam::DQuat::IDENTITY))
        .collect();
    c.bench_function("ray_fan", |b| {
        b.iter(|| {
            axes.iter()
                .map(|&dir| {
                    octree.cast_ray(origin, dir, 300.0, &mut ws, |i, limit| {
                        boxes[i as usize].ray_entry(origin, dir, limit)
                    })
                })
                .collect::<Vec<_>>()
        })
    });
    c.bench_function("ray_fan/bvh", |b| {
        b.iter(|| {
            axes.iter()
                .map(|&dir| {
                    statics.cast_ray(origin, dir, 300.0, |i, limit| {
                        boxes[i as usize].ray_entry(origin, dir, limit)
                    })
                })
                .collect::<Vec<_>>()
        })
    });
}

fn broadphase(c: &mut Criterion) {
    let scene = city();
    let boxes: Vec<Aabb64> = scene.obstacles.iter().map(|o| o.aabb_enu_m).collect();
    let octree = Octree::build(&boxes, OctreeConfig::default());
    let bvh = Bvh::from_iter(
        BvhBuildStrategy::Binned,
        boxes
            .iter()
            .map(|b| Aabb::new(b.min.as_vec3(), b.max.as_vec3()))
            .enumerate(),
    );
    let query = Aabb64::around(DVec3::new(8.0, 50.0, 40.0), DVec3::splat(300.0));
    let query32 = Aabb::new(query.min.as_vec3(), query.max.as_vec3());
    let mut ws = OctreeWorkspace::default();
    let mut group = c.benchmark_group("broadphase");
    group.bench_function("octree", |b| {
        b.iter(|| {
            let mut n = 0usize;
            octree.query_aabb(&query, &mut ws, |_| n += 1);
            n
        })
    });
    group.bench_function("parry_bvh", |b| {
        b.iter(|| bvh.intersect_aabb(&query32).count())
    });
    group.bench_function("linear", |b| {
        b.iter(|| boxes.iter().filter(|o| o.intersects(&query)).count())
    });
    group.finish();
}

fn mesh_build(c: &mut Criterion) {
    let scene = city();
    let building = scene
        .obstacles
        .iter()
        .max_by_key(|o| o.geometry.triangle_count())
        .expect("the city has buildings")
        .geometry
        .clone();
    let airliner = scene.geometries[scene.kind_model(Kind::A320)].clone();
    let mut group = c.benchmark_group("mesh_build");
    group.sample_size(20);
    group.bench_function(
        format!("building_{}_triangles", building.triangle_count()),
        |b| b.iter(|| building.build_trimesh()),
    );
    group.bench_function(
        format!("a320_{}_triangles", airliner.triangle_count()),
        |b| b.iter(|| airliner.build_trimesh()),
    );
    group.finish();
}

criterion_group!(benches, step, ray_fan, broadphase, mesh_build);
criterion_main!(benches);
