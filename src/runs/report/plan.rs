//! The plan view of a row that is worth a look: from above, the vehicle's track as it sent it
//! (the results' `vehicle_track`), the intruder's as the row gave it, and the scene's
//! footprints near them (boxes and blocks as their rectangles, meshes as their upward-facing
//! triangles: a closed solid's plan outline, each clipped to the plan), the start of each
//! track, and the vehicle and the intruder where the row's first collision, else its closest
//! approach to traffic, happened. The intruder is drawn from [`AROUND_S`] before that moment
//! to as long after (all of it when there is no moment): an encounter's intruder crosses
//! kilometres, its closest approach is metres.

use glam::DVec3;
use plotters::prelude::*;

use crate::error::Result;
use crate::runs::report::charts::{failed, svg_of, FONT};
use crate::runs::summary::RowView;
use crate::runs::waypoints::parse_waypoints;
use crate::scene::geometry::GeometrySource;
use crate::scene::Scene;

/// A track: seconds on the row's timeline and a scene ENU position, metres.
pub type Track = Vec<(f64, DVec3)>;

/// A plan's side, pixels.
const SIDE_PX: u32 = 460;
/// Room around the tracks, metres.
const MARGIN_M: f64 = 25.0;
/// Footprint polygons drawn in one plan at most (a city's roofs near a long track).
const MAX_FOOTPRINTS: usize = 4000;
/// The intruder is drawn this long before and after the moment marked, seconds.
pub const AROUND_S: f64 = 15.0;

const VEHICLE: RGBColor = RGBColor(31, 119, 180);
const INTRUDER: RGBColor = RGBColor(255, 127, 14);
const MARK: RGBColor = RGBColor(214, 39, 40);

/// `t_s e_m n_m u_m; ...` as a track (`None` when absent or not a track).
pub fn track_of(text: Option<&str>) -> Option<Track> {
    let points = parse_waypoints(text?).ok()?;
    Some(
        points
            .iter()
            .map(|w| (w.t_s, DVec3::from_array(w.position_enu_m)))
            .collect(),
    )
}

/// Where `track` is at `t_s`, linearly between its points (its ends outside them).
pub fn at(track: &[(f64, DVec3)], t_s: f64) -> Option<DVec3> {
    let (first, last) = (track.first()?, track.last()?);
    if t_s <= first.0 {
        return Some(first.1);
    }
    if t_s >= last.0 {
        return Some(last.1);
    }
    let k = track.partition_point(|(t, _)| *t <= t_s);
    let ((t0, p0), (t1, p1)) = (track[k - 1], track[k]);
    let f = if t1 > t0 { (t_s - t0) / (t1 - t0) } else { 0.0 };
    Some(p0.lerp(p1, f))
}

/// `track` from `from_s` to `to_s`: its points between them and its positions at both ends.
pub fn between(track: &[(f64, DVec3)], from_s: f64, to_s: f64) -> Track {
    let inside = track
        .iter()
        .filter(|(t, _)| *t > from_s && *t < to_s)
        .copied();
    let ends = |t: f64| at(track, t).map(|p| (t.clamp(track[0].0, track[track.len() - 1].0), p));
    ends(from_s)
        .into_iter()
        .chain(inside)
        .chain(ends(to_s))
        .collect()
}

/// `polygon` clipped to the window `((e0, e1), (n0, n1))` (Sutherland-Hodgman, one side at a
/// time); empty when nothing of it is inside.
///
/// ```
/// use savsim::runs::report::plan::clip;
/// let square = vec![(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
/// let clipped = clip(&square, ((0.0, 5.0), (0.0, 5.0)));
/// assert_eq!(clipped.len(), 4);
/// assert!(clipped.iter().all(|&(e, n)| (0.0..=1.0).contains(&e) && (0.0..=1.0).contains(&n)));
/// assert!(clip(&square, ((2.0, 3.0), (2.0, 3.0))).is_empty());
/// ```
pub fn clip(polygon: &[(f64, f64)], window: ((f64, f64), (f64, f64))) -> Vec<(f64, f64)> {
    let ((e0, e1), (n0, n1)) = window;
    // Each side as: the coordinate it bounds (0 east, 1 north), its value, whether inside is above.
    let sides = [(0, e0, true), (0, e1, false), (1, n0, true), (1, n1, false)];
    let mut out = polygon.to_vec();
    for (axis, bound, above) in sides {
        let value = |p: (f64, f64)| if axis == 0 { p.0 } else { p.1 };
        let inside = |p: (f64, f64)| (value(p) >= bound) == above || value(p) == bound;
        let cross = |a: (f64, f64), b: (f64, f64)| {
            let f = (bound - value(a)) / (value(b) - value(a));
            (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1))
        };
        let input = std::mem::take(&mut out);
        for (i, &b) in input.iter().enumerate() {
            let a = input[(i + input.len() - 1) % input.len()];
            match (inside(a), inside(b)) {
                (true, true) => out.push(b),
                (true, false) => out.push(cross(a, b)),
                (false, true) => out.extend([cross(a, b), b]),
                (false, false) => {}
            }
        }
    }
    out
}

