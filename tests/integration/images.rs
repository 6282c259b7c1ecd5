//! Image devices and lidars against an independent cast: the pinhole's rays written here from
//! the pinhole model, the boxes' twelve triangles each written here from their corners, and a
//! scalar Moller-Trumbore cast over every triangle (sharing no code with savsim's); the depth
//! image and its segmentation, a field of view's edges, a lidar's channels and returns, the
//! determinism of a noisy image, and bad definitions.

use glam::DVec3;
use savsim::geo::Geodetic;
use savsim::pipeline::{BodySource, CollisionConfig, MovingBodies, ObstacleRef, Pipeline, Rays};
use savsim_core::sensors::device::{Model, RangeModel};
use savsim_core::sensors::draws::Draws;
use savsim_core::sensors::image::{DepthImage, PointCloud, Segment, SegmentClass};
use savsim_core::sensors::range::{Beam, BeamReading, BeamTruth, RangeState};
use savsim_core::sensors::spec::DeviceSpec;

use crate::common::{boxes_scene, scene_at};

const ORIGIN: Geodetic = Geodetic::new(-35.363261, 149.165230, 584.0);

const OWN: BodySource = BodySource::Vehicle {
    vehicle: 1,
    component_id: 1,
};

/// Boxes as (min, max) ENU corners: a wall ahead, a block to the right, a post to the left, a
/// low slab below: all within 9 m of the camera at (0, 0, 5).
const BOXES: [([f64; 3], [f64; 3]); 4] = [
    ([-6.0, 7.25, 0.0], [6.0, 8.5, 12.0]),
    ([2.5, 2.0, 0.0], [4.75, 5.5, 7.5]),
    ([-3.1, 3.3, 0.0], [-2.6, 3.9, 9.0]),
    ([-2.0, 4.0, 0.0], [2.0, 7.0, 2.5]),
];

/// A box's twelve triangles, from its eight corners.
fn box_triangles((lo, hi): ([f64; 3], [f64; 3])) -> Vec<[DVec3; 3]> {
    let c = |x: usize, y: usize, z: usize| {
        DVec3::new([lo[0], hi[0]][x], [lo[1], hi[1]][y], [lo[2], hi[2]][z])
    };
    let quads = [
        [c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 1, 0), c(1, 1, 0), c(1, 1, 1), c(0, 1, 1)],
        [c(0, 0, 0), c(0, 1, 0), c(0, 1, 1), c(0, 0, 1)],
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
    ];
    quads
        .iter()
        .flat_map(|[a, b, cc, d]| [[*a, *b, *cc], [*a, *cc, *d]])
        .collect()
}

/// The nearest triangle a ray meets within `max_m` (Moller-Trumbore in f64, every triangle
/// tried): its distance and the index of the box it belongs to.
fn scalar_cast(
    boxes: &[([f64; 3], [f64; 3])],
    origin: DVec3,
    dir: DVec3,
    max_m: f64,
) -> Option<(f64, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (i, b) in boxes.iter().enumerate() {
        for [a, bb, c] in box_triangles(*b) {
            let (e1, e2) = (bb - a, c - a);
            let p = dir.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let s = origin - a;
            let u = s.dot(p) / det;
            let q = s.cross(e1);
            let v = dir.dot(q) / det;
            let t = e2.dot(q) / det;
            let inside = (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0;
            if inside && (0.0..=max_m).contains(&t) && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i));
            }
        }
    }
    best
}

/// Pixel `(u, v)`'s ray of a `w` x `h` pinhole whose field is `fov_deg` (edge to edge), in the
/// camera's frame (x along the optical axis, y right, z down), unit: through the pixel's centre.
fn pinhole_ray(w: u32, h: u32, fov_deg: [f64; 2], u: u32, v: u32) -> DVec3 {
    let fx = f64::from(w) / 2.0 / (fov_deg[0].to_radians() / 2.0).tan();
    let fy = f64::from(h) / 2.0 / (fov_deg[1].to_radians() / 2.0).tan();
    DVec3::new(
        1.0,
        (f64::from(u) + 0.5 - f64::from(w) / 2.0) / fx,
        (f64::from(v) + 0.5 - f64::from(h) / 2.0) / fy,
    )
    .normalize_or_zero()
}

