//! The scene file's sections, each read into what the scene holds: vehicle models,
//! obstacles (boxes, blocks, meshes), terrain patches (generated, or from SRTM, GeoTIFF and
//! ArduPilot files), city models (CityJSON) and moving obstacles.

mod terrain;

use std::collections::{BTreeMap, HashSet};

use glam::DVec3;

use crate::geo::Geodetic;
use crate::scene::build::{item_name, parse_item, Builder};
use crate::scene::geometry::Geometry;
use crate::scene::spec::{CitySpec, DynamicSpec, ObstacleSpec, OsmSpec, VehicleSpec};
use crate::scene::{
    cityjson, osm, DynamicObstacle, DynamicSource, Kind, OsmStats, Placement, SceneError,
    StaticObstacle,
};

pub(crate) use terrain::terrain;

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
        let threat = threats.of(spec.kind, spec.threat);
        obstacles.push(b.obstacle(spec.id, spec.kind, threat, placement, geometry_index));
    }
    Ok(())
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
        let text = b
            .files
            .read_text(&path)
            .map_err(|e| b.file_err(&item, &path, e))?;
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
        let city = cityjson::buildings(&text, &types, spec.anchor_xyz, spec.rotation_deg)
            .map_err(|m| b.file_err(&item, &path, m))?;
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
            let placement = Placement {
                position_enu_m: anchor_enu + plane_from_local * building.origin_from_anchor_m,
                enu_from_local: rotation,
            };
            obstacles.push(b.obstacle(id, Kind::Building, threat, placement, geometry_index));
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
        let bytes = b
            .files
            .read(&path)
            .map_err(|e| b.file_err(&item, &path, e))?;
        let pbf = spec.file.to_ascii_lowercase().ends_with(".pbf");
        let data = if pbf {
            osm::parse_pbf(&bytes)
        } else {
            std::str::from_utf8(&bytes)
                .map_err(|e| osm::OsmError::Xml(e.to_string()))
                .and_then(osm::parse_xml)
        }
        .map_err(|e| b.file_err(&item, &path, e))?;
        let (footprints, found) = osm::footprints(&data);
        let mut stats = OsmStats {
            id: spec.id.clone(),
            outlines_replaced: found.outlines_replaced,
            outlines_trimmed: found.outlines_trimmed,
            slivers_dropped: found.slivers_dropped,
            holes: found.inner_rings,
            holes_cut_by_parts: found.holes_cut_by_parts,
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
            obstacles.push(b.obstacle(id, Kind::Building, threat, placement, geometry_index));
            stats.buildings += 1;
            stats.parts += usize::from(f.part);
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
