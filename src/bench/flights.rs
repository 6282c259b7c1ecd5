//! The bench's flight set: deterministic flights built from the scene's own content (its
//! streets, towers, concave buildings, thin obstacles and terrain), so that the same command
//! gives the same flights on any machine, and a user's own scene gets flights of the same
//! families.
//!
//! A flight's description says what it was built to do ("passes 2.0 m from b17's east
//! face"); the bench's truth is the `reference` mode, never the description.

use std::f64::consts::PI;

use glam::{DQuat, DVec3};

use crate::geo::LocalTangentPlane;
use crate::pipeline::{BodyKey, BodyPose, BodySource, DynamicBody};
use crate::scene::geometry::GeometrySource;
use crate::scene::{Aabb64, Kind, Scene};
use crate::world::{Attitude, TrackSample};

/// Every flight's clock starts here, seconds (any value would do; not 0, so that a clock
/// that starts at 0 is not special).
const T0_S: f64 = 1000.0;

/// Another aircraft on a straight course.
#[derive(Debug, Clone, PartialEq)]
pub struct Traffic {
    /// Id in events.
    pub id: std::sync::Arc<str>,
    /// What it is (threat class and model).
    pub kind: Kind,
    /// Where it is at the flight's first sample, scene ENU metres.
    pub start_enu_m: DVec3,
    /// Its constant velocity, ENU m/s.
    pub velocity_enu_mps: DVec3,
}

impl Traffic {
    /// Its pose at `t_s` (the flights' clock).
    pub fn pose_at(&self, t_s: f64) -> BodyPose {
        BodyPose {
            position_enu_m: self.start_enu_m + self.velocity_enu_mps * (t_s - T0_S),
            enu_from_body: level_frd(self.velocity_enu_mps),
        }
    }

    /// The moving obstacle between two sample times; `index` numbers it in its flight.
    pub fn body(&self, scene: &Scene, index: u32, t_before_s: f64, t_now_s: f64) -> DynamicBody {
        DynamicBody {
            key: BodyKey {
                source: BodySource::Scripted(index),
                generation: 0,
            },
            id: self.id.clone(),
            kind: self.kind,
            threat: scene.threat_of(self.kind),
            geometry_index: scene.kind_model(self.kind),
            previous: self.pose_at(t_before_s),
            current: self.pose_at(t_now_s),
            speed_mps: self.velocity_enu_mps.length(),
        }
    }
}

/// One bench flight.
#[derive(Debug, Clone, PartialEq)]
pub struct Flight {
    /// Short unique name (`near-miss-2m`).
    pub name: String,
    /// What it was built to do.
    pub what: String,
    /// Telemetry rate, Hz.
    pub rate_hz: f64,
    /// Ground speed, m/s (the largest, for terrain following).
    pub speed_mps: f64,
    /// The vehicle's samples.
    pub samples: Vec<TrackSample>,
    /// Other aircraft.
    pub traffic: Vec<Traffic>,
}

/// Rotation from a level body flying along `velocity` (nose east when still) to ENU.
fn level_frd(velocity_enu_mps: DVec3) -> DQuat {
    let heading = if velocity_enu_mps.truncate().length() > 1e-9 {
        velocity_enu_mps.y.atan2(velocity_enu_mps.x)
    } else {
        0.0
    };
    DQuat::from_rotation_z(heading) * DQuat::from_rotation_x(PI)
}

/// Samples of `position(t)` (t in seconds from the start) for `duration_s` at `rate_hz`, level,
/// nose along the velocity.
fn sampled(
    plane: &LocalTangentPlane,
    rate_hz: f64,
    duration_s: f64,
    position: impl Fn(f64) -> DVec3,
) -> Vec<TrackSample> {
    sampled_banked(plane, rate_hz, duration_s, position, |_| 0.0)
}