fn device(toml_text: &str) -> RangeModel {
    let spec: DeviceSpec = toml::from_str(toml_text).unwrap();
    match spec.build().unwrap().model {
        Model::Range(m) => m,
        other => panic!("not a range device: {other:?}"),
    }
}

/// A camera looking along ENU `forward`, its right level, its down square to both: the
/// camera's frame to ENU.
fn camera_to_enu(forward: DVec3) -> impl Fn(DVec3) -> DVec3 {
    let f = forward.normalize_or_zero();
    let right = f.cross(DVec3::Z).normalize_or_zero();
    let down = f.cross(right);
    move |d: DVec3| f * d.x + right * d.y + down * d.z
}

/// `model`'s reading at instant `(k, dt_s)` of what `hits` says is along each of its `beams`,
/// drawing with `seed` and `key`: the truths and the readings.
fn read(
    model: &RangeModel,
    beams: &[Beam],
    hits: &[Option<(ObstacleRef, f64)>],
    (seed, key): (u64, u64),
    instant: (u64, f64),
) -> (Vec<BeamTruth>, Vec<BeamReading>) {
    let truths: Vec<BeamTruth> = beams
        .iter()
        .zip(hits)
        .map(|(b, hit)| BeamTruth::along(b, hit.map(|(_, d)| d)))
        .collect();
    let mut readings = vec![BeamReading::NoData; beams.len()];
    model.read(
        &mut RangeState::default(),
        &Draws::new(seed),
        key,
        instant,
        &truths,
        &mut readings,
    );
    (truths, readings)
}

/// What the pipeline's exact rays say from `origin` along `dirs`.
fn cast(
    boxes: &[([f64; 3], [f64; 3])],
    origin: DVec3,
    dirs: &[DVec3],
    max_m: f64,
) -> Vec<Option<(ObstacleRef, f64)>> {
    let scene = scene_at(ORIGIN, &boxes_scene(boxes));
    let mut pipeline = Pipeline::new(&scene, CollisionConfig::default());
    let mut out = vec![None; dirs.len()];
    let rays = Rays {
        origin_enu_m: origin,
        dirs_enu: dirs,
        max_m,
    };
    pipeline.cast_exact_hits(&scene, OWN, &MovingBodies::default(), rays, &mut out);
    out
}

#[test]
fn a_depth_image_and_its_segmentation_match_a_scalar_cast_over_every_triangle() {
    let (w, h, fov) = (160, 120, [87.0, 58.0]);
    let camera = device(
        "kind = \"range\"\nrate_hz = 30.0\nimage_px = [160, 120]\nfov_deg = [87.0, 58.0]\nrange_m = [0.1, 20.0]",
    );
    // savsim's rays are the pinhole's, pixel by pixel, row by row from the top left.
    let beams = camera.beams();
    assert_eq!(beams.len(), (w * h) as usize);
    for v in 0..h {
        for u in 0..w {
            let want = pinhole_ray(w, h, fov, u, v);
            let got = beams[(v * w + u) as usize][0];
            assert!((got - want).length() < 1e-12, "pixel ({u}, {v})");
        }
    }
    let origin = DVec3::new(0.0, 0.0, 5.0);
    let to_enu = camera_to_enu(DVec3::new(0.1, 1.0, 0.0));
    let dirs: Vec<DVec3> = beams.iter().map(|b| to_enu(b[0])).collect();
    let hits = cast(&BOXES, origin, &dirs, 20.0);
    // The reading without errors, made into an image.
    let (truths, readings) = read(&camera, &beams, &hits, (1, 7), (0, 1.0 / 30.0));
    let segments: Vec<Segment> = hits
        .iter()
        .map(|hit| {
            hit.map_or_else(Segment::default, |(o, _)| {
                savsim_core::collision::fan::segment_of(o, |_| Some(savsim::scene::Kind::Building))
            })
        })
        .collect();
    let mut image = DepthImage::default();
    image.fill(w, h, &readings, &truths, &segments);
    let (mut seen, mut per_box) = (0, [0usize; 4]);
    for v in 0..h {
        for u in 0..w {
            let i = (v * w + u) as usize;
            let ray = pinhole_ray(w, h, fov, u, v);
            let want = scalar_cast(&BOXES, origin, to_enu(ray), 20.0);
            let depth = image.depth_m[i];
            match want {
                Some((t, b)) => {
                    let want_depth = t * ray.x;
                    assert!(
                        (f64::from(depth) - want_depth).abs() < 1e-6,
                        "pixel ({u}, {v}): depth {depth}, want {want_depth}"
                    );
                    assert_eq!(
                        (image.segment_id[i], image.class[i]),
                        (b as u32 + 1, SegmentClass::Building as u8),
                        "pixel ({u}, {v}) sees box {b}"
                    );
                    seen += 1;
                    per_box[b] += 1;
                }
                None => {
                    assert!(depth.is_infinite(), "pixel ({u}, {v}): {depth}, want none");
                    assert_eq!((image.segment_id[i], image.class[i]), (0, 0));
                }
            }
        }
    }
    assert!(seen > 5_000, "{seen} pixels see a box");
    assert!(
        per_box.iter().all(|&n| n > 50),
        "pixels per box: {per_box:?}"
    );
}

