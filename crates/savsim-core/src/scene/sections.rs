//! The scene file's sections, each read into what the scene holds: vehicle models,
//! obstacles (boxes, blocks, meshes), terrain patches (generated, or from SRTM, GeoTIFF and
//! ArduPilot files), city models (CityJSON) and moving obstacles.

use std::collections::{BTreeMap, HashSet};
use std::sync::Arc;

use glam::DVec3;

use crate::geo::Geodetic;
use crate::scene::build::{item_name, parse_item, Builder};
use crate::scene::geometry::{Geometry, HeightGrid, TerrainPatch};
use crate::scene::spec::{CitySpec, DynamicSpec, ObstacleSpec, OsmSpec, TerrainSpec, VehicleSpec};
use crate::scene::terrain::{self, Elevation};
use crate::scene::{
    cityjson, gen, osm, DynamicObstacle, DynamicSource, Kind, OsmStats, Placement, SceneError,
    StaticObstacle,
};

/// Each kind's threat T: the paper's, or the scene's `[threat]` table's.
pub(crate) struct Threats(pub(crate) Vec<(Kind, f64)>);

impl Threats {
    /// The scene's table (`[threat]`, optional) over the paper's values.
    pub(crate) fn read(b: &Builder<'_>, table: Option<&toml::Value>) -> Result<Self, SceneError> {
        let overrides: BTreeMap<Kind, f64> = match table {
            Some(v) => parse_item(b, v, "[threat]")?,
            None => BTreeMap::new(),
        };
        let mut by_kind = Vec::new();
        for kind in Kind::ALL {
            let t = overrides.get(&kind).copied().unwrap_or(kind.paper_threat());
            if !t.is_finite() {
                return Err(b.err(Some("[threat]".into()), Some(kind.name()), "not finite"));
            }
            by_kind.push((kind, t));
        }
        Ok(Self(by_kind))
    }

    /// An item's threat: its own if it gives one, else its kind's.
    pub(crate) fn of(&self, kind: Kind, own: Option<f64>) -> f64 {
        own.unwrap_or_else(|| {
            self.0
                .iter()
                .find(|(k, _)| *k == kind)
                .map_or(kind.paper_threat(), |t| t.1)
        })
    }
}

/// `[[vehicle]]`: which model each system id flies (`None`: every other).
pub(crate) fn vehicles(
    b: &mut Builder<'_>,
    items: &[toml::Value],
) -> Result<Vec<(Option<u8>, usize)>, SceneError> {
    let mut vehicle_models = vec![(None, 0)];
    for (i, value) in items.iter().enumerate() {
        let item = item_name("vehicle", value, i);
        let spec: VehicleSpec = parse_item(b, value, &item)?;
        let g = b.model(&spec.model, &item)?;
        vehicle_models.retain(|(id, _)| *id != spec.system_id);
        vehicle_models.push((spec.system_id, g));
    }
    Ok(vehicle_models)
}

