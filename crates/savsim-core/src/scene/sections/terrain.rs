//! `[[terrain]]`: a grid of heights (written out in the scene, generated, or resampled from an
//! elevation file: SRTM, GeoTIFF, ArduPilot .DAT) cut into patches, each a static obstacle.

use std::sync::Arc;

use glam::DVec3;

use super::Threats;
use crate::geo::Geodetic;
use crate::scene::build::{item_name, parse_item, Builder};
use crate::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
use crate::scene::spec::{GeneratedTerrainSpec, TerrainSpec};
use crate::scene::terrain::{self, Elevation};
use crate::scene::{gen, Placement, SceneError, StaticObstacle};

/// Most cells a side of a grid.
const MAX_CELLS_A_SIDE: f64 = 20_000.0;

/// `[[terrain]]`: a grid (generated, or resampled from an elevation file) cut into patches.
pub(crate) fn terrain(
    b: &mut Builder<'_>,
    items: &[toml::Value],
    threats: &Threats,
    obstacles: &mut Vec<StaticObstacle>,
) -> Result<(), SceneError> {
    for (i, value) in items.iter().enumerate() {
        let item = item_name("terrain", value, i);
        let spec: TerrainSpec = parse_item(b, value, &item)?;
        let (grid, file_corner) = match (&spec.file, &spec.generated) {
            (None, None) if spec.heights_m.is_some() => (given_grid(b, &item, &spec)?, None),
            (None, Some(g)) => (generated_grid(b, &item, g)?, None),
            (Some(file), None) => {
                let (grid, corner) = file_grid(b, &item, &spec, file)?;
                (grid, Some(corner))
            }
            _ => {
                return Err(b.err(
                    Some(item),
                    Some("file"),
                    "give exactly one of `file`, `generated` and `heights_m`",
                ))
            }
        };
        add_patches(b, &spec, grid, file_corner, threats, obstacles);
    }
    Ok(())
}

/// A generated grid (`generated`), its size checked.
fn generated_grid(
    b: &Builder<'_>,
    item: &str,
    g: &GeneratedTerrainSpec,
) -> Result<HeightGrid, SceneError> {
    if !(g.cell_m > 0.0 && g.size_m.iter().all(|s| *s >= g.cell_m) && g.relief_m >= 0.0)
        || g.size_m.iter().any(|s| s / g.cell_m > MAX_CELLS_A_SIDE)
    {
        return Err(b.err(
            Some(item.to_owned()),
            Some("generated"),
            "need cell_m > 0, size_m >= cell_m (at most 20000 cells a side), relief_m >= 0",
        ));
    }
    Ok(gen::terrain_grid(g.seed, g.size_m, g.cell_m, g.relief_m))
}

/// An elevation file's heights resampled to the scene's ENU grid over `area` (default 4 km a
/// side around the origin), and the grid's south-west corner, scene ENU metres.
fn file_grid(
    b: &Builder<'_>,
    item: &str,
    spec: &TerrainSpec,
    file: &str,
) -> Result<(HeightGrid, DVec3), SceneError> {
    let fail = |field: &str, m: String| b.err(Some(item.to_owned()), Some(field), m);
    let path = b.dir.join(file);
    let elevation = Elevation::read(&path, b.files)
        .map_err(|m| fail("file", format!("{}: {m}", path.display())))?;
    let (centre, size_m) = match &spec.area {
        Some(a) => (a.center_geo, a.size_m),
        None => (None, [4000.0, 4000.0]),
    };
    let centre_enu = match centre {
        Some([lat, lon]) => {
            let g = Geodetic::new(lat, lon, 0.0);
            if !g.is_valid() {
                return Err(fail(
                    "area.center_geo",
                    "not a valid [lat_deg, lon_deg]".into(),
                ));
            }
            let p = b.plane.enu_m_from_geodetic(&g);
            DVec3::new(p.x, p.y, 0.0)
        }
        None => DVec3::ZERO,
    };
    // Default: the file's spacing, but at most 25 m, so the triangles follow the file's
    // bilinear surface closely.
    let cell_m = spec
        .cell_m
        .unwrap_or_else(|| elevation.spacing_m().clamp(10.0, 25.0));
    if !(cell_m > 0.0
        && size_m
            .iter()
            .all(|s| *s >= cell_m && s / cell_m <= MAX_CELLS_A_SIDE))
    {
        return Err(fail(
            "area.size_m",
            "need size_m >= cell_m > 0, at most 20000 cells a side".into(),
        ));
    }
    let corner = centre_enu - DVec3::new(size_m[0], size_m[1], 0.0) * 0.5;
    let grid = terrain::resample(&elevation, &b.plane, corner, size_m, cell_m)
        .map_err(|m| fail("area", format!("{}: {m}", path.display())))?;
    Ok((grid, corner))
}

