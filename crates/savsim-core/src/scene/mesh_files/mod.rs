//! Mesh files: OBJ, STL, glTF/GLB and COLLADA read into vertices and triangles (in file units
//! for OBJ and STL; COLLADA's own `<unit>` and `<up_axis>` applied). No scene knowledge: the
//! scene format scales and turns what these return.

mod collada;

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
        "dae" => collada::load_collada(path, files),
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