/// As [`sampled`], the nose also pitched along a climb and the body rolled by `roll_rad(t)`.
fn sampled_banked(
    plane: &LocalTangentPlane,
    rate_hz: f64,
    duration_s: f64,
    position: impl Fn(f64) -> DVec3,
    roll_rad: impl Fn(f64) -> f64,
) -> Vec<TrackSample> {
    let n = (duration_s * rate_hz).round().max(1.0) as usize;
    let h = 0.25 / rate_hz;
    (0..=n)
        .map(|i| {
            let t = i as f64 / rate_hz;
            let p = position(t);
            // Central difference inside the flight, one-sided at its ends (the path is held
            // outside [0, duration], which would halve the speed there).
            let (t0, t1) = ((t - h).max(0.0), (t + h).min(duration_s));
            let velocity = if t1 > t0 {
                (position(t1) - position(t0)) / (t1 - t0)
            } else {
                DVec3::ZERO
            };
            TrackSample {
                t_s: T0_S + t,
                time_boot_ms: (5_000.0 + t * 1000.0).round() as u32,
                position: plane.geodetic_from_enu_m(p),
                position_enu_m: p,
                velocity_enu_mps: velocity,
                attitude: Attitude {
                    time_boot_ms: (5_000.0 + t * 1000.0).round() as u32,
                    // Pitch up along a climb (about FRD y), then roll (about FRD x).
                    enu_from_frd: level_frd(velocity)
                        * DQuat::from_rotation_y(velocity.z.atan2(velocity.truncate().length()))
                        * DQuat::from_rotation_x(roll_rad(t)),
                    body_rates_radps: DVec3::ZERO,
                },
            }
        })
        .collect()
}

/// A straight flight from `a` to `b`.
pub(crate) fn line_samples(
    plane: &LocalTangentPlane,
    a: DVec3,
    b: DVec3,
    speed_mps: f64,
    rate_hz: f64,
) -> Vec<TrackSample> {
    let duration_s = (b - a).length() / speed_mps;
    let velocity = (b - a) / duration_s;
    sampled(plane, rate_hz, duration_s, |t| {
        a + velocity * t.clamp(0.0, duration_s)
    })
}

/// Half extents (ENU) of a model flying level along `velocity`.
fn half_extents(scene: &Scene, geometry_index: usize, velocity_enu_mps: DVec3) -> (DVec3, DVec3) {
    let placement = crate::scene::Placement {
        position_enu_m: DVec3::ZERO,
        enu_from_local: level_frd(velocity_enu_mps),
    };
    let b = placement.enu_aabb(&scene.geometries[geometry_index].local_aabb);
    (-b.min, b.max)
}

/// Axis-aligned blocks of a static obstacle, scene ENU metres (None when it is rotated or not
/// made of boxes).
fn enu_blocks(scene: &Scene, index: usize) -> Option<Vec<Aabb64>> {
    let o = &scene.obstacles[index];
    if o.placement.enu_from_local.angle_between(DQuat::IDENTITY) > 1e-9 {
        return None;
    }
    let at = |min: glam::Vec3, max: glam::Vec3| {
        Aabb64::new(
            o.placement.position_enu_m + min.as_dvec3(),
            o.placement.position_enu_m + max.as_dvec3(),
        )
    };
    match &o.geometry.source {
        GeometrySource::Cuboid { min, max } => Some(vec![at(*min, *max)]),
        GeometrySource::Blocks { blocks, .. } => {
            Some(blocks.iter().map(|(min, max)| at(*min, *max)).collect())
        }
        _ => None,
    }
}

/// Static obstacles other than terrain, nearest the scene's centre first.
fn by_distance(scene: &Scene, centre: DVec3) -> Vec<usize> {
    let mut order: Vec<usize> = (0..scene.obstacles.len())
        .filter(|&i| !scene.obstacles[i].geometry.is_terrain())
        .collect();
    let key = |i: &usize| {
        let c = scene.obstacles[*i].aabb_enu_m.centre();
        ((c.x - centre.x).hypot(c.y - centre.y) * 1000.0) as i64
    };
    order.sort_by_key(|i| (key(i), *i));
    order
}

