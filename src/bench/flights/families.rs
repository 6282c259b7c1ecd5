//! The flight set's families, each built from the `Setting` and appended in the set's order:
//! crossings, street passes, tower passes, concave grazes, fast movers, traffic, manoeuvres,
//! a vehicle head-on, terrain.

use std::f64::consts::PI;

use glam::DVec3;

use super::search::{clear_line, concave_pass, enu_blocks, street_ends, thin_pass};
use super::{half_extents, line_samples, sampled, sampled_banked, Flight, Setting, Traffic};
use crate::scene::Kind;
use crate::world::TrackSample;

/// Crossings at several heights, headings and rates, and one 30 m above everything.
pub(super) fn crossings(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let half = s.half;
    for (name, a, b, speed, rate) in [
        (
            "cross-ew-40m",
            s.at(-half, 50.0, 40.0),
            s.at(half, 50.0, 40.0),
            15.0,
            10.0,
        ),
        (
            "cross-ns-120m",
            s.at(-50.0, -half, 120.0),
            s.at(-50.0, half, 120.0),
            20.0,
            10.0,
        ),
        (
            "cross-diag-60m",
            s.at(-half, -half, 60.0),
            s.at(half, half, 60.0),
            20.0,
            50.0,
        ),
    ] {
        let (a, b) = (a + s.centre.with_z(0.0), b + s.centre.with_z(0.0));
        let a = a.with_z(a.z.max(b.z));
        let b = b.with_z(a.z);
        out.push(Flight::alone(
            name.into(),
            format!("level crossing at z = {:.0} m (scene ENU)", a.z),
            rate,
            speed,
            line_samples(&s.plane, a, b, speed, rate),
        ));
    }
    let (centre, clear_z) = (s.centre, s.clear_z);
    out.push(Flight::alone(
        "cross-above-all".into(),
        format!("level crossing at {clear_z:.0} m, 30 m above everything"),
        5.0,
        25.0,
        line_samples(
            &s.plane,
            DVec3::new(centre.x - half, centre.y + 10.0, clear_z),
            DVec3::new(centre.x + half, centre.y + 10.0, clear_z),
            25.0,
            5.0,
        ),
    ));
}

/// Low passes along clear lines (streets), for scenes without terrain.
pub(super) fn street_passes(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let margin_m = s.vehicle_half_side_m() + 2.0;
    for (name, along_x, agl, speed, rate) in [
        ("low-street-ew-10m", true, 10.0, 10.0, 10.0),
        ("low-street-ns-15m", false, 15.0, 10.0, 5.0),
    ] {
        if let Some(offset) = clear_line(s.scene, s.centre, along_x, agl, s.half, margin_m) {
            let (a, b) = street_ends(s.centre, along_x, offset, s.half, agl);
            out.push(Flight::alone(
                name.into(),
                format!("low pass {agl:.0} m up along a clear street line"),
                rate,
                speed,
                line_samples(&s.plane, a, b, speed, rate),
            ));
        }
    }
}

