//! Mesh files: OBJ, STL, glTF/GLB and COLLADA read into vertices and triangles (in file units
//! for OBJ and STL; COLLADA's own `<unit>` and `<up_axis>` applied). No scene knowledge: the
//! scene format scales and turns what these return.

use std::path::Path;

use glam::Vec3;

use crate::scene::Files;

/// Vertices and triangles (indices into the vertices).
pub type Mesh = (Vec<Vec3>, Vec<[u32; 3]>);

/// Why a mesh file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MeshFileError {
    /// The file could not be read.
    #[error("{0}")]
    Read(std::io::Error),
    /// Its format's reader refused it.
    #[error("not a valid {format} file: {message}")]
    Decode {
        /// The format.
        format: &'static str,
        /// What its reader said.
        message: String,
    },
    /// A kind of file savsim does not read.
    #[error(
        "unsupported mesh format {extension:?} (savsim reads .obj, .stl, .gltf, .glb and .dae)"
    )]
    Unsupported {
        /// The file's extension.
        extension: String,
    },
    /// A glTF buffer file that could not be read.
    #[error("buffer {uri}: {error}")]
    Buffer {
        /// The buffer's URI.
        uri: String,
        /// Why.
        error: std::io::Error,
    },
    /// Content savsim does not take.
    #[error("{0}")]
    Content(&'static str),
}

impl MeshFileError {
    fn decode(format: &'static str, e: impl std::fmt::Display) -> Self {
        MeshFileError::Decode {
            format,
            message: e.to_string(),
        }
    }
}

/// Read a mesh file (OBJ, STL, glTF/GLB or COLLADA) through `files` into vertices and
/// triangles, in file units (COLLADA: metres, Z up).
pub fn load_mesh_file(path: &Path, files: &dyn Files) -> Result<Mesh, MeshFileError> {
    let ext = path
        .extension()
        .map(|x| x.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "obj" => {
            let options = tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            };
            let bytes = files.read(path).map_err(MeshFileError::Read)?;
            let dir = path.parent().unwrap_or(Path::new("."));
            // Materials are not needed; an .mtl that cannot be read is not an error.
            let (obj_models, _) = tobj::load_obj_buf(&mut bytes.as_slice(), &options, |mtl| {
                match files.read(&dir.join(mtl)) {
                    Ok(b) => tobj::load_mtl_buf(&mut b.as_slice()),
                    Err(_) => Err(tobj::LoadError::OpenFileFailed),
                }
            })
            .map_err(|e| MeshFileError::decode("OBJ", e))?;
            let mut vertices = Vec::new();
            let mut indices = Vec::new();
            for m in obj_models {
                let base = vertices.len() as u32;
                vertices.extend(
                    m.mesh
                        .positions
                        .chunks_exact(3)
                        .map(|p| Vec3::new(p[0], p[1], p[2])),
                );
                indices.extend(
                    m.mesh
                        .indices
                        .chunks_exact(3)
                        .map(|t| [base + t[0], base + t[1], base + t[2]]),
                );
            }
            Ok((vertices, indices))
        }
        "stl" => {
            let bytes = files.read(path).map_err(MeshFileError::Read)?;
            let mesh = stl_io::read_stl(&mut std::io::Cursor::new(bytes))
                .map_err(|e| MeshFileError::decode("STL", e))?;
            let vertices = mesh
                .vertices
                .iter()
                .map(|v| Vec3::new(v[0], v[1], v[2]))
                .collect();
            let indices = mesh
                .faces
                .iter()
                .map(|f| {
                    [
                        f.vertices[0] as u32,
                        f.vertices[1] as u32,
                        f.vertices[2] as u32,
                    ]
                })
                .collect();
            Ok((vertices, indices))
        }
        "gltf" | "glb" => load_gltf(path, files),
        "dae" => load_collada(path, files),
        other => Err(MeshFileError::Unsupported {
            extension: other.into(),
        }),
    }
}

/// Read every triangle of a glTF 2.0 file (.gltf with its buffers, or .glb), with node
/// transforms applied, in file units (glTF: metres, Y up).
fn load_gltf(path: &Path, files: &dyn Files) -> Result<Mesh, MeshFileError> {
    let bytes = files.read(path).map_err(MeshFileError::Read)?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| MeshFileError::decode("glTF", e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or(MeshFileError::Content("the .glb has no binary chunk"))?,
            gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => files
                .read(&dir.join(uri))
                .map_err(|error| MeshFileError::Buffer {
                    uri: uri.into(),
                    error,
                })?,
            gltf::buffer::Source::Uri(_) => {
                return Err(MeshFileError::Content(
                    "embedded data: URIs are not supported; use .glb or external buffers",
                ))
            }
        };
        buffers.push(data);
    }
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let mut stack: Vec<(gltf::Node<'_>, glam::Mat4)> =
        match gltf.default_scene().or_else(|| gltf.scenes().next()) {
            Some(scene) => scene.nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect(),
            None => gltf.nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect(),
        };
    while let Some((node, parent)) = stack.pop() {
        let world = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                if primitive.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
                let Some(positions) = reader.read_positions() else {
                    continue;
                };
                let base = vertices.len() as u32;
                vertices.extend(positions.map(|p| world.transform_point3(Vec3::from(p))));
                let count = vertices.len() as u32 - base;
                let flat: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..count).collect(),
                };
                indices.extend(
                    flat.chunks_exact(3)
                        .map(|t| [base + t[0], base + t[1], base + t[2]]),
                );
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    Ok((vertices, indices))
}

