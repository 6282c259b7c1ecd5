//! `savsim scene info`: what a scene holds and what it would cost to model all of it.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::scene::geometry::trimesh_bytes;
use crate::scene::geometry::GeometrySource;
use crate::scene::Scene;

/// A human-readable description of a scene.
pub fn describe(scene: &Scene) -> String {
    let mut out = String::new();
    let mut by_kind: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    let mut mesh_bytes = 0;
    for o in &scene.obstacles {
        let e = by_kind.entry(o.kind.name()).or_default();
        e.0 += 1;
        let triangles = o.geometry.triangle_count();
        e.1 += triangles;
        let vertices = match &o.geometry.source {
            GeometrySource::Mesh { vertices, .. } => vertices.len(),
            _ => triangles / 2 + 8,
        };
        mesh_bytes += trimesh_bytes(vertices, triangles);
    }
    let o = scene.origin;
    let _ = writeln!(
        out,
        "scene {}: origin {:.7} deg, {:.7} deg, {:.1} m AMSL",
        scene.name, o.lat_deg, o.lon_deg, o.alt_m
    );
    let _ = writeln!(out, "static obstacles: {}", scene.obstacles.len());
    for (kind, (n, triangles)) in &by_kind {
        let _ = writeln!(
            out,
            "  {kind:<9} {n:>7} obstacles {triangles:>12} triangles"
        );
    }
    for o in &scene.osm {
        let defaulted = if o.buildings == 0 {
            0.0
        } else {
            100.0 * o.height_defaulted as f64 / o.buildings as f64
        };
        let _ = writeln!(
            out,
            "  osm {}: {} buildings ({} parts, {} holes, {} more where parts stand); heights: {} from height, {} from levels, {} defaulted ({defaulted:.1}%); {} outlines replaced by their parts, {} kept where their parts leave them ({} slivers left out), {} skipped",
            o.id, o.buildings, o.parts, o.holes, o.holes_cut_by_parts, o.height_from_tag, o.height_from_levels, o.height_defaulted, o.outlines_replaced, o.outlines_trimmed, o.slivers_dropped, o.skipped
        );
    }
    let _ = writeln!(out, "dynamic obstacles: {}", scene.dynamic.len());
    for d in &scene.dynamic {
        let _ = writeln!(out, "  {} ({}): {:?}", d.id, d.kind.name(), d.source);
    }
    if !scene.obstacles.is_empty() {
        let b = scene.bounds_enu_m();
        let plane = crate::geo::LocalTangentPlane::new(scene.origin);
        let sw = plane.geodetic_from_enu_m(b.min);
        let ne = plane.geodetic_from_enu_m(b.max);
        let _ = writeln!(
            out,
            "bounds: E {:.1}..{:.1} m, N {:.1}..{:.1} m, U {:.1}..{:.1} m",
            b.min.x, b.max.x, b.min.y, b.max.y, b.min.z, b.max.z
        );
        let _ = writeln!(
            out,
            "        lat {:.6}..{:.6} deg, lon {:.6}..{:.6} deg",
            sw.lat_deg, ne.lat_deg, sw.lon_deg, ne.lon_deg
        );
    }
    let box_bytes = scene.obstacles.len() * std::mem::size_of::<parry3d::shape::Cuboid>();
    let _ = writeln!(
        out,
        "memory if every collider were built: boxes {} B, meshes ~{:.1} MiB",
        box_bytes,
        mesh_bytes as f64 / (1 << 20) as f64
    );
    out
}
