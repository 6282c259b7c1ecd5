//! The reference's own shapes, built from the scene's plain data: each block a box, loaded
//! meshes and terrain triangles (terrain also as its own height grid, for "under it"), and the
//! overlap of two of them at two poses: between two boxes an oriented-box separating-axis test
//! written here in f64; anything with triangles through parry's intersection and distance
//! primitives.

use glam::{DMat3, DQuat, DVec3, Vec3};
use parry3d::math::Pose;
use parry3d::query;
use parry3d::shape::{Cuboid, Shape, TriMesh};

use super::ground::{Ground, TOUCH_M};
use crate::scene::geometry::{Geometry, GeometrySource};

/// A shape as the reference sees it.
pub(super) enum Parts {
    /// Boxes (centre in the body frame, half extents): solid.
    Solids(Vec<(DVec3, DVec3)>),
    /// Triangles (a loaded mesh); terrain also keeps its grid: under it is inside; a closed
    /// mesh (the scene says so) bounds a solid: inside it is inside ([`inside_closed`]).
    Surface {
        mesh: Box<TriMesh>,
        ground: Option<Ground>,
        closed: bool,
    },
    /// Nothing with volume or area.
    Empty,
}

impl Parts {
    pub(super) fn of(geometry: &Geometry) -> Self {
        let solid = |min: Vec3, max: Vec3| {
            let (min, max) = (min.as_dvec3(), max.as_dvec3());
            (
                (min + max) * 0.5,
                ((max - min) * 0.5).max(DVec3::splat(1e-4)),
            )
        };
        let surface = |(vertices, indices): (Vec<Vec3>, Vec<[u32; 3]>), ground, closed| {
            TriMesh::new(vertices, indices).map_or(Parts::Empty, |mesh| Parts::Surface {
                mesh: Box::new(mesh),
                ground,
                closed,
            })
        };
        match &geometry.source {
            GeometrySource::Cuboid { min, max } => Parts::Solids(vec![solid(*min, *max)]),
            GeometrySource::Blocks { blocks, .. } => {
                Parts::Solids(blocks.iter().map(|(a, b)| solid(*a, *b)).collect())
            }
            GeometrySource::Mesh {
                vertices,
                indices,
                closed,
            } => surface((vertices.to_vec(), indices.to_vec()), None, *closed),
            GeometrySource::Terrain(patch) => {
                let ground = Ground::of(patch);
                surface(ground.triangles(), Some(ground), false)
            }
        }
    }

    /// Radius of the sphere about the body's origin that holds it, metres.
    pub(super) fn radius_m(&self) -> f64 {
        match self {
            Parts::Solids(boxes) => boxes
                .iter()
                .map(|(c, h)| c.abs() + *h)
                .map(|corner| corner.length())
                .fold(0.0, f64::max),
            Parts::Surface { mesh, .. } => mesh
                .vertices()
                .iter()
                .map(|v| v.as_dvec3().length())
                .fold(0.0, f64::max),
            Parts::Empty => 0.0,
        }
    }

    /// The terrain grid, if this is terrain.
    pub(super) fn ground(&self) -> Option<&Ground> {
        match self {
            Parts::Surface { ground, .. } => ground.as_ref(),
            _ => None,
        }
    }
}

/// A rigid pose: where the body's origin is (scene ENU) and how it is turned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct At {
    pub position_enu_m: DVec3,
    pub rotation: DQuat,
}

impl At {
    /// Fraction `u` of the way from `self` to `to`: linear position, spherical rotation.
    pub(super) fn towards(self, to: At, u: f64) -> At {
        At {
            position_enu_m: self.position_enu_m.lerp(to.position_enu_m, u),
            rotation: self.rotation.slerp(to.rotation, u),
        }
    }
}

/// True when any part of `a` at `pa` overlaps or touches any part of `b` at `pb`, or one
/// holds the other inside a closed surface.
pub(super) fn overlap(a: &Parts, pa: At, b: &Parts, pb: At) -> bool {
    held(a, pa, b, pb) || held(b, pb, a, pa) || touch(a, pa, b, pb)
}