#[test]
fn an_edge_pixel_sees_a_box_0_01_degree_inside_its_ray_and_not_outside() {
    // A block whose south-west edge stands at (0, 6): a ray from the origin bearing east of
    // north meets it, one bearing west of north does not. The camera is yawed so that the
    // right-most pixels' rays bear 0.01 degree to one side of that edge.
    let (w, h, fov) = (160, 120, [87.0, 58.0]);
    let camera = device(
        "kind = \"range\"\nrate_hz = 30.0\nimage_px = [160, 120]\nfov_deg = [87.0, 58.0]\nrange_m = [0.1, 40.0]",
    );
    let block = [([0.0, 6.0, 0.0], [20.0, 26.0, 30.0])];
    let origin = DVec3::new(0.0, 0.0, 5.0);
    let ray = pinhole_ray(w, h, fov, w - 1, h / 2);
    let azimuth = ray.y.atan2(ray.x);
    // The field's edge is half a pixel beyond the last column's rays.
    let edge = (fov[0] / 2.0).to_radians();
    assert!(azimuth < edge && edge - azimuth < (fov[0] / f64::from(w)).to_radians());
    let looking = |yaw: f64| {
        let to_enu = camera_to_enu(DVec3::new(yaw.sin(), yaw.cos(), 0.0));
        let dirs: Vec<DVec3> = camera.beams().iter().map(|b| to_enu(b[0])).collect();
        (cast(&block, origin, &dirs, 40.0), to_enu)
    };
    for (offset_deg, sees) in [(0.01f64, true), (-0.01, false)] {
        let (hits, to_enu) = looking(offset_deg.to_radians() - azimuth);
        for v in 0..h {
            let got = hits[(v * w + w - 1) as usize];
            assert_eq!(
                got.is_some(),
                sees,
                "row {v}, {offset_deg:+} degree: {got:?}"
            );
            let want = scalar_cast(
                &block,
                origin,
                to_enu(pinhole_ray(w, h, fov, w - 1, v)),
                40.0,
            );
            assert_eq!(want.is_some(), sees, "the scalar cast, row {v}");
        }
        // The column before it bears a pixel further west: it never sees the block.
        assert!((0..h).all(|v| hits[(v * w + w - 2) as usize].is_none()));
    }
    // Nothing beyond the field's edge is in any pixel: the block's edge 0.01 degree outside.
    let (hits, _) = looking(-(edge + 0.01f64.to_radians()));
    assert!(hits.iter().all(Option::is_none));
    // And 0.01 degree inside the edge, though no ray is there yet, nor half a pixel in...
    let (hits, _) = looking(-(edge - 0.01f64.to_radians()));
    assert!(hits.iter().all(Option::is_none));
    // ... while the last column sees it once its rays are past the edge of the block.
    let (hits, _) = looking(-(azimuth - 0.01f64.to_radians()));
    assert!(hits.iter().any(Option::is_some));
}