/// The gap between two axis-aligned rectangles in one plane (0 when they overlap).
fn rect_gap(a: [f64; 4], b: [f64; 4]) -> f64 {
    let gx = (b[0] - a[2]).max(a[0] - b[2]).max(0.0);
    let gy = (b[1] - a[3]).max(a[1] - b[3]).max(0.0);
    gx.hypot(gy)
}

/// The flight set for `scene`: crossings, low passes along streets, near misses beside
/// towers, grazing passes through concave obstacles, fast movers, traffic, hovering, and over
/// terrain: terrain following and flight into a ridge. Families the scene has nothing for
/// (no terrain, no concave obstacle) are left out.
pub fn flight_set(scene: &Scene) -> Vec<Flight> {
    let plane = LocalTangentPlane::new(scene.origin);
    let bounds = scene.bounds_enu_m();
    let centre = DVec3::new(0.0, 0.0, 0.0).clamp(bounds.min, bounds.max);
    let has_terrain = scene.obstacles.iter().any(|o| o.geometry.is_terrain());
    let ground = |x: f64, y: f64| {
        if has_terrain {
            scene.ground_height_enu_m(x, y).unwrap_or(0.0)
        } else {
            0.0
        }
    };
    let tallest_m = scene
        .obstacles
        .iter()
        .filter(|o| !o.geometry.is_terrain())
        .map(|o| o.aabb_enu_m.max.z - ground(o.aabb_enu_m.centre().x, o.aabb_enu_m.centre().y))
        .fold(0.0, f64::max);
    let vehicle = scene.vehicle_model(1);
    let mut flights = Vec::new();
    let mut add = |name: String, what: String, rate_hz: f64, speed_mps: f64, samples, traffic| {
        flights.push(Flight {
            name,
            what,
            rate_hz,
            speed_mps,
            samples,
            traffic,
        });
    };
    // Half the span crossed by the crossings, metres.
    let half = 600.0_f64
        .min(0.5 * (bounds.max.x - bounds.min.x))
        .min(0.5 * (bounds.max.y - bounds.min.y))
        .max(50.0);
    let at = |x: f64, y: f64, agl: f64| DVec3::new(x, y, ground(x, y) + agl);

    // Crossings at several heights, headings and rates.
    for (name, a, b, speed, rate) in [
        (
            "cross-ew-40m",
            at(-half, 50.0, 40.0),
            at(half, 50.0, 40.0),
            15.0,
            10.0,
        ),
        (
            "cross-ns-120m",
            at(-50.0, -half, 120.0),
            at(-50.0, half, 120.0),
            20.0,
            10.0,
        ),
        (
            "cross-diag-60m",
            at(-half, -half, 60.0),
            at(half, half, 60.0),
            20.0,
            50.0,
        ),
    ] {
        let (a, b) = (a + centre.with_z(0.0), b + centre.with_z(0.0));
        let a = a.with_z(a.z.max(b.z));
        let b = b.with_z(a.z);
        add(
            name.into(),
            format!("level crossing at z = {:.0} m (scene ENU)", a.z),
            rate,
            speed,
            line_samples(&plane, a, b, speed, rate),
            vec![],
        );
    }
    let clear_z = bounds.max.z + 30.0;
    add(
        "cross-above-all".into(),
        format!("level crossing at {clear_z:.0} m, 30 m above everything"),
        5.0,
        25.0,
        line_samples(
            &plane,
            DVec3::new(centre.x - half, centre.y + 10.0, clear_z),
            DVec3::new(centre.x + half, centre.y + 10.0, clear_z),
            25.0,
            5.0,
        ),
        vec![],
    );

    // Low passes along clear lines (streets) and one through a raised obstacle (a skybridge).
    // The vehicle's largest half extent across its path.
    let hv_side = {
        let (lo, hi) = half_extents(scene, vehicle, DVec3::X);
        lo.max(hi).y.max(lo.max(hi).z)
    };
    if !has_terrain {
        for (name, along_x, agl, speed, rate) in [
            ("low-street-ew-10m", true, 10.0, 10.0, 10.0),
            ("low-street-ns-15m", false, 15.0, 10.0, 5.0),
        ] {
            if let Some(offset) = clear_line(scene, centre, along_x, agl, half, hv_side + 2.0) {
                let (a, b) = street_ends(centre, along_x, offset, half, agl);
                add(
                    name.into(),
                    format!("low pass {agl:.0} m up along a clear street line"),
                    rate,
                    speed,
                    line_samples(&plane, a, b, speed, rate),
                    vec![],
                );
            }
        }
    }

    // Near misses beside the faces of towers.
    let order = by_distance(scene, centre);
    let mut towers = order.iter().copied().filter(|&i| {
        let o = &scene.obstacles[i];
        let size = o.aabb_enu_m.max - o.aabb_enu_m.min;
        enu_blocks(scene, i).is_some() && size.x >= 4.0 && size.y >= 4.0
    });
    for gap_m in [0.5, 1.0, 2.0, 5.0] {
        let Some(i) = towers.next() else { break };
        let blocks = enu_blocks(scene, i).unwrap_or_default();
        // The block reaching farthest east; fly north past its face at mid height.
        let Some(face) = blocks
            .iter()
            .copied()
            .max_by(|a, b| a.max.x.total_cmp(&b.max.x))
        else {
            continue;
        };
        let (lo, _) = half_extents(scene, vehicle, DVec3::Y);
        let x = face.max.x + gap_m + lo.x;
        let z = 0.5 * (face.min.z + face.max.z);
        let id = &scene.obstacles[i].id;
        add(
            format!("near-miss-{gap_m}m"),
            format!("passes {gap_m} m from {id}'s east face (box against box)"),
            10.0,
            8.0,
            line_samples(
                &plane,
                DVec3::new(x, face.min.y - 3.0, z),
                DVec3::new(x, face.max.y + 3.0, z),
                8.0,
                10.0,
            ),
            vec![],
        );
    }
    // Hovering beside a tower, 3 m off its north face.
    if let Some(i) = towers.next() {
        let b = scene.obstacles[i].aabb_enu_m;
        let (_, hi) = half_extents(scene, vehicle, DVec3::ZERO);
        let p = DVec3::new(
            b.centre().x,
            b.max.y + 3.0 + hi.y.max(hi.x),
            b.min.z + 0.5 * (b.max.z - b.min.z),
        );
        add(
            "hover-3m".into(),
            format!(
                "hovers 3 m off {}'s north face for 10 s",
                scene.obstacles[i].id
            ),
            50.0,
            0.0,
            sampled(&plane, 50.0, 10.0, |_| p),
            vec![],
        );
    }

    // Grazing passes through concave obstacles: the box says hit, the shape says clear.
    let mut used = Vec::new();
    for target_m in [1.0, 2.0, 3.0] {
        if let Some((i, a, b, clearance)) =
            concave_pass(scene, &order, target_m, (hv_side, hv_side), &used)
        {
            used.push(i);
            let id = &scene.obstacles[i].id;
            add(
                format!("graze-concave-{target_m}m"),
                format!("through {id}'s bounding box, {clearance:.2} m clear of its shape (box against box)"),
                10.0,
                6.0,
                line_samples(&plane, a, b, 6.0, 10.0),
                vec![],
            );
        }
    }

    // Fast movers: through the thinnest obstacle near the centre, and airliner speeds.
    if let Some((i, a, b)) = thin_pass(scene, &order) {
        let id = scene.obstacles[i].id.clone();
        for (speed, rate) in [(100.0, 10.0), (30.0, 5.0)] {
            add(
                format!("fast-{speed}-thin-{rate}hz"),
                format!(
                    "{speed} m/s through {id} (thinnest obstacle near the centre) at {rate} Hz"
                ),
                rate,
                speed,
                line_samples(&plane, a, b, speed, rate),
                vec![],
            );
        }
    }
    for rate in [50.0, 5.0] {
        let z = ground(centre.x, centre.y) + 150.0_f64.min(0.7 * tallest_m.max(10.0));
        add(
            format!("fast-250-{rate}hz"),
            format!("250 m/s level at z = {z:.0} m across the centre at {rate} Hz"),
            rate,
            250.0,
            line_samples(
                &plane,
                DVec3::new(centre.x - 2.0 * half, centre.y - 30.0, z),
                DVec3::new(centre.x + 2.0 * half, centre.y - 30.0, z),
                250.0,
                rate,
            ),
            vec![],
        );
    }

    // Traffic on crossing courses, above everything static.
    let z = clear_z + 20.0;
    let own_v = DVec3::new(15.0, 0.0, 0.0);
    let start = DVec3::new(centre.x - 300.0, centre.y, z);
    let meet_s = 20.0;
    let meet = start + own_v * meet_s;
    let own = line_samples(&plane, start, start + own_v * 40.0, 15.0, 10.0);
    let airliner_v = DVec3::new(0.0, 70.0, 0.0);
    let (_, own_hi) = half_extents(scene, vehicle, own_v);
    let (airliner_lo, _) = half_extents(scene, scene.kind_model(Kind::A320), airliner_v);
    let dji_v = DVec3::new(-12.0, 0.0, 0.0);
    let (dji_lo, _) = half_extents(scene, scene.kind_model(Kind::Dji), dji_v);
    for (name, what, traffic) in [
        (
            "traffic-a320-collision",
            "an A320 at 70 m/s crosses the vehicle's course at the vehicle's height, on time",
            Traffic {
                id: "a320-crossing".into(),
                kind: Kind::A320,
                start_enu_m: meet - airliner_v * meet_s,
                velocity_enu_mps: airliner_v,
            },
        ),
        (
            "traffic-a320-above-5m",
            "an A320 at 70 m/s crosses 5 m above the vehicle (box against box)",
            Traffic {
                id: "a320-above".into(),
                kind: Kind::A320,
                start_enu_m: meet - airliner_v * meet_s
                    + DVec3::Z * (own_hi.z + airliner_lo.z + 5.0),
                velocity_enu_mps: airliner_v,
            },
        ),
        (
            "traffic-dji-headon-2m",
            "a DJI-class quad head-on, passing 2 m to the side (box against box)",
            Traffic {
                id: "dji-headon".into(),
                kind: Kind::Dji,
                start_enu_m: meet - dji_v * meet_s + DVec3::Y * (own_hi.y + dji_lo.y + 2.0),
                velocity_enu_mps: dji_v,
            },
        ),
    ] {
        add(
            name.into(),
            what.into(),
            10.0,
            15.0,
            own.clone(),
            vec![traffic],
        );
    }

    // Turning, climbing and rolling near the obstacles: the sweeps turn (screw motion).
    let turn_radius = 60.0;
    let turn_speed = 15.0;
    let orbit_s = 2.0 * PI * turn_radius / turn_speed;
    let around = |r: f64, t: f64, omega: f64| {
        DVec3::new(
            centre.x + r * (omega * t).cos(),
            centre.y + r * (omega * t).sin(),
            0.0,
        )
    };
    add(
        "turn-orbit-40m".into(),
        format!("a banked (25 deg) orbit of {turn_radius} m radius around the centre, 40 m up"),
        10.0,
        turn_speed,
        sampled_banked(
            &plane,
            10.0,
            orbit_s,
            |t| {
                let p = around(turn_radius, t, turn_speed / turn_radius);
                p.with_z(ground(p.x, p.y) + 40.0)
            },
            |_| 25f64.to_radians(),
        ),
        vec![],
    );
    add(
        "climb-spiral".into(),
        "a climbing spiral of 40 m radius from 10 m to 130 m up, banked 30 deg".into(),
        10.0,
        12.0,
        sampled_banked(
            &plane,
            10.0,
            60.0,
            |t| {
                let p = around(40.0, t, 12.0 / 40.0);
                p.with_z(ground(centre.x, centre.y) + 10.0 + 2.0 * t)
            },
            |_| 30f64.to_radians(),
        ),
        vec![],
    );
    add(
        "roll-weave".into(),
        "a weave across the crossing line (80 m amplitude) at 30 m up, rolling +-35 deg, 20 Hz"
            .into(),
        20.0,
        15.0,
        sampled_banked(
            &plane,
            20.0,
            2.0 * half / 15.0,
            |t| {
                let x = centre.x - half + 15.0 * t;
                let y = centre.y + 80.0 * (t * 0.3).sin();
                DVec3::new(x, y, ground(x, y) + 30.0)
            },
            |t| 35f64.to_radians() * (t * 0.3).cos(),
        ),
        vec![],
    );
    // Vehicle against vehicle: a quad like this one, head-on at the same height.
    let quad_v = DVec3::new(-10.0, 0.0, 0.0);
    add(
        "vehicle-quad-headon".into(),
        "another quadcopter head-on at 10 m/s, same height: a vehicle-vehicle collision".into(),
        10.0,
        15.0,
        own.clone(),
        vec![Traffic {
            id: "quad-headon".into(),
            kind: Kind::Dji,
            start_enu_m: meet - quad_v * meet_s,
            velocity_enu_mps: quad_v,
        }],
    );

    // Terrain: following it, and flying level into it.
    if has_terrain {
        let (x0, x1, y) = (
            centre.x - 2.0 * half,
            centre.x + 2.0 * half,
            centre.y + 200.0,
        );
        for (name, agl, speed, rate) in [
            ("terrain-follow-30m", 30.0, 20.0, 10.0),
            ("terrain-follow-5m", 5.0, 15.0, 5.0),
        ] {
            let duration = (x1 - x0) / speed;
            add(
                name.into(),
                format!("follows the terrain {agl} m above it (at the samples) at {speed} m/s"),
                rate,
                speed,
                sampled(&plane, rate, duration, |t| {
                    let x = x0 + speed * t.clamp(0.0, duration);
                    DVec3::new(x, y, ground(x, y) + agl)
                }),
                vec![],
            );
        }
        // Level at 40 m above the start until the ground rises through that height.
        let (x0, y) = (centre.x - 2.0 * half, centre.y - 400.0);
        let z = ground(x0, y) + 40.0;
        let mut x1 = x0 + 50.0;
        while x1 < x0 + 4.0 * half && ground(x1, y) < z + 20.0 {
            x1 += 10.0;
        }
        add(
            "terrain-cfit".into(),
            format!("level at {z:.0} m into rising ground (controlled flight into terrain)"),
            10.0,
            40.0,
            line_samples(
                &plane,
                DVec3::new(x0, y, z),
                DVec3::new(x1 + 50.0, y, z),
                40.0,
                10.0,
            ),
            vec![],
        );
    }
    flights
}