/// The plan's square window around `tracks` (east and north ranges, metres), equal in both.
fn window(tracks: &[&Track]) -> Option<((f64, f64), (f64, f64))> {
    let points = tracks.iter().flat_map(|t| t.iter().map(|(_, p)| *p));
    let (lo, hi) = points.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    );
    if !(lo.x.is_finite() && hi.x.is_finite()) {
        return None;
    }
    let half = ((hi.x - lo.x).max(hi.y - lo.y) / 2.0 + MARGIN_M).max(MARGIN_M);
    let (ce, cn) = ((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0);
    Some(((ce - half, ce + half), (cn - half, cn + half)))
}

/// The footprints of `scene`'s obstacles (terrain left out) that reach into `window`, as
/// polygons of east-north points; at most [`MAX_FOOTPRINTS`].
pub fn footprints(scene: &Scene, window: ((f64, f64), (f64, f64))) -> Vec<Vec<(f64, f64)>> {
    let ((e0, e1), (n0, n1)) = window;
    let mut out = Vec::new();
    for o in &scene.obstacles {
        let b = &o.aabb_enu_m;
        let near = b.max.x >= e0 && b.min.x <= e1 && b.max.y >= n0 && b.min.y <= n1;
        if !near || o.geometry.is_terrain() {
            continue;
        }
        let plan = |p: glam::Vec3| {
            let enu = o.placement.enu_from_local_point(p.as_dvec3());
            (enu.x, enu.y)
        };
        let rectangle = |min: glam::Vec3, max: glam::Vec3| {
            [
                (min.x, min.y),
                (max.x, min.y),
                (max.x, max.y),
                (min.x, max.y),
            ]
            .map(|(x, y)| plan(glam::Vec3::new(x, y, min.z)))
            .to_vec()
        };
        match &o.geometry.source {
            GeometrySource::Cuboid { min, max } => out.push(rectangle(*min, *max)),
            GeometrySource::Blocks { blocks, .. } => {
                out.extend(blocks.iter().map(|(min, max)| rectangle(*min, *max)));
            }
            GeometrySource::Mesh {
                vertices, indices, ..
            } => {
                for t in indices.iter() {
                    let [a, b, c] = t.map(|i| vertices[i as usize].as_dvec3());
                    let up = o.placement.enu_from_local * (b - a).cross(c - a);
                    if up.z > 0.0 {
                        out.push([a, b, c].map(|p| plan(p.as_vec3())).to_vec());
                    }
                }
            }
            GeometrySource::Terrain(_) => {}
        }
        if out.len() >= MAX_FOOTPRINTS {
            out.truncate(MAX_FOOTPRINTS);
            break;
        }
    }
    out.iter()
        .map(|p| clip(p, window))
        .filter(|p| p.len() >= 3)
        .collect()
}