/// `[[obstacle]]`: boxes, blocks, models and mesh files placed in the scene.
pub(crate) fn obstacles(
    b: &mut Builder<'_>,
    items: &[toml::Value],
    threats: &Threats,
    ids: &mut HashSet<String>,
    obstacles: &mut Vec<StaticObstacle>,
) -> Result<(), SceneError> {
    for (i, value) in items.iter().enumerate() {
        let item = item_name("obstacle", value, i);
        let spec: ObstacleSpec = parse_item(b, value, &item)?;
        if !ids.insert(spec.id.clone()) {
            return Err(b.err(Some(item), Some("id"), "duplicate id"));
        }
        let geometry_index = b.shape(&spec.shape, &item, "shape")?;
        let position = b.position(spec.position_enu_m, spec.position_geo, &item)?;
        if !spec.yaw_deg.is_finite() {
            return Err(b.err(Some(item), Some("yaw_deg"), "not finite"));
        }
        let placement = Placement::from_yaw(position, spec.yaw_deg);
        let geometry = b.geometries[geometry_index].clone();
        obstacles.push(StaticObstacle {
            id: spec.id,
            kind: spec.kind,
            threat: threats.of(spec.kind, spec.threat),
            aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
            placement,
            geometry,
            geometry_index,
        });
    }
    Ok(())
}

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
            (None, Some(g)) => {
                if !(g.cell_m > 0.0 && g.size_m.iter().all(|s| *s >= g.cell_m) && g.relief_m >= 0.0)
                    || g.size_m.iter().any(|s| s / g.cell_m > 20_000.0)
                {
                    return Err(b.err(
                        Some(item),
                        Some("generated"),
                        "need cell_m > 0, size_m >= cell_m (at most 20000 cells a side), relief_m >= 0",
                    ));
                }
                (
                    gen::terrain_grid(g.seed, g.size_m, g.cell_m, g.relief_m),
                    None,
                )
            }
            (Some(file), None) => {
                let path = b.dir.join(file);
                let elevation = Elevation::read(&path, b.files).map_err(|m| {
                    b.err(
                        Some(item.clone()),
                        Some("file"),
                        format!("{}: {m}", path.display()),
                    )
                })?;
                let (centre, size_m) = match &spec.area {
                    Some(a) => (a.center_geo, a.size_m),
                    None => (None, [4000.0, 4000.0]),
                };
                let centre_enu = match centre {
                    Some([lat, lon]) => {
                        let g = Geodetic::new(lat, lon, 0.0);
                        if !g.is_valid() {
                            return Err(b.err(
                                Some(item),
                                Some("area.center_geo"),
                                "not a valid [lat_deg, lon_deg]",
                            ));
                        }
                        let p = b.plane.enu_m_from_geodetic(&g);
                        DVec3::new(p.x, p.y, 0.0)
                    }
                    None => DVec3::ZERO,
                };
                // Default: the file's spacing, but at most 25 m, so the triangles follow the
                // file's bilinear surface closely.
                let cell_m = spec
                    .cell_m
                    .unwrap_or_else(|| elevation.spacing_m().clamp(10.0, 25.0));
                if !(cell_m > 0.0
                    && size_m
                        .iter()
                        .all(|s| *s >= cell_m && s / cell_m <= 20_000.0))
                {
                    return Err(b.err(
                        Some(item),
                        Some("area.size_m"),
                        "need size_m >= cell_m > 0, at most 20000 cells a side",
                    ));
                }
                let corner = centre_enu - DVec3::new(size_m[0], size_m[1], 0.0) * 0.5;
                let grid = terrain::resample(&elevation, &b.plane, corner, size_m, cell_m)
                    .map_err(|m| {
                        b.err(
                            Some(item.clone()),
                            Some("area"),
                            format!("{}: {m}", path.display()),
                        )
                    })?;
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
    Ok(())
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

/// `[[city]]`: a CityJSON file's buildings, anchored at a geodetic position.
pub(crate) fn cities(
    b: &mut Builder<'_>,
    items: &[toml::Value],
    threats: &Threats,
    ids: &mut HashSet<String>,
    obstacles: &mut Vec<StaticObstacle>,
) -> Result<(), SceneError> {
    for (i, value) in items.iter().enumerate() {
        let item = item_name("city", value, i);
        let spec: CitySpec = parse_item(b, value, &item)?;
        let path = b.dir.join(&spec.file);
        let text = b.files.read_text(&path).map_err(|e| {
            b.err(
                Some(item.clone()),
                Some("file"),
                format!("{}: {e}", path.display()),
            )
        })?;
        let [lat, lon, alt] = spec.anchor_geo;
        let anchor = Geodetic::new(lat, lon, alt);
        if !anchor.is_valid() || !spec.rotation_deg.is_finite() {
            return Err(b.err(
                Some(item),
                Some("anchor_geo"),
                "not a valid [lat_deg, lon_deg, alt_m]",
            ));
        }
        let types = spec.types.clone().unwrap_or_else(|| {
            ["Building", "BuildingPart", "Bridge"]
                .map(str::to_owned)
                .to_vec()
        });
        let city = cityjson::buildings(&text, &types, spec.anchor_xyz, spec.rotation_deg).map_err(
            |m| {
                b.err(
                    Some(item.clone()),
                    Some("file"),
                    format!("{}: {m}", path.display()),
                )
            },
        )?;
        let anchor_enu = b.plane.enu_m_from_geodetic(&anchor);
        // The dataset's axes are the anchor's local east, north, up, turned into the plane's.
        let plane_from_local = b.plane.plane_enu_from_local_enu_at(&anchor);
        let rotation = glam::DQuat::from_mat3(&plane_from_local);
        let threat = threats.of(Kind::Building, spec.threat);
        for building in city {
            let id = format!("{}/{}", spec.id, building.id);
            if !ids.insert(id.clone()) {
                return Err(b.err(Some(item), Some("id"), format!("duplicate id {id:?}")));
            }
            let geometry_index = b.add(building.geometry);
            let geometry = b.geometries[geometry_index].clone();
            let placement = Placement {
                position_enu_m: anchor_enu + plane_from_local * building.origin_from_anchor_m,
                enu_from_local: rotation,
            };
            obstacles.push(StaticObstacle {
                id,
                kind: Kind::Building,
                threat,
                aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
                placement,
                geometry,
                geometry_index,
            });
        }
    }
    Ok(())
}

/// `[[osm]]`: an OpenStreetMap file's buildings (`.osm` XML or `.osm.pbf`), each footprint
/// projected into the scene's ENU frame (its nodes at the origin's height, exact) and extruded
/// from its base to its top above U = 0 (`scene::osm::heights`).
pub(crate) fn osm(
    b: &mut Builder<'_>,
    items: &[toml::Value],
    threats: &Threats,
    ids: &mut HashSet<String>,
    obstacles: &mut Vec<StaticObstacle>,
) -> Result<Vec<OsmStats>, SceneError> {
    let mut all = Vec::new();
    for (i, value) in items.iter().enumerate() {
        let item = item_name("osm", value, i);
        let spec: OsmSpec = parse_item(b, value, &item)?;
        let policy = osm_policy(b, &spec, &item)?;
        let path = b.dir.join(&spec.file);
        let bytes = b.files.read(&path).map_err(|e| {
            b.err(
                Some(item.clone()),
                Some("file"),
                format!("{}: {e}", path.display()),
            )
        })?;
        let pbf = spec.file.to_ascii_lowercase().ends_with(".pbf");
        let data = if pbf {
            osm::parse_pbf(&bytes)
        } else {
            std::str::from_utf8(&bytes)
                .map_err(|e| osm::OsmError::Xml(e.to_string()))
                .and_then(osm::parse_xml)
        }
        .map_err(|e| {
            b.err(
                Some(item.clone()),
                Some("file"),
                format!("{}: {e}", path.display()),
            )
        })?;
        let (footprints, found) = osm::footprints(&data);
        let mut stats = OsmStats {
            id: spec.id.clone(),
            outlines_replaced: found.outlines_replaced,
            outlines_trimmed: found.outlines_trimmed,
            slivers_dropped: found.slivers_dropped,
            skipped: found.open_ways + found.broken_relations,
            ..OsmStats::default()
        };
        let threat = threats.of(Kind::Building, spec.threat);
        for f in &footprints {
            let Some((base_m, top_m, source)) = osm::heights(&f.tags, policy) else {
                stats.skipped += 1;
                continue;
            };
            let Some((placement, geometry)) = osm_building(b, f, base_m, top_m) else {
                stats.skipped += 1;
                continue;
            };
            let id = format!("{}/{}", spec.id, f.id);
            if !ids.insert(id.clone()) {
                return Err(b.err(Some(item), Some("id"), format!("duplicate id {id:?}")));
            }
            let geometry_index = b.add(geometry);
            let geometry = b.geometries[geometry_index].clone();
            obstacles.push(StaticObstacle {
                id,
                kind: Kind::Building,
                threat,
                aabb_enu_m: placement.enu_aabb(&geometry.local_aabb),
                placement,
                geometry,
                geometry_index,
            });
            stats.buildings += 1;
            stats.parts += usize::from(f.part);
            stats.holes += f.holes.len();
            match source {
                osm::HeightSource::Height => stats.height_from_tag += 1,
                osm::HeightSource::Levels => stats.height_from_levels += 1,
                osm::HeightSource::Default => stats.height_defaulted += 1,
            }
        }
        all.push(stats);
    }
    Ok(all)
}

/// An `[[osm]]` item's height policy, checked.
fn osm_policy(
    b: &Builder<'_>,
    spec: &OsmSpec,
    item: &str,
) -> Result<osm::HeightPolicy, SceneError> {
    let defaults = osm::HeightPolicy::default();
    let check = |v: Option<f64>, default: f64, field: &str| match v {
        None => Ok(default),
        Some(m) if m.is_finite() && m > 0.0 && m <= 1000.0 => Ok(m),
        Some(m) => Err(b.err(
            Some(item.into()),
            Some(field),
            format!("{m}: give 0 < metres <= 1000"),
        )),
    };
    Ok(osm::HeightPolicy {
        level_m: check(spec.level_m, defaults.level_m, "level_m")?,
        default_m: check(
            spec.default_height_m,
            defaults.default_m,
            "default_height_m",
        )?,
    })
}

/// A footprint as a prism: placed at its first vertex's position (U = 0), its rings relative to
/// that in the scene's ENU axes. `None` when it has no area.
fn osm_building(
    b: &Builder<'_>,
    f: &osm::Footprint,
    base_m: f64,
    top_m: f64,
) -> Option<(Placement, Geometry)> {
    let alt = b.plane.origin().alt_m;
    let enu = |p: &[f64; 2]| b.plane.enu_m_from_geodetic(&Geodetic::new(p[1], p[0], alt));
    let anchor = enu(f.outer.first()?);
    let local = |ring: &[[f64; 2]]| -> Vec<glam::DVec2> {
        ring.iter().map(|p| (enu(p) - anchor).truncate()).collect()
    };
    let holes: Vec<Vec<glam::DVec2>> = f.holes.iter().map(|h| local(h)).collect();
    let geometry = crate::scene::extrude::prism(&local(&f.outer), &holes, base_m, top_m).ok()?;
    let placement = Placement {
        position_enu_m: DVec3::new(anchor.x, anchor.y, 0.0),
        enu_from_local: glam::DQuat::IDENTITY,
    };
    Some((placement, geometry))
}

/// `[[dynamic]]`: moving obstacles (waypoint tracks, MAVLink vehicles, ADS-B traffic).
pub(crate) fn dynamic(
    b: &mut Builder<'_>,
    items: &[toml::Value],
    threats: &Threats,
    kind_models: &[(Kind, usize)],
    ids: &mut HashSet<String>,
) -> Result<Vec<DynamicObstacle>, SceneError> {
    let mut dynamic = Vec::new();
    for (i, value) in items.iter().enumerate() {
        let item = item_name("dynamic", value, i);
        let spec: DynamicSpec = parse_item(b, value, &item)?;
        if !ids.insert(spec.id.clone()) {
            return Err(b.err(Some(item), Some("id"), "duplicate id"));
        }
        let source = match (spec.waypoints, spec.system_id, spec.icao) {
            (Some(w), None, None) => {
                if w.is_empty()
                    || w.windows(2).any(|p| p[1].t_s <= p[0].t_s)
                    || w.iter()
                        .any(|p| !p.t_s.is_finite() || !DVec3::from(p.position_enu_m).is_finite())
                {
                    return Err(b.err(
                        Some(item),
                        Some("waypoints"),
                        "need at least one waypoint, finite values, t_s strictly increasing",
                    ));
                }
                DynamicSource::Waypoints(w)
            }
            (None, Some(id), None) => DynamicSource::SystemId(id),
            (None, None, Some(icao)) => DynamicSource::Icao(icao),
            _ => {
                return Err(b.err(
                    Some(item),
                    Some("waypoints"),
                    "give exactly one of `waypoints`, `system_id`, `icao`",
                ))
            }
        };
        let geometry_index = match &spec.model {
            Some(m) => b.model(m, &item)?,
            None => kind_models.iter().find(|(k, _)| *k == spec.kind).unwrap().1,
        };
        dynamic.push(DynamicObstacle {
            id: spec.id.into(),
            kind: spec.kind,
            threat: threats.of(spec.kind, spec.threat),
            geometry: b.geometries[geometry_index].clone(),
            geometry_index,
            source,
            transponder: spec.transponder.unwrap_or(true),
        });
    }
    Ok(dynamic)
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

/// `[[sensor]]`: devices of the vehicles, each checked now (its error names the item and the
/// field); the run decides whether they are used.
pub(crate) fn sensors(
    b: &Builder<'_>,
    items: &[toml::Value],
) -> Result<Vec<crate::sensors::spec::DeviceSpec>, SceneError> {
    let mut out = Vec::new();
    for (i, value) in items.iter().enumerate() {
        let item = item_name("sensor", value, i);
        let spec: crate::sensors::spec::DeviceSpec = parse_item(b, value, &item)?;
        spec.build()
            .map_err(|e| b.err(Some(item.clone()), Some(e.field), e.why))?;
        out.push(spec);
    }
    if !out.is_empty() {
        crate::sensors::suite::Suite::from_specs(&out)
            .map_err(|e| b.err(Some("[[sensor]]".into()), None, e.to_string()))?;
    }
    Ok(out)
}