/// Offset (across the line) of a clear line `agl` metres up through `centre`, along x or y,
/// `half` each way, at least `margin_m` from every obstacle's box.
fn clear_line(
    scene: &Scene,
    centre: DVec3,
    along_x: bool,
    agl_m: f64,
    half: f64,
    margin_m: f64,
) -> Option<f64> {
    (0..400)
        .map(|k| if k % 2 == 0 { k / 2 } else { -(k / 2 + 1) })
        .find_map(|k| {
            let offset = f64::from(k) * 2.0;
            let (a, b) = street_ends(centre, along_x, offset, half, agl_m);
            let path = Aabb64::new(a.min(b), a.max(b)).inflated(margin_m);
            (!scene
                .obstacles
                .iter()
                .any(|o| o.aabb_enu_m.intersects(&path)))
            .then_some(offset)
        })
}

fn street_ends(centre: DVec3, along_x: bool, offset: f64, half: f64, agl_m: f64) -> (DVec3, DVec3) {
    if along_x {
        (
            DVec3::new(centre.x - half, centre.y + offset, agl_m),
            DVec3::new(centre.x + half, centre.y + offset, agl_m),
        )
    } else {
        (
            DVec3::new(centre.x + offset, centre.y - half, agl_m),
            DVec3::new(centre.x + offset, centre.y + half, agl_m),
        )
    }
}

