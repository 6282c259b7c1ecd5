//! Criterion benches of the collision core's hot pieces, on the bundled city:
//!
//! - `step/<mode>`: one flight of the bench set (a crossing at 40 m), every tick, per mode;
//! - `ray_fan`: the six 300 m rays cast front to back through the octree at a downtown point
//!   (each obstacle hit at its box);
//! - `ray_fan/bvh`: the same six rays through the static `Bvh` the sensing layer casts on.
//! - `broadphase/*`: the obstacles in a 600 m box, by savsim's octree, parry's Bvh and a
//!   linear scan;
//! - `mesh_build/*`: turning a building and an airliner model into parry TriMeshes.
//! - `image/*`: a whole reading of an image device or a lidar cast from a street corner
//!   downtown (20 m up, looking north-east across the blocks) through the exact rays the feed
//!   casts: the 160 x 120 planner image, a D435 at 424 x 240 and 848 x 480 (to 10 m, and to
//!   300 m), a VLP-16 turn and an OS1-64 turn. Throughput in rays.
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

fn images(c: &mut Criterion) {
    use savsim::pipeline::{BodySource, MovingBodies, Rays};
    use savsim_core::sensors::device::Model;
    use savsim_core::sensors::spec::DeviceSpec;
    let scene = city();
    let mut pipeline = Pipeline::new(&scene, CollisionConfig::default());
    let own = BodySource::Vehicle {
        vehicle: 1,
        component_id: 1,
    };
    let origin = DVec3::new(8.0, 50.0, 20.0);
    // Looking north-east: the device's x (boresight) to ENU north-east, its y (right) to
    // south-east, its z (down) down.
    let (ne, se) = (
        DVec3::new(1.0, 1.0, 0.0).normalize_or_zero(),
        DVec3::new(1.0, -1.0, 0.0).normalize_or_zero(),
    );
    let to_enu = |d: DVec3| ne * d.x + se * d.y - DVec3::Z * d.z;
    let mut group = c.benchmark_group("image");
    group.sample_size(10);
    for (name, spec) in [
        ("depth-160x120", "preset = \"depth-160x120\""),
        (
            "d435-424x240",
            "preset = \"realsense-d435-depth\"\nimage_px = [424, 240]",
        ),
        ("d435-848x480", "preset = \"realsense-d435-depth\""),
        (
            "d435-424x240-to-300m",
            "preset = \"realsense-d435-depth\"\nimage_px = [424, 240]\nrange_m = [0.2, 300.0]",
        ),
        ("vlp16", "preset = \"velodyne-vlp16\""),
        ("os1-64", "preset = \"ouster-os1-64\""),
    ] {
        let spec: DeviceSpec = toml::from_str(spec).expect("a device");
        let Model::Range(model) = spec.build().expect("it builds").model else {
            unreachable!("a range device")
        };
        let dirs: Vec<DVec3> = model.beams().iter().map(|b| to_enu(b[0])).collect();
        let mut out = vec![None; dirs.len()];
        let rays = Rays {
            origin_enu_m: origin,
            dirs_enu: &dirs,
            max_m: model.range_m[1],
        };
        pipeline.cast_exact_rays(&scene, own, &MovingBodies::default(), rays, &mut out);
        let hits = out.iter().flatten().count();
        eprintln!(
            "image/{name}: {} rays, {hits} hit ({:.0}%)",
            dirs.len(),
            100.0 * hits as f64 / dirs.len() as f64
        );
        group.throughput(Throughput::Elements(dirs.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| {
                let rays = Rays {
                    origin_enu_m: origin,
                    dirs_enu: &dirs,
                    max_m: model.range_m[1],
                };
                pipeline.cast_exact_rays(&scene, own, &MovingBodies::default(), rays, &mut out);
                out.iter().flatten().count()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, step, ray_fan, broadphase, mesh_build, images);
criterion_main!(benches);