/// The plan of one row: its vehicle's track, the intruder's (if any), the scene's footprints
/// near them (`scene`: `None` when it could not be loaded), the moment marked. `None` when
/// the row holds no track.
pub fn chart(row: &RowView, scene: Option<&Scene>) -> Result<Option<String>> {
    let Some(vehicle) = track_of(row.vehicle_track.as_deref()) else {
        return Ok(None);
    };
    let (moment, what) = match (row.first_collision_t_s, row.cpa_t_s) {
        (Some(t), _) => (Some(t), "first collision"),
        (None, Some(t)) => (Some(t), "closest approach"),
        _ => (None, ""),
    };
    let intruder = track_of(row.intruder.as_deref())
        .filter(|t| !t.is_empty())
        .map(|t| match moment {
            Some(m) => between(&t, m - AROUND_S, m + AROUND_S),
            None => t,
        });
    let tracks: Vec<&Track> = std::iter::once(&vehicle).chain(intruder.as_ref()).collect();
    let Some(window) = window(&tracks) else {
        return Ok(None);
    };
    let shapes = scene.map(|s| footprints(s, window)).unwrap_or_default();
    let caption = match moment {
        Some(t) => format!("{}: {what} at {t:.1} s", row.id),
        None => row.id.clone(),
    };
    let svg = svg_of((SIDE_PX, SIDE_PX + 30), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(caption, FONT)
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(44)
            .build_cartesian_2d(window.0 .0..window.0 .1, window.1 .0..window.1 .1)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_label_formatter(&|e| format!("{e:.0}"))
            .y_label_formatter(&|n| format!("{n:.0}"))
            .x_desc("east, m")
            .y_desc("north, m")
            .label_style(FONT)
            .draw()
            .map_err(failed)?;
        let grey = RGBColor(185, 185, 185).filled();
        chart
            .draw_series(shapes.into_iter().map(|p| Polygon::new(p, grey)))
            .map_err(failed)?;
        for (track, colour) in [(Some(&vehicle), VEHICLE), (intruder.as_ref(), INTRUDER)] {
            let Some(track) = track.filter(|t| !t.is_empty()) else {
                continue;
            };
            let line: Vec<(f64, f64)> = track.iter().map(|(_, p)| (p.x, p.y)).collect();
            chart
                .draw_series([PathElement::new(line, colour.stroke_width(2))])
                .map_err(failed)?;
            let start = track[0].1;
            chart
                .draw_series([Circle::new((start.x, start.y), 4, colour.filled())])
                .map_err(failed)?;
            if let Some(p) = moment.and_then(|t| at(track, t)) {
                chart
                    .draw_series([Cross::new((p.x, p.y), 7, MARK.stroke_width(2))])
                    .map_err(failed)?;
            }
        }
        Ok(())
    })?;
    Ok(Some(svg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_track_is_read_where_it_is_between_its_points_and_cut_at_both_ends() {
        let track = track_of(Some("0 0 0 10; 10 100 0 10; 20 100 100 10")).unwrap();
        assert_eq!(at(&track, 5.0), Some(DVec3::new(50.0, 0.0, 10.0)));
        assert_eq!(at(&track, -3.0), Some(track[0].1));
        assert_eq!(at(&track, 99.0), Some(track[2].1));
        let cut = between(&track, 5.0, 15.0);
        let times: Vec<f64> = cut.iter().map(|(t, _)| *t).collect();
        assert_eq!(times, [5.0, 10.0, 15.0]);
        assert_eq!(cut[2].1, DVec3::new(100.0, 50.0, 10.0));
        // Past the track's ends: its first and last points, at their own times.
        let all = between(&track, -100.0, 100.0);
        assert_eq!(all.len(), 5);
        assert_eq!((all[0].0, all[4].0), (0.0, 20.0));
        assert!(track_of(Some("not a track")).is_none() && track_of(None).is_none());
    }

    #[test]
    fn a_turned_box_and_a_mesh_are_drawn_as_their_outlines_from_above_clipped_to_the_plan() {
        let text = "[origin]\nlat_deg = 0.0\nlon_deg = 0.0\nalt_m = 0.0\n\n\
                    [[obstacle]]\nid = \"b\"\nkind = \"building\"\nshape = { box = [20.0, 10.0, 5.0] }\n\
                    position_enu_m = [0.0, 0.0, 0.0]\nyaw_deg = 90.0\n";
        let scene = crate::scene::parse(text, std::path::Path::new("s.toml"), "s").unwrap();
        let shapes = footprints(&scene, ((-50.0, 50.0), (-50.0, 50.0)));
        assert_eq!(shapes.len(), 1);
        // Turned a quarter: 10 m east-west, 20 m north-south.
        let (es, ns): (Vec<f64>, Vec<f64>) = shapes[0].iter().copied().unzip();
        let span = |v: &[f64]| {
            v.iter().fold(f64::MIN, |a, b| a.max(*b)) - v.iter().fold(f64::MAX, |a, b| a.min(*b))
        };
        assert!(
            (span(&es) - 10.0).abs() < 1e-6 && (span(&ns) - 20.0).abs() < 1e-6,
            "{shapes:?}"
        );
        // Clipped to a window that holds half of it.
        let half = footprints(&scene, ((0.0, 50.0), (-50.0, 50.0)));
        let (es, _): (Vec<f64>, Vec<f64>) = half[0].iter().copied().unzip();
        assert!((span(&es) - 5.0).abs() < 1e-6, "{half:?}");
        // Out of the window: nothing.
        assert!(footprints(&scene, ((100.0, 200.0), (100.0, 200.0))).is_empty());
        // A mesh (the built-in balloon): its upward triangles cover its plan outline.
        let text = "[origin]\nlat_deg = 0.0\nlon_deg = 0.0\nalt_m = 0.0\n\n\
                    [[obstacle]]\nid = \"m\"\nkind = \"balloon\"\nshape = { model = \"balloon\" }\n\
                    position_enu_m = [5.0, 0.0, 30.0]\n";
        let scene = crate::scene::parse(text, std::path::Path::new("s.toml"), "s").unwrap();
        let shapes = footprints(&scene, ((-50.0, 50.0), (-50.0, 50.0)));
        assert!(shapes.len() > 8, "{shapes:?}");
        let (es, ns): (Vec<f64>, Vec<f64>) = shapes.iter().flatten().copied().unzip();
        let b = scene.obstacles[0].aabb_enu_m;
        assert!(
            (span(&es) - (b.max.x - b.min.x)).abs() < 1e-3,
            "{es:?} {b:?}"
        );
        assert!(
            (span(&ns) - (b.max.y - b.min.y)).abs() < 1e-3,
            "{ns:?} {b:?}"
        );
    }
}