/// True when `inner` at `pi` has a point inside `outer` at `po`, a closed surface (a point of
/// a shape wholly inside it: any other inside point touches its surface too).
fn held(outer: &Parts, po: At, inner: &Parts, pi: At) -> bool {
    let Parts::Surface {
        mesh, closed: true, ..
    } = outer
    else {
        return false;
    };
    let point = match inner {
        Parts::Solids(boxes) => boxes.first().map(|(c, _)| *c),
        Parts::Surface { mesh, .. } => mesh.vertices().first().map(|v| v.as_dvec3()),
        Parts::Empty => None,
    };
    point.is_some_and(|p| {
        let enu = pi.position_enu_m + pi.rotation * p;
        let local = po.rotation.inverse() * (enu - po.position_enu_m);
        inside_closed(mesh, local)
    })
}

/// Whether `p` (the mesh's frame) is inside a closed mesh: its generalised winding number
/// (the solid angle its triangles subtend at `p`, over 4 pi, by Van Oosterom and Strackee's
/// formula) is about one. O(triangles), in f64.
fn inside_closed(mesh: &TriMesh, p: DVec3) -> bool {
    let solid_angle: f64 = mesh
        .triangles()
        .map(|t| {
            let [a, b, c] = [t.a, t.b, t.c].map(|v| v.as_dvec3() - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let numerator = a.dot(b.cross(c));
            let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            2.0 * numerator.atan2(denominator)
        })
        .sum();
    solid_angle / (4.0 * std::f64::consts::PI) > 0.5
}

/// True when any part of `a` at `pa` overlaps or touches any part of `b` at `pb`.
fn touch(a: &Parts, pa: At, b: &Parts, pb: At) -> bool {
    match (a, b) {
        (Parts::Empty, _) | (_, Parts::Empty) => false,
        (Parts::Solids(sa), Parts::Solids(sb)) => sa.iter().any(|(ca, ha)| {
            sb.iter()
                .any(|(cb, hb)| boxes_touch(pa, *ca, *ha, pb, *cb, *hb))
        }),
        (Parts::Solids(boxes), Parts::Surface { mesh, .. }) => {
            solids_touch_surface(boxes, pa, mesh, pb)
        }
        (Parts::Surface { mesh, .. }, Parts::Solids(boxes)) => {
            solids_touch_surface(boxes, pb, mesh, pa)
        }
        _ => shapes_touch(a, pa, b, pb),
    }
}

/// Boxes (centre in their body frame, half extents) at `pa` against the triangles of a surface
/// at `pb`, each pair by [`box_touches_triangle`] in f64 (parry's tree only picks the
/// triangles near each box).
fn solids_touch_surface(boxes: &[(DVec3, DVec3)], pa: At, mesh: &TriMesh, pb: At) -> bool {
    let ra = DMat3::from_quat(pa.rotation);
    let rb = DMat3::from_quat(pb.rotation);
    let axes = [ra.x_axis, ra.y_axis, ra.z_axis];
    boxes.iter().any(|(c, h)| {
        let centre = pa.position_enu_m + ra * *c;
        // The box's bounds in the surface's frame, for picking triangles.
        let local_centre = rb.transpose() * (centre - pb.position_enu_m);
        let reach: f64 = h.length() + TOUCH_M;
        let query = parry3d::bounding_volume::Aabb::new(
            (local_centre - DVec3::splat(reach)).as_vec3() - Vec3::splat(1e-3),
            (local_centre + DVec3::splat(reach)).as_vec3() + Vec3::splat(1e-3),
        );
        let corner = |p: Vec3| pb.position_enu_m + rb * p.as_dvec3();
        let touches = mesh.bvh().intersect_aabb(&query).any(|k| {
            let t = mesh.triangle(k);
            box_touches_triangle(centre, &axes, *h, [corner(t.a), corner(t.b), corner(t.c)])
        });
        touches
    })
}

/// A box (centre, unit axes, half extents) and a triangle touch within [`TOUCH_M`]: none of
/// the 13 candidate axes (the box's 3 face normals, the triangle's normal, the 9 crossings of
/// a box axis with a triangle edge) separates them by more. In f64 about the box's centre.
fn box_touches_triangle(centre: DVec3, axes: &[DVec3; 3], half: DVec3, tri: [DVec3; 3]) -> bool {
    let v = tri.map(|p| p - centre);
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let separates = |l: DVec3| {
        let Some(l) = l.try_normalize() else {
            return false;
        };
        let r: f64 = (0..3).map(|i| half[i] * axes[i].dot(l).abs()).sum();
        let p = v.map(|q| q.dot(l));
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        lo - r > TOUCH_M || -r - hi > TOUCH_M
    };
    let normal = edges[0].cross(edges[1]);
    let by_face = axes.iter().any(|&a| separates(a)) || separates(normal);
    let by_edge = || {
        axes.iter().any(|&a| {
            edges
                .iter()
                .any(|&e| a.cross(e).length() > 1e-12 * e.length() && separates(a.cross(e)))
        })
    };
    !(by_face || by_edge())
}

/// Two oriented boxes (centre in their body frame, half extents) touch within [`TOUCH_M`]:
/// none of the 15 separating axes (3 + 3 face normals, 9 edge crossings) separates them by
/// more.
fn boxes_touch(pa: At, ca: DVec3, ha: DVec3, pb: At, cb: DVec3, hb: DVec3) -> bool {
    let (ra, rb) = (DMat3::from_quat(pa.rotation), DMat3::from_quat(pb.rotation));
    let centre_a = pa.position_enu_m + ra * ca;
    let centre_b = pb.position_enu_m + rb * cb;
    let t = centre_b - centre_a;
    let (axes_a, axes_b) = (
        [ra.x_axis, ra.y_axis, ra.z_axis],
        [rb.x_axis, rb.y_axis, rb.z_axis],
    );
    let separates = |l: DVec3| {
        let Some(l) = l.try_normalize() else {
            return false;
        };
        let reach =
            |axes: &[DVec3; 3], h: DVec3| (0..3).map(|i| h[i] * axes[i].dot(l).abs()).sum::<f64>();
        t.dot(l).abs() - reach(&axes_a, ha) - reach(&axes_b, hb) > TOUCH_M
    };
    let by_face = axes_a.iter().chain(&axes_b).any(|&l| separates(l));
    let by_edge = || {
        axes_a.iter().any(|&a| {
            axes_b
                .iter()
                .any(|&b| a.cross(b).length() > 1e-9 && separates(a.cross(b)))
        })
    };
    !(by_face || by_edge())
}

/// Two surfaces, through parry, in f32 about `pa`'s position.
fn shapes_touch(a: &Parts, pa: At, b: &Parts, pb: At) -> bool {
    let anchor = pa.position_enu_m;
    let pose = |p: At, centre: DVec3| {
        Pose::from_parts(
            (p.position_enu_m + p.rotation * centre - anchor).as_vec3(),
            p.rotation.as_quat().normalize(),
        )
    };
    let mut touch = false;
    each(a, &mut |ca, sa| {
        each(b, &mut |cb, sb| {
            let (poa, pob) = (pose(pa, ca), pose(pb, cb));
            touch = query::intersection_test(&poa, sa, &pob, sb).is_ok_and(|i| i.intersecting)
                || query::distance(&poa, sa, &pob, sb).is_ok_and(|d| {
                    f64::from(d.distance) <= TOUCH_M + 1e-6 * size(sa).max(size(sb))
                });
            touch
        })
    });
    touch
}

/// f32 resolution of a large triangle mesh's coordinates: added to the touch distance.
fn size(s: &dyn Shape) -> f64 {
    s.as_trimesh()
        .map_or(0.0, |m| f64::from(m.local_aabb().half_extents().length()))
}

/// Call `f(centre, shape)` for each part until it returns true.
fn each(parts: &Parts, f: &mut dyn FnMut(DVec3, &dyn Shape) -> bool) -> bool {
    match parts {
        Parts::Solids(boxes) => boxes.iter().any(|(c, h)| f(*c, &Cuboid::new(h.as_vec3()))),
        Parts::Surface { mesh, .. } => f(DVec3::ZERO, mesh.as_ref()),
        Parts::Empty => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default quad through a 0.5 m slab, centimetre by centimetre: in contact exactly
    /// while its 0.62 m over the rotors overlaps the slab.
    #[test]
    fn the_quad_touches_a_slab_while_it_overlaps_it() {
        let quad = Parts::of(&crate::scene::models::quad());
        let slab = Parts::Solids(vec![(
            DVec3::new(0.0, 0.0, 50.0),
            DVec3::new(0.25, 50.0, 50.0),
        )]);
        let still = At {
            position_enu_m: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
        };
        for k in -70..=70 {
            let x = f64::from(k) * 0.01;
            let v = At {
                position_enu_m: DVec3::new(x, 0.0, 50.0),
                rotation: DQuat::IDENTITY,
            };
            let expect = x.abs() <= 0.25 + 0.31;
            // Within a millimetre of the edge either answer is a touch within TOUCH_M.
            if (x.abs() - 0.56).abs() > 1e-3 {
                assert_eq!(overlap(&quad, v, &slab, still), expect, "x = {x}");
            }
        }
    }
}