/// A level line through obstacle `i`'s bounding box, along x or y, that clears its blocks by
/// about `target_m` (the vehicle's half extents `(side, up)` included): the obstacle nearest
/// the centre with such a line, not in `used`. Returns the obstacle, the line's ends and the
/// clearance.
fn concave_pass(
    scene: &Scene,
    order: &[usize],
    target_m: f64,
    vehicle_half_m: (f64, f64),
    used: &[usize],
) -> Option<(usize, DVec3, DVec3, f64)> {
    for &i in order.iter().take(400) {
        if used.contains(&i) {
            continue;
        }
        let Some(blocks) = enu_blocks(scene, i) else {
            continue;
        };
        if blocks.len() < 2 {
            continue;
        }
        let bb = scene.obstacles[i].aabb_enu_m;
        for along_x in [false, true] {
            // The cross-section: (across, up).
            let across = |b: &Aabb64| {
                if along_x {
                    (b.min.y, b.max.y)
                } else {
                    (b.min.x, b.max.x)
                }
            };
            let (lo, hi) = across(&bb);
            let mut best: Option<(f64, f64, f64)> = None;
            let mut u = lo + 0.25;
            while u < hi {
                let mut z = bb.min.z + vehicle_half_m.1 + 0.25;
                while z < bb.max.z - vehicle_half_m.1 {
                    let me = [
                        u - vehicle_half_m.0,
                        z - vehicle_half_m.1,
                        u + vehicle_half_m.0,
                        z + vehicle_half_m.1,
                    ];
                    let clearance = blocks
                        .iter()
                        .map(|b| {
                            let (a0, a1) = across(b);
                            rect_gap(me, [a0, b.min.z, a1, b.max.z])
                        })
                        .fold(f64::INFINITY, f64::min);
                    if (clearance - target_m).abs() < 0.3
                        && best.is_none_or(|(c, _, _)| {
                            (clearance - target_m).abs() < (c - target_m).abs()
                        })
                    {
                        best = Some((clearance, u, z));
                    }
                    z += 0.5;
                }
                u += 0.5;
            }
            if let Some((clearance, u, z)) = best {
                let (a, b) = if along_x {
                    (
                        DVec3::new(bb.min.x - 15.0, u, z),
                        DVec3::new(bb.max.x + 15.0, u, z),
                    )
                } else {
                    (
                        DVec3::new(u, bb.min.y - 15.0, z),
                        DVec3::new(u, bb.max.y + 15.0, z),
                    )
                };
                return Some((i, a, b, clearance));
            }
        }
    }
    None
}

/// A level line through the middle of the thinnest obstacle (horizontally) among the 200 nearest
/// the centre, across its thin side.
fn thin_pass(scene: &Scene, order: &[usize]) -> Option<(usize, DVec3, DVec3)> {
    let i = order.iter().take(200).copied().min_by(|&a, &b| {
        let thin = |i: usize| {
            let s = scene.obstacles[i].aabb_enu_m.max - scene.obstacles[i].aabb_enu_m.min;
            s.x.min(s.y)
        };
        thin(a).total_cmp(&thin(b)).then(a.cmp(&b))
    })?;
    let b = scene.obstacles[i].aabb_enu_m;
    let c = b.centre();
    let size = b.max - b.min;
    let (a, e) = if size.x < size.y {
        (
            DVec3::new(b.min.x - 100.0, c.y, c.z),
            DVec3::new(b.max.x + 100.0, c.y, c.z),
        )
    } else {
        (
            DVec3::new(c.x, b.min.y - 100.0, c.z),
            DVec3::new(c.x, b.max.y + 100.0, c.z),
        )
    };
    Some((i, a, e))
}