/// Near misses beside the east faces of the towers nearest the centre (0.5 to 5 m), then
/// hovering 3 m off the next tower's north face.
pub(super) fn tower_passes(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let scene = s.scene;
    let mut towers = s.order.iter().copied().filter(|&i| {
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
        let (lo, _) = half_extents(scene, s.vehicle, DVec3::Y);
        let x = face.max.x + gap_m + lo.x;
        let z = 0.5 * (face.min.z + face.max.z);
        let id = &scene.obstacles[i].id;
        out.push(Flight::alone(
            format!("near-miss-{gap_m}m"),
            format!("passes {gap_m} m from {id}'s east face (box against box)"),
            10.0,
            8.0,
            line_samples(
                &s.plane,
                DVec3::new(x, face.min.y - 3.0, z),
                DVec3::new(x, face.max.y + 3.0, z),
                8.0,
                10.0,
            ),
        ));
    }
    if let Some(i) = towers.next() {
        let b = scene.obstacles[i].aabb_enu_m;
        let (_, hi) = half_extents(scene, s.vehicle, DVec3::ZERO);
        let p = DVec3::new(
            b.centre().x,
            b.max.y + 3.0 + hi.y.max(hi.x),
            b.min.z + 0.5 * (b.max.z - b.min.z),
        );
        out.push(Flight::alone(
            "hover-3m".into(),
            format!(
                "hovers 3 m off {}'s north face for 10 s",
                scene.obstacles[i].id
            ),
            50.0,
            0.0,
            sampled(&s.plane, 50.0, 10.0, |_| p),
        ));
    }
}

/// Grazing passes through concave obstacles (1, 2 and 3 m clear of their blocks), each through
/// another obstacle: the box says hit, the shape says clear.
pub(super) fn concave_grazes(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let side = s.vehicle_half_side_m();
    let mut used = Vec::new();
    for target_m in [1.0, 2.0, 3.0] {
        if let Some((i, a, b, clearance)) =
            concave_pass(s.scene, &s.order, target_m, (side, side), &used)
        {
            used.push(i);
            let id = &s.scene.obstacles[i].id;
            out.push(Flight::alone(
                format!("graze-concave-{target_m}m"),
                format!("through {id}'s bounding box, {clearance:.2} m clear of its shape (box against box)"),
                10.0,
                6.0,
                line_samples(&s.plane, a, b, 6.0, 10.0),
            ));
        }
    }
}

/// Fast movers: through the thinnest obstacle near the centre, and at airliner speeds across
/// the centre.
pub(super) fn fast_movers(s: &Setting<'_>, out: &mut Vec<Flight>) {
    if let Some((i, a, b)) = thin_pass(s.scene, &s.order) {
        let id = s.scene.obstacles[i].id.clone();
        for (speed, rate) in [(100.0, 10.0), (30.0, 5.0)] {
            out.push(Flight::alone(
                format!("fast-{speed}-thin-{rate}hz"),
                format!(
                    "{speed} m/s through {id} (thinnest obstacle near the centre) at {rate} Hz"
                ),
                rate,
                speed,
                line_samples(&s.plane, a, b, speed, rate),
            ));
        }
    }
    let (centre, half) = (s.centre, s.half);
    let tallest_m = s.tallest_m();
    for rate in [50.0, 5.0] {
        let z = s.ground(centre.x, centre.y) + 150.0_f64.min(0.7 * tallest_m.max(10.0));
        out.push(Flight::alone(
            format!("fast-250-{rate}hz"),
            format!("250 m/s level at z = {z:.0} m across the centre at {rate} Hz"),
            rate,
            250.0,
            line_samples(
                &s.plane,
                DVec3::new(centre.x - 2.0 * half, centre.y - 30.0, z),
                DVec3::new(centre.x + 2.0 * half, centre.y - 30.0, z),
                250.0,
                rate,
            ),
        ));
    }
}

/// The vehicle's course for encounters with other aircraft: east at 15 m/s, 20 m above
/// everything static, for 40 s; the others meet it 20 s in.
pub(super) struct EncounterCourse {
    /// The vehicle's samples.
    own: Vec<TrackSample>,
    /// Its velocity, ENU m/s.
    own_v: DVec3,
    /// Where it is at the meeting, ENU metres.
    meet: DVec3,
    /// When, seconds from the start.
    meet_s: f64,
}

impl EncounterCourse {
    pub(super) fn of(s: &Setting<'_>) -> Self {
        let own_v = DVec3::new(15.0, 0.0, 0.0);
        let start = DVec3::new(s.centre.x - 300.0, s.centre.y, s.clear_z + 20.0);
        let meet_s = 20.0;
        EncounterCourse {
            own: line_samples(&s.plane, start, start + own_v * 40.0, 15.0, 10.0),
            own_v,
            meet: start + own_v * meet_s,
            meet_s,
        }
    }

    /// The vehicle on this course, meeting `traffic`.
    fn with(&self, name: &str, what: &str, traffic: Traffic) -> Flight {
        Flight {
            name: name.into(),
            what: what.into(),
            rate_hz: 10.0,
            speed_mps: 15.0,
            samples: self.own.clone(),
            traffic: vec![traffic],
        }
    }
}

/// Traffic on crossing courses, above everything static: an airliner on time, one 5 m above,
/// a small quadcopter head-on 2 m to the side.
pub(super) fn traffic(s: &Setting<'_>, course: &EncounterCourse, out: &mut Vec<Flight>) {
    let scene = s.scene;
    let (meet, meet_s) = (course.meet, course.meet_s);
    let airliner_v = DVec3::new(0.0, 70.0, 0.0);
    let (_, own_hi) = half_extents(scene, s.vehicle, course.own_v);
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
        out.push(course.with(name, what, traffic));
    }
}