#[test]
fn a_vlp16_turn_has_its_channels_and_its_returns_lie_on_the_faces() {
    let lidar = device("preset = \"velodyne-vlp16\"\nsigma_m = 0.0\nquantum_m = 0.0");
    let beams = lidar.beams();
    assert_eq!(beams.len(), 16 * 1800);
    // 16 elevations, -15 to +15 degrees 2 apart, from the top row down.
    let mut elevations: Vec<f64> = beams
        .iter()
        .step_by(1800)
        .map(|b| (-b[0].z).asin().to_degrees())
        .collect();
    elevations.reverse();
    for (i, e) in elevations.iter().enumerate() {
        assert!(
            (e - (-15.0 + 2.0 * i as f64)).abs() < 1e-9,
            "{elevations:?}"
        );
    }
    // Inside a room 8 x 6 x 4 m (its walls four boxes), the lidar at its middle, 2 m up.
    let room = [
        ([-4.5, -3.0, 0.0], [-4.0, 3.0, 4.0]),
        ([4.0, -3.0, 0.0], [4.5, 3.0, 4.0]),
        ([-4.5, -3.5, 0.0], [4.5, -3.0, 4.0]),
        ([-4.5, 3.0, 0.0], [4.5, 3.5, 4.0]),
    ];
    let origin = DVec3::new(0.0, 0.0, 2.0);
    let to_enu = camera_to_enu(DVec3::Y);
    let dirs: Vec<DVec3> = beams.iter().map(|b| to_enu(b[0])).collect();
    let hits = cast(&room, origin, &dirs, 100.0);
    let (_, readings) = read(&lidar, &beams, &hits, (3, 1), (0, 0.1));
    let mut cloud = PointCloud::default();
    cloud.fill(&beams, &readings, &vec![Segment::default(); beams.len()]);
    // Every ray within +-15 degrees meets a wall from 2 m up (the 0.9 m minimum: none nearer).
    assert_eq!(cloud.points_m.len(), beams.len());
    for p in &cloud.points_m {
        let enu = origin
            + to_enu(DVec3::new(
                f64::from(p[0]),
                f64::from(p[1]),
                f64::from(p[2]),
            ));
        let on_face = (enu.x.abs() - 4.0).abs() < 1e-5 || (enu.y.abs() - 3.0).abs() < 1e-5;
        assert!(on_face, "{enu} is on no wall");
    }
}

#[test]
fn a_noisy_image_is_the_same_for_a_seed_and_another_for_another() {
    let camera = device("preset = \"depth-160x120\"");
    let beams = camera.beams();
    let to_enu = camera_to_enu(DVec3::new(0.1, 1.0, 0.0));
    let dirs: Vec<DVec3> = beams.iter().map(|b| to_enu(b[0])).collect();
    let hits = cast(&BOXES, DVec3::new(0.0, 0.0, 5.0), &dirs, 10.0);
    let image = |seed: u64, k: u64| {
        let (truths, readings) = read(&camera, &beams, &hits, (seed, 5), (k, 1.0 / 30.0));
        let mut image = DepthImage::default();
        image.fill(
            160,
            120,
            &readings,
            &truths,
            &vec![Segment::default(); beams.len()],
        );
        image
            .depth_m
            .iter()
            .map(|d| d.to_bits())
            .collect::<Vec<u32>>()
    };
    assert_eq!(image(1, 10), image(1, 10));
    assert_ne!(image(1, 10), image(2, 10));
    assert_ne!(image(1, 10), image(1, 11));
    // About 2% of the pixels are invalid (NaN), as the preset says.
    let invalid = image(1, 10)
        .iter()
        .filter(|b| f32::from_bits(**b).is_nan())
        .count();
    assert!(
        (250..=520).contains(&invalid),
        "{invalid} invalid of 19,200"
    );
}

