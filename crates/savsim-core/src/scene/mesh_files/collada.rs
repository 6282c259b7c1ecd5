//! COLLADA (.dae): every triangle of a file's meshes, placed by its visual scene's nodes and
//! converted by its own `<unit>` and `<up_axis>`. Read with a plain XML parser and no schema
//! validation: real exporters' files vary.

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Vec3};
use roxmltree::{Document, Node};

use super::{Mesh, MeshFileError};
use crate::scene::Files;

/// Nodes instanced from `<library_nodes>` at most: a file whose nodes instance each other in a
/// cycle is cut off there.
const MAX_INSTANCES: usize = 100_000;

/// Read every triangle of a COLLADA file (`<triangles>`, `<polylist>` and `<polygons>` of its
/// meshes), with the visual scene's node transforms applied, converted to metres and to Z up
/// by the file's own `<unit>` and `<up_axis>` (so `scale` and `up` need not be given for it).
pub(super) fn load_collada(path: &Path, files: &dyn Files) -> Result<Mesh, MeshFileError> {
    let text = files.read_text(path).map_err(MeshFileError::Read)?;
    let doc = Document::parse(&text).map_err(|e| MeshFileError::decode("COLLADA", e))?;
    let collada = Collada::new(&doc);
    let mut mesh: Mesh = (Vec::new(), Vec::new());
    match collada.visual_scene() {
        Some(scene) => collada.add_visual_scene(scene, &mut mesh),
        // No visual scene: every geometry as it is.
        None => {
            for g in doc.descendants().filter(|n| named(n, "geometry")) {
                collada.add_geometry(g, Mat4::IDENTITY, &mut mesh);
            }
        }
    }
    Ok(in_metres_z_up(&doc, mesh))
}

fn named(n: &Node<'_, '_>, name: &str) -> bool {
    n.tag_name().name() == name
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.tag_name().name() == name)
}