/// Turning, climbing and rolling near the obstacles (the sweeps turn: screw motion): a banked
/// orbit, a climbing spiral, a rolling weave.
pub(super) fn manoeuvres(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let centre = s.centre;
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
    out.push(Flight::alone(
        "turn-orbit-40m".into(),
        format!("a banked (25 deg) orbit of {turn_radius} m radius around the centre, 40 m up"),
        10.0,
        turn_speed,
        sampled_banked(
            &s.plane,
            10.0,
            orbit_s,
            |t| {
                let p = around(turn_radius, t, turn_speed / turn_radius);
                p.with_z(s.ground(p.x, p.y) + 40.0)
            },
            |_| 25f64.to_radians(),
        ),
    ));
    out.push(Flight::alone(
        "climb-spiral".into(),
        "a climbing spiral of 40 m radius from 10 m to 130 m up, banked 30 deg".into(),
        10.0,
        12.0,
        sampled_banked(
            &s.plane,
            10.0,
            60.0,
            |t| {
                let p = around(40.0, t, 12.0 / 40.0);
                p.with_z(s.ground(centre.x, centre.y) + 10.0 + 2.0 * t)
            },
            |_| 30f64.to_radians(),
        ),
    ));
    let half = s.half;
    out.push(Flight::alone(
        "roll-weave".into(),
        "a weave across the crossing line (80 m amplitude) at 30 m up, rolling +-35 deg, 20 Hz"
            .into(),
        20.0,
        15.0,
        sampled_banked(
            &s.plane,
            20.0,
            2.0 * half / 15.0,
            |t| {
                let x = centre.x - half + 15.0 * t;
                let y = centre.y + 80.0 * (t * 0.3).sin();
                DVec3::new(x, y, s.ground(x, y) + 30.0)
            },
            |t| 35f64.to_radians() * (t * 0.3).cos(),
        ),
    ));
}

/// Vehicle against vehicle: a quad like this one, head-on at the same height.
pub(super) fn vehicle_head_on(course: &EncounterCourse, out: &mut Vec<Flight>) {
    let quad_v = DVec3::new(-10.0, 0.0, 0.0);
    out.push(course.with(
        "vehicle-quad-headon",
        "another quadcopter head-on at 10 m/s, same height: a vehicle-vehicle collision",
        Traffic {
            id: "quad-headon".into(),
            kind: Kind::Dji,
            start_enu_m: course.meet - quad_v * course.meet_s,
            velocity_enu_mps: quad_v,
        },
    ));
}

/// Over terrain: following it 30 m and 5 m above, and flying level into rising ground.
pub(super) fn terrain(s: &Setting<'_>, out: &mut Vec<Flight>) {
    let (centre, half) = (s.centre, s.half);
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
        out.push(Flight::alone(
            name.into(),
            format!("follows the terrain {agl} m above it (at the samples) at {speed} m/s"),
            rate,
            speed,
            sampled(&s.plane, rate, duration, |t| {
                let x = x0 + speed * t.clamp(0.0, duration);
                DVec3::new(x, y, s.ground(x, y) + agl)
            }),
        ));
    }
    // Level at 40 m above the start until the ground rises through that height.
    let (x0, y) = (centre.x - 2.0 * half, centre.y - 400.0);
    let z = s.ground(x0, y) + 40.0;
    let mut x1 = x0 + 50.0;
    while x1 < x0 + 4.0 * half && s.ground(x1, y) < z + 20.0 {
        x1 += 10.0;
    }
    out.push(Flight::alone(
        "terrain-cfit".into(),
        format!("level at {z:.0} m into rising ground (controlled flight into terrain)"),
        10.0,
        40.0,
        line_samples(
            &s.plane,
            DVec3::new(x0, y, z),
            DVec3::new(x1 + 50.0, y, z),
            40.0,
            10.0,
        ),
    ));
}