#[test]
fn bad_images_and_lidars_are_errors_naming_the_field() {
    for (text, field) in [
        ("preset = \"depth-160x120\"\nimage_px = [0, 0]", "image_px"),
        (
            "preset = \"depth-160x120\"\nimage_px = [100000, 100000]",
            "image_px",
        ),
        (
            "preset = \"depth-160x120\"\nfov_deg = [0.0, 58.0]",
            "fov_deg",
        ),
        (
            "preset = \"depth-160x120\"\nfov_deg = [180.0, 58.0]",
            "fov_deg",
        ),
        (
            "preset = \"depth-160x120\"\nfov_deg = [87.0, nan]",
            "fov_deg",
        ),
        (
            "preset = \"depth-160x120\"\nstep_deg = [1.0, 1.0]",
            "step_deg",
        ),
        (
            "preset = \"depth-160x120\"\nrange_m = [nan, 10.0]",
            "range_m",
        ),
        ("preset = \"velodyne-vlp16\"\nchannels = 0", "channels"),
        ("preset = \"velodyne-vlp16\"\nchannels = 100000", "channels"),
        (
            "preset = \"velodyne-vlp16\"\nfov_deg = [360.0, 0.0]",
            "channels",
        ),
        ("preset = \"adsb-1090es\"\nimage_px = [10, 10]", "image_px"),
    ] {
        let spec: DeviceSpec = toml::from_str(text).unwrap();
        let err = spec.build().expect_err(text).to_string();
        assert!(err.contains(field), "{text}: {err}");
    }
    // A value that is not a pixel count at all is the parser's error, naming the field.
    let err = toml::from_str::<DeviceSpec>("image_px = [-1, 5]").unwrap_err();
    assert!(err.to_string().contains("image_px"), "{err}");
}

#[test]
fn a_crowded_scene_gives_every_depth_of_the_scalar_cast_near_and_far() {
    // 144 posts on a 12 x 12 grid 4 m apart: a chunk of rays meets more of them than it tries
    // one by one, so far rays go through the tree; near and far, the depths are the cast's.
    let posts: Vec<([f64; 3], [f64; 3])> = (0..144)
        .map(|k| {
            let (x, y) = (
                f64::from(k % 12) * 4.0 - 22.0,
                f64::from(k / 12) * 4.0 + 3.0,
            );
            let h = 2.0 + f64::from((k * 7) % 5);
            ([x, y, 0.0], [x + 0.8, y + 0.6, h])
        })
        .collect();
    let camera = device(
        "kind = \"range\"\nrate_hz = 30.0\nimage_px = [80, 60]\nfov_deg = [120.0, 60.0]\nrange_m = [0.1, 200.0]",
    );
    let origin = DVec3::new(0.3, 0.0, 2.5);
    let to_enu = camera_to_enu(DVec3::new(0.05, 1.0, -0.1));
    let beams = camera.beams();
    let dirs: Vec<DVec3> = beams.iter().map(|b| to_enu(b[0])).collect();
    let hits = cast(&posts, origin, &dirs, 200.0);
    let (mut seen, mut far) = (0, 0);
    for (k, (dir, got)) in dirs.iter().zip(&hits).enumerate() {
        let want = scalar_cast(&posts, origin, *dir, 200.0);
        match (got, want) {
            (Some((o, d)), Some((t, b))) => {
                assert!(
                    (d - t).abs() < 1e-6,
                    "ray {k}: {d} m ({o:?}), want {t} m (post {b}) along {dir} from {origin}"
                );
                assert_eq!(*o, ObstacleRef::Static(b as u32), "ray {k}");
                seen += 1;
                far += usize::from(t > 20.0);
            }
            (None, None) => {}
            _ => panic!("ray {k}: {got:?}, want {want:?}"),
        }
    }
    assert!(
        seen > 1_000 && far > 100,
        "{seen} rays hit, {far} beyond 20 m"
    );
}