/// The numbers of an element's text (what does not parse is left out).
fn numbers(n: Node<'_, '_>) -> Vec<f32> {
    n.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// The id a `#id` reference names.
fn fragment(s: &str) -> String {
    s.strip_prefix('#').unwrap_or(s).to_owned()
}

/// A parsed file and its elements by id.
struct Collada<'a, 'i> {
    doc: &'a Document<'i>,
    by_id: HashMap<&'a str, Node<'a, 'i>>,
}

impl<'a, 'i> Collada<'a, 'i> {
    fn new(doc: &'a Document<'i>) -> Self {
        let by_id = doc
            .descendants()
            .filter_map(|n| Some((n.attribute("id")?, n)))
            .collect();
        Collada { doc, by_id }
    }

    /// The visual scene the file instances, or else its first.
    fn visual_scene(&self) -> Option<Node<'a, 'i>> {
        self.doc
            .descendants()
            .find(|n| named(n, "instance_visual_scene"))
            .and_then(|i| {
                self.by_id
                    .get(fragment(i.attribute("url")?).as_str())
                    .copied()
            })
            .or_else(|| self.doc.descendants().find(|n| named(n, "visual_scene")))
    }

    /// Positions of a `<vertices>` (or `<source>`) id, as points.
    fn positions(&self, id: &str) -> Option<Vec<Vec3>> {
        let mut node = *self.by_id.get(id)?;
        if named(&node, "vertices") {
            let input = node
                .children()
                .find(|c| named(c, "input") && c.attribute("semantic") == Some("POSITION"))?;
            node = *self
                .by_id
                .get(fragment(input.attribute("source")?).as_str())?;
        }
        let floats = numbers(child(node, "float_array")?);
        let accessor = child(child(node, "technique_common")?, "accessor")?;
        let stride: usize = accessor
            .attribute("stride")
            .and_then(|s| s.parse().ok())
            .unwrap_or(3);
        Some(
            floats
                .chunks(stride.max(1))
                .filter(|c| c.len() >= 3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect(),
        )
    }

    /// Walk the visual scene's node tree (nodes instanced from `<library_nodes>` included, at
    /// most [`MAX_INSTANCES`]), adding each instanced geometry placed by its node's transforms.
    fn add_visual_scene(&self, scene: Node<'a, 'i>, mesh: &mut Mesh) {
        let mut stack: Vec<(Node<'a, 'i>, Mat4)> = scene
            .children()
            .filter(|c| named(c, "node"))
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        let mut instances = 0usize;
        while let Some((node, parent)) = stack.pop() {
            let world = node_transform(node, parent);
            for instance in node.children().filter(|c| named(c, "instance_geometry")) {
                let target = instance.attribute("url").map(fragment).unwrap_or_default();
                if let Some(g) = self.by_id.get(target.as_str()) {
                    self.add_geometry(*g, world, mesh);
                }
            }
            stack.extend(
                node.children()
                    .filter(|c| named(c, "node"))
                    .map(|c| (c, world)),
            );
            for instance in node.children().filter(|c| named(c, "instance_node")) {
                let target = instance.attribute("url").map(fragment).unwrap_or_default();
                if let Some(n) = self.by_id.get(target.as_str()) {
                    if instances < MAX_INSTANCES {
                        instances += 1;
                        stack.push((*n, world));
                    }
                }
            }
        }
    }

    /// Add every primitive of a `<geometry>`'s mesh, transformed by `world`.
    fn add_geometry(&self, geometry: Node<'a, 'i>, world: Mat4, mesh: &mut Mesh) {
        let Some(m) = child(geometry, "mesh") else {
            return;
        };
        for primitive in m
            .children()
            .filter(|c| ["triangles", "polylist", "polygons"].contains(&c.tag_name().name()))
        {
            self.add_primitive(primitive, world, mesh);
        }
    }

    /// Add a `<triangles>`, `<polylist>` or `<polygons>`: its positions (transformed by
    /// `world`) and its polygons, fanned into triangles. One without a usable `VERTEX` input
    /// adds nothing.
    fn add_primitive(&self, primitive: Node<'a, 'i>, world: Mat4, mesh: &mut Mesh) {
        let (vertices, indices) = mesh;
        let inputs: Vec<_> = primitive.children().filter(|c| named(c, "input")).collect();
        let stride = inputs
            .iter()
            .filter_map(|i| i.attribute("offset")?.parse::<usize>().ok())
            .max()
            .unwrap_or(0)
            + 1;
        let Some(vertex) = inputs
            .iter()
            .find(|i| i.attribute("semantic") == Some("VERTEX"))
        else {
            return;
        };
        let offset: usize = vertex
            .attribute("offset")
            .and_then(|o| o.parse().ok())
            .unwrap_or(0);
        let Some(points) = vertex
            .attribute("source")
            .and_then(|s| self.positions(&fragment(s)))
        else {
            return;
        };
        let base = vertices.len() as u32;
        vertices.extend(points.iter().map(|p| world.transform_point3(*p)));
        // The position index of each corner of a `<p>`.
        let corners = |p: Node<'_, '_>| -> Vec<u32> {
            numbers(p)
                .chunks_exact(stride)
                .map(|c| c[offset] as u32)
                .collect()
        };
        let mut polygon = |c: &[u32]| {
            for k in 1..c.len().saturating_sub(1) {
                indices.push([base + c[0], base + c[k], base + c[k + 1]]);
            }
        };
        match primitive.tag_name().name() {
            "triangles" => {
                for p in primitive.children().filter(|c| named(c, "p")) {
                    corners(p).chunks_exact(3).for_each(&mut polygon);
                }
            }
            "polylist" => {
                let counts = child(primitive, "vcount").map(numbers).unwrap_or_default();
                let all = child(primitive, "p").map(corners).unwrap_or_default();
                let mut at = 0usize;
                for n in counts {
                    let n = n as usize;
                    if let Some(c) = all.get(at..at + n) {
                        polygon(c);
                    }
                    at += n;
                }
            }
            _ => {
                for p in primitive.children().filter(|c| named(c, "p")) {
                    polygon(&corners(p));
                }
            }
        }
    }
}

/// `parent` times a node's own transforms (`<matrix>`, `<translate>`, `<rotate>`, `<scale>`),
/// in the order written.
fn node_transform(node: Node<'_, '_>, parent: Mat4) -> Mat4 {
    let mut world = parent;
    for t in node
        .children()
        .filter(|c| ["matrix", "translate", "rotate", "scale"].contains(&c.tag_name().name()))
    {
        world *= transform_of(t);
    }
    world
}

/// One transform element as a matrix (identity when malformed).
fn transform_of(n: Node<'_, '_>) -> Mat4 {
    let v = numbers(n);
    match (n.tag_name().name(), v.as_slice()) {
        ("matrix", m) if m.len() == 16 => {
            let mut a = [0f32; 16];
            a.copy_from_slice(m);
            Mat4::from_cols_array(&a).transpose()
        }
        ("translate", [x, y, z]) => Mat4::from_translation(Vec3::new(*x, *y, *z)),
        ("rotate", [x, y, z, deg]) => Mat4::from_axis_angle(
            Vec3::new(*x, *y, *z).normalize_or(Vec3::Z),
            deg.to_radians(),
        ),
        ("scale", [x, y, z]) => Mat4::from_scale(Vec3::new(*x, *y, *z)),
        _ => Mat4::IDENTITY,
    }
}

/// The mesh in metres (the file's `<unit meter>`, 1 by default) and Z up (its `<up_axis>`,
/// Y up by default).
fn in_metres_z_up(doc: &Document<'_>, (vertices, indices): Mesh) -> Mesh {
    let asset = doc.descendants().find(|n| named(n, "asset"));
    let meter = asset
        .and_then(|a| child(a, "unit"))
        .and_then(|u| u.attribute("meter")?.trim().parse::<f32>().ok())
        .filter(|m| *m > 0.0)
        .unwrap_or(1.0);
    let up = asset
        .and_then(|a| child(a, "up_axis"))
        .and_then(|u| u.text())
        .unwrap_or("Y_UP")
        .trim()
        .to_owned();
    let to_z_up = |v: Vec3| match up.as_str() {
        "Z_UP" => v,
        "X_UP" => Vec3::new(-v.y, -v.z, v.x),
        _ => Vec3::new(v.x, -v.z, v.y),
    };
    (
        vertices.into_iter().map(|v| to_z_up(v) * meter).collect(),
        indices,
    )
}