/// Read every triangle of a COLLADA file (`<triangles>`, `<polylist>` and `<polygons>` of its
/// meshes), with the visual scene's node transforms applied, converted to metres and to Z up
/// by the file's own `<unit>` and `<up_axis>` (so `scale` and `up` need not be given for it).
/// Read with a plain XML parser and no schema validation: real exporters' files vary.
fn load_collada(path: &Path, files: &dyn Files) -> Result<Mesh, MeshFileError> {
    use roxmltree::{Document, Node};
    let text = files.read_text(path).map_err(MeshFileError::Read)?;
    let doc = Document::parse(&text).map_err(|e| MeshFileError::decode("COLLADA", e))?;
    fn named(n: &Node<'_, '_>, name: &str) -> bool {
        n.tag_name().name() == name
    }
    fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
        n.children().find(|c| c.tag_name().name() == name)
    }
    fn numbers(n: Node<'_, '_>) -> Vec<f32> {
        n.text()
            .unwrap_or("")
            .split_ascii_whitespace()
            .filter_map(|t| t.parse().ok())
            .collect()
    }
    let fragment = |s: &str| s.strip_prefix('#').unwrap_or(s).to_owned();
    let by_id: std::collections::HashMap<&str, Node<'_, '_>> = doc
        .descendants()
        .filter_map(|n| Some((n.attribute("id")?, n)))
        .collect();
    // Positions of a <vertices> (or <source>) id, as points.
    let positions = |id: &str| -> Option<Vec<Vec3>> {
        let mut node = *by_id.get(id)?;
        if named(&node, "vertices") {
            let input = node
                .children()
                .find(|c| named(c, "input") && c.attribute("semantic") == Some("POSITION"))?;
            node = *by_id.get(fragment(input.attribute("source")?).as_str())?;
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
    };
    let mut vertices = Vec::new();
    let mut indices = Vec::new();
    let mut add_geometry = |geometry: Node<'_, '_>, world: glam::Mat4| {
        let Some(mesh) = child(geometry, "mesh") else {
            return;
        };
        for primitive in mesh
            .children()
            .filter(|c| ["triangles", "polylist", "polygons"].contains(&c.tag_name().name()))
        {
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
                continue;
            };
            let offset: usize = vertex
                .attribute("offset")
                .and_then(|o| o.parse().ok())
                .unwrap_or(0);
            let Some(points) = vertex
                .attribute("source")
                .and_then(|s| positions(&fragment(s)))
            else {
                continue;
            };
            let base = vertices.len() as u32;
            vertices.extend(points.iter().map(|p| world.transform_point3(*p)));
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
    };
    let transform_of = |n: Node<'_, '_>| -> glam::Mat4 {
        let v = numbers(n);
        match (n.tag_name().name(), v.as_slice()) {
            ("matrix", m) if m.len() == 16 => {
                let mut a = [0f32; 16];
                a.copy_from_slice(m);
                glam::Mat4::from_cols_array(&a).transpose()
            }
            ("translate", [x, y, z]) => glam::Mat4::from_translation(Vec3::new(*x, *y, *z)),
            ("rotate", [x, y, z, deg]) => glam::Mat4::from_axis_angle(
                Vec3::new(*x, *y, *z).normalize_or(Vec3::Z),
                deg.to_radians(),
            ),
            ("scale", [x, y, z]) => glam::Mat4::from_scale(Vec3::new(*x, *y, *z)),
            _ => glam::Mat4::IDENTITY,
        }
    };
    let scene = doc
        .descendants()
        .find(|n| named(n, "instance_visual_scene"))
        .and_then(|i| by_id.get(fragment(i.attribute("url")?).as_str()).copied())
        .or_else(|| doc.descendants().find(|n| named(n, "visual_scene")));
    match scene {
        Some(scene) => {
            let mut stack: Vec<(Node<'_, '_>, glam::Mat4)> = scene
                .children()
                .filter(|c| named(c, "node"))
                .map(|n| (n, glam::Mat4::IDENTITY))
                .collect();
            // A file whose nodes instance each other in a cycle is cut off here.
            const MAX_INSTANCES: usize = 100_000;
            let mut instances = 0usize;
            while let Some((node, parent)) = stack.pop() {
                let mut world = parent;
                for t in node.children().filter(|c| {
                    ["matrix", "translate", "rotate", "scale"].contains(&c.tag_name().name())
                }) {
                    world *= transform_of(t);
                }
                for instance in node.children().filter(|c| named(c, "instance_geometry")) {
                    let target = instance.attribute("url").map(fragment).unwrap_or_default();
                    if let Some(g) = by_id.get(target.as_str()) {
                        add_geometry(*g, world);
                    }
                }
                stack.extend(
                    node.children()
                        .filter(|c| named(c, "node"))
                        .map(|c| (c, world)),
                );
                // Nodes instanced from <library_nodes>.
                for instance in node.children().filter(|c| named(c, "instance_node")) {
                    let target = instance.attribute("url").map(fragment).unwrap_or_default();
                    if let Some(n) = by_id.get(target.as_str()) {
                        if instances < MAX_INSTANCES {
                            instances += 1;
                            stack.push((*n, world));
                        }
                    }
                }
            }
        }
        None => {
            for g in doc.descendants().filter(|n| named(n, "geometry")) {
                add_geometry(g, glam::Mat4::IDENTITY);
            }
        }
    }
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
    Ok((
        vertices.into_iter().map(|v| to_z_up(v) * meter).collect(),
        indices,
    ))
}