/// The grid's patches as static obstacles (`id/x_y`), placed from its south-west corner: the
/// item's `position_enu_m`, else the file's area, else the grid centred on the origin.
fn add_patches(
    b: &mut Builder<'_>,
    spec: &TerrainSpec,
    grid: HeightGrid,
    file_corner: Option<DVec3>,
    threats: &Threats,
    obstacles: &mut Vec<StaticObstacle>,
) {
    let grid = Arc::new(grid);
    let extent = DVec3::new(
        (grid.nx - 1) as f64 * grid.cell_m as f64,
        (grid.ny - 1) as f64 * grid.cell_m as f64,
        0.0,
    );
    let corner = match (spec.position_enu_m, file_corner) {
        (Some(p), _) => DVec3::from(p),
        (None, Some(c)) => c,
        (None, None) => -extent * 0.5,
    };
    let patch_cells = spec.patch_cells.unwrap_or(32).max(1);
    let threat = threats.of(spec.kind, spec.threat);
    for (geometry, x0, y0) in terrain_patches(&grid, patch_cells) {
        let geometry_index = b.add(geometry);
        let geometry = b.geometries[geometry_index].clone();
        let placement = Placement::from_yaw(
            corner + DVec3::new(x0 as f64, y0 as f64, 0.0) * grid.cell_m as f64,
            0.0,
        );
        obstacles.push(StaticObstacle {
            id: format!("{}/{}_{}", spec.id, x0 / patch_cells, y0 / patch_cells),
            kind: spec.kind,
            threat,
            aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
            placement,
            geometry,
            geometry_index,
        });
    }
}

/// A grid written out in the scene (`heights_m` rows south to north, `cell_m` apart).
fn given_grid(b: &Builder<'_>, item: &str, spec: &TerrainSpec) -> Result<HeightGrid, SceneError> {
    let rows = spec.heights_m.as_deref().unwrap_or_default();
    let nx = rows.first().map_or(0, Vec::len);
    let fail = |field: &str, m: &str| b.err(Some(item.to_owned()), Some(field), m);
    if rows.len() < 2 || nx < 2 || rows.iter().any(|r| r.len() != nx) {
        return Err(fail(
            "heights_m",
            "need at least 2 rows of at least 2 heights, every row as long",
        ));
    }
    if rows
        .iter()
        .flatten()
        .any(|h| !(h.is_finite() && h.abs() < 1e6))
    {
        return Err(fail("heights_m", "every height finite, within 1000 km"));
    }
    let cell_m = match spec.cell_m {
        Some(c) if c.is_finite() && c > 0.0 && c < 1e5 => c,
        _ => return Err(fail("cell_m", "`heights_m` needs cell_m > 0 (metres)")),
    };
    if spec.file.is_none() && spec.area.is_some() {
        return Err(fail("area", "`area` is for `file`"));
    }
    Ok(HeightGrid {
        nx,
        ny: rows.len(),
        cell_m: cell_m as f32,
        heights_m: rows.iter().flatten().map(|&h| h as f32).collect(),
    })
}

/// Cut a grid into patches of `patch_cells` cells a side (sharing their edge samples).
fn terrain_patches(
    grid: &Arc<HeightGrid>,
    patch_cells: usize,
) -> impl Iterator<Item = (Geometry, usize, usize)> + '_ {
    let ys = (0..grid.ny - 1).step_by(patch_cells);
    ys.flat_map(move |y0| {
        (0..grid.nx - 1).step_by(patch_cells).filter_map(move |x0| {
            let patch = TerrainPatch {
                grid: grid.clone(),
                x0,
                y0,
                nx: (patch_cells + 1).min(grid.nx - x0),
                ny: (patch_cells + 1).min(grid.ny - y0),
                base_m: 0.0,
            };
            Geometry::terrain(patch).ok().map(|g| (g, x0, y0))
        })
    })
}
