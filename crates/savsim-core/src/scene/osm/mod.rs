//! OpenStreetMap buildings (`[[osm]]` in a scene): `.osm` XML and `.osm.pbf` read into one
//! in-memory model, building footprints assembled from closed ways and multipolygon relations
//! (holes kept), `building:part` preferred to the outline it lies in, and heights by one policy
//! ([`heights`]). Pure: the bytes are handed in; `scene::sections` projects and extrudes.

mod height_tags;
mod parts;

pub use height_tags::{heights, length_m, HeightPolicy, HeightSource, MAX_HEIGHT_M, MAX_LEVELS};
use parts::prefer_parts;
pub use parts::{SLIVER_AREA_M2, SLIVER_WIDTH_M};

use std::collections::HashMap;

/// An OSM element's tags.
pub type Tags = Vec<(String, String)>;

/// A way: its node ids and tags.
#[derive(Debug, Clone, Default)]
pub struct Way {
    /// Node ids, in order.
    pub refs: Vec<i64>,
    /// Tags.
    pub tags: Tags,
}

/// A relation member.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    /// Whether it is a way (only ways make rings).
    pub is_way: bool,
    /// Its id.
    pub id: i64,
    /// Its role (`outer`, `inner`, ...).
    pub role: String,
}

/// A relation.
#[derive(Debug, Clone, Default)]
pub struct Relation {
    /// Its id.
    pub id: i64,
    /// Its members.
    pub members: Vec<Member>,
    /// Tags.
    pub tags: Tags,
}

/// What an OSM file holds, as far as buildings need.
#[derive(Debug, Clone, Default)]
pub struct OsmData {
    /// Node positions: (lon_deg, lat_deg).
    pub nodes: HashMap<i64, [f64; 2]>,
    /// Ways by id.
    pub ways: HashMap<i64, Way>,
    /// Relations, in file order.
    pub relations: Vec<Relation>,
}

/// Why an OSM file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum OsmError {
    /// Not XML, or not an `<osm>` document.
    #[error("not OSM XML: {0}")]
    Xml(String),
    /// Not a readable OSM PBF file.
    #[error("not a readable OSM PBF file: {0}")]
    Pbf(String),
}

/// Read OSM XML (`.osm`). Nodes without a valid `lat`/`lon` are left out (a way through one is
/// then not closed and is skipped).
pub fn parse_xml(text: &str) -> Result<OsmData, OsmError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| OsmError::Xml(e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "osm" {
        return Err(OsmError::Xml(format!(
            "the root element is <{}>, not <osm>",
            root.tag_name().name()
        )));
    }
    let mut data = OsmData::default();
    let id = |n: &roxmltree::Node<'_, '_>| n.attribute("id").and_then(|v| v.parse::<i64>().ok());
    let tags = |n: &roxmltree::Node<'_, '_>| -> Tags {
        n.children()
            .filter(|c| c.has_tag_name("tag"))
            .filter_map(|t| Some((t.attribute("k")?.to_owned(), t.attribute("v")?.to_owned())))
            .collect()
    };
    for element in root.children().filter(roxmltree::Node::is_element) {
        let Some(element_id) = id(&element) else {
            continue;
        };
        match element.tag_name().name() {
            "node" => {
                let coordinate = |k: &str| {
                    element
                        .attribute(k)
                        .and_then(|v| v.parse::<f64>().ok())
                        .filter(|v| v.is_finite())
                };
                if let (Some(lat), Some(lon)) = (coordinate("lat"), coordinate("lon")) {
                    insert_node(&mut data, element_id, lon, lat);
                }
            }
            "way" => {
                let refs = element
                    .children()
                    .filter(|c| c.has_tag_name("nd"))
                    .filter_map(|c| c.attribute("ref")?.parse::<i64>().ok())
                    .collect();
                let tags = tags(&element);
                data.ways.insert(element_id, Way { refs, tags });
            }
            "relation" => {
                let members = element
                    .children()
                    .filter(|c| c.has_tag_name("member"))
                    .filter_map(|m| {
                        Some(Member {
                            is_way: m.attribute("type")? == "way",
                            id: m.attribute("ref")?.parse().ok()?,
                            role: m.attribute("role").unwrap_or_default().to_owned(),
                        })
                    })
                    .collect();
                let tags = tags(&element);
                data.relations.push(Relation {
                    id: element_id,
                    members,
                    tags,
                });
            }
            _ => {}
        }
    }
    Ok(data)
}

/// Keep a node whose position is a place (finite, latitude within 90 degrees, longitude within
/// 180); a way through one left out is not closed and is skipped.
fn insert_node(data: &mut OsmData, id: i64, lon_deg: f64, lat_deg: f64) {
    if lat_deg.abs() <= 90.0 && lon_deg.abs() <= 180.0 {
        data.nodes.insert(id, [lon_deg, lat_deg]);
    }
}

/// Read OSM PBF (`.osm.pbf`). Nodes outside the globe are left out, as in XML. A file the `osmpbf` crate cannot read (or panics on: it does on
/// some corrupt enum values) is an error.
pub fn parse_pbf(bytes: &[u8]) -> Result<OsmData, OsmError> {
    let read = std::panic::catch_unwind(|| {
        let mut data = OsmData::default();
        let reader = osmpbf::ElementReader::new(std::io::Cursor::new(bytes));
        let owned = |tags: &mut dyn Iterator<Item = (&str, &str)>| -> Tags {
            tags.map(|(k, v)| (k.to_owned(), v.to_owned())).collect()
        };
        reader
            .for_each(|element| match element {
                osmpbf::Element::Node(n) => insert_node(&mut data, n.id(), n.lon(), n.lat()),
                osmpbf::Element::DenseNode(n) => {
                    insert_node(&mut data, n.id(), n.lon(), n.lat());
                }
                osmpbf::Element::Way(w) => {
                    let way = Way {
                        refs: w.refs().collect(),
                        tags: owned(&mut w.tags()),
                    };
                    data.ways.insert(w.id(), way);
                }
                osmpbf::Element::Relation(r) => {
                    let members = r
                        .members()
                        .map(|m| Member {
                            is_way: matches!(m.member_type, osmpbf::RelMemberType::Way),
                            id: m.member_id,
                            role: m.role().unwrap_or_default().to_owned(),
                        })
                        .collect();
                    data.relations.push(Relation {
                        id: r.id(),
                        members,
                        tags: owned(&mut r.tags()),
                    });
                }
            })
            .map(|()| data)
            .map_err(|e| OsmError::Pbf(e.to_string()))
    });
    read.unwrap_or_else(|_| Err(OsmError::Pbf("the reader failed on its content".into())))
}

/// A building footprint: its outer ring and holes as (lon_deg, lat_deg), closed (first point
/// not repeated), and its tags.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// `way/ID` or `relation/ID`.
    pub id: String,
    /// The outer ring.
    pub outer: Vec<[f64; 2]>,
    /// Inner rings.
    pub holes: Vec<Vec<[f64; 2]>>,
    /// Tags (a relation's; an outline's own for a way).
    pub tags: Tags,
    /// Tagged `building:part` (and not `building`).
    pub part: bool,
}

/// What assembling the footprints found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Assembly {
    /// Building ways not closed (or through a missing node): not buildings.
    pub open_ways: usize,
    /// Building relations whose rings do not close: not buildings.
    pub broken_relations: usize,
    /// Outlines their `building:part`s cover entirely: replaced by them.
    pub outlines_replaced: usize,
    /// Outlines their parts cover in part: kept as the pieces the parts leave.
    pub outlines_trimmed: usize,
    /// Pieces of trimmed outlines too thin or small to keep (see [`SLIVER_WIDTH_M`]).
    pub slivers_dropped: usize,
    /// Inner rings of every building and part assembled (what libosmium's assembler counts):
    /// courtyards drawn in OpenStreetMap.
    pub inner_rings: usize,
    /// Holes the parts cut in the outlines they leave: where a part stands wholly inside its
    /// outline, the outline's piece has a hole the part fills (not a courtyard).
    pub holes_cut_by_parts: usize,
}

fn tag<'a>(tags: &'a Tags, key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

/// Whether the tags make a building (any `building` value but `no`) or a building part.
fn building_kind(tags: &Tags) -> Option<bool> {
    match (tag(tags, "building"), tag(tags, "building:part")) {
        (Some(v), _) if v != "no" => Some(false),
        (_, Some(v)) if v != "no" => Some(true),
        _ => None,
    }
}

/// The positions of a way's nodes; `None` when one is missing.
fn positions(data: &OsmData, refs: &[i64]) -> Option<Vec<[f64; 2]>> {
    refs.iter().map(|r| data.nodes.get(r).copied()).collect()
}

/// A closed ring of node ids (first == last, at least 4) as positions without the repeat.
fn ring(data: &OsmData, refs: &[i64]) -> Option<Vec<[f64; 2]>> {
    if refs.len() < 4 || refs.first() != refs.last() {
        return None;
    }
    let mut points = positions(data, refs)?;
    points.pop();
    Some(points)
}

/// Join ways (node-id sequences) into closed rings by their shared end nodes, as
/// multipolygon members are drawn; `None` if any way is left in an open chain.
fn join_rings(mut ways: Vec<Vec<i64>>) -> Option<Vec<Vec<i64>>> {
    let mut rings = Vec::new();
    while let Some(mut chain) = ways.pop() {
        while chain.len() < 2 || chain.first() != chain.last() {
            let end = *chain.last()?;
            let next = ways
                .iter()
                .position(|w| w.first() == Some(&end) || w.last() == Some(&end))?;
            let mut way = ways.swap_remove(next);
            if way.first() != Some(&end) {
                way.reverse();
            }
            chain.extend_from_slice(&way[1..]);
        }
        rings.push(chain);
    }
    Some(rings)
}

/// Every building footprint: closed ways tagged `building` or `building:part`, and
/// `type=multipolygon` relations so tagged (outer and inner rings joined from their member
/// ways; an empty role is outer). An outline keeps what its `building:part`s leave of it
/// (`prefer_parts`). Outlines (and their pieces) in id order (ways, then relations), then the
/// parts in that order.
pub fn footprints(data: &OsmData) -> (Vec<Footprint>, Assembly) {
    let mut out = Vec::new();
    let mut found = Assembly::default();
    let mut way_ids: Vec<&i64> = data.ways.keys().collect();
    way_ids.sort_unstable();
    for id in way_ids {
        let way = &data.ways[id];
        let Some(part) = building_kind(&way.tags) else {
            continue;
        };
        match ring(data, &way.refs) {
            Some(outer) => out.push(Footprint {
                id: format!("way/{id}"),
                outer,
                holes: Vec::new(),
                tags: way.tags.clone(),
                part,
            }),
            None => found.open_ways += 1,
        }
    }
    let mut relations: Vec<&Relation> = data.relations.iter().collect();
    relations.sort_by_key(|r| r.id);
    for r in relations {
        let Some(part) = building_kind(&r.tags) else {
            continue;
        };
        if tag(&r.tags, "type") != Some("multipolygon") {
            continue;
        }
        match relation_rings(data, r) {
            Some((mut outers, holes)) if outers.len() == 1 => out.push(Footprint {
                id: format!("relation/{}", r.id),
                outer: outers.remove(0),
                holes,
                tags: r.tags.clone(),
                part,
            }),
            Some((outers, holes)) if !outers.is_empty() => {
                // Several outer rings: one footprint each, every hole with the ring it is in.
                for (k, outer) in outers.iter().enumerate() {
                    let inside: Vec<Vec<[f64; 2]>> = holes
                        .iter()
                        .filter(|h| h.first().is_some_and(|p| contains(outer, *p)))
                        .cloned()
                        .collect();
                    out.push(Footprint {
                        id: format!("relation/{}/{k}", r.id),
                        outer: outer.clone(),
                        holes: inside,
                        tags: r.tags.clone(),
                        part,
                    });
                }
            }
            _ => found.broken_relations += 1,
        }
    }
    found.inner_rings = out.iter().map(|f| f.holes.len()).sum();
    let out = prefer_parts(out, &mut found);
    (out, found)
}

/// A relation's outer and inner rings as positions.
#[allow(clippy::type_complexity)]
fn relation_rings(
    data: &OsmData,
    r: &Relation,
) -> Option<(Vec<Vec<[f64; 2]>>, Vec<Vec<[f64; 2]>>)> {
    let of_role = |inner: bool| -> Option<Vec<Vec<[f64; 2]>>> {
        let ways: Vec<Vec<i64>> = r
            .members
            .iter()
            .filter(|m| m.is_way && (m.role == "inner") == inner)
            .filter(|m| inner || m.role.is_empty() || m.role == "outer")
            .map(|m| data.ways.get(&m.id).map(|w| w.refs.clone()))
            .collect::<Option<_>>()?;
        join_rings(cancel_shared_segments(ways))?
            .iter()
            .map(|refs| ring(data, refs))
            .collect()
    };
    Some((of_role(false)?, of_role(true)?))
}

/// `ways` with every segment two of them share taken out, as libosmium's assembler does (a
/// segment drawn an even number of times bounds nothing): two rings drawn along a common edge
/// become one ring around both, so two courtyards that share a side are one hole. What is
/// left is given as two-node ways for [`join_rings`] to chain; ways that share no segment are
/// returned as they are.
fn cancel_shared_segments(ways: Vec<Vec<i64>>) -> Vec<Vec<i64>> {
    let key = |a: i64, b: i64| (a.min(b), a.max(b));
    let mut drawn: std::collections::HashMap<(i64, i64), usize> = Default::default();
    for s in ways.iter().flat_map(|w| w.windows(2)) {
        *drawn.entry(key(s[0], s[1])).or_default() += 1;
    }
    if drawn.values().all(|&n| n == 1) {
        return ways;
    }
    let mut left = Vec::new();
    for s in ways.iter().flat_map(|w| w.windows(2)) {
        let n = drawn.get_mut(&key(s[0], s[1])).map(std::mem::take);
        if s[0] != s[1] && n.is_some_and(|n| n % 2 == 1) {
            left.push(vec![s[0], s[1]]);
        }
    }
    left
}

/// Whether `p` is inside the ring (even-odd rule, in the plane of lon and lat).
fn contains(ring: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut inside = false;
    let mut j = ring.len().wrapping_sub(1);
    for (i, a) in ring.iter().enumerate() {
        let b = ring[j];
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
        {
            inside = !inside;
        }
        j = i;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(xml: &str) -> OsmData {
        parse_xml(xml).unwrap()
    }

    const SQUARE: &str = r#"<osm version="0.6">
      <node id="1" lat="0" lon="0"/><node id="2" lat="0" lon="0.001"/>
      <node id="3" lat="0.001" lon="0.001"/><node id="4" lat="0.001" lon="0"/>
      <node id="5" lat="0.0004" lon="0.0004"/><node id="6" lat="0.0004" lon="0.0006"/>
      <node id="7" lat="0.0006" lon="0.0006"/><node id="8" lat="0.0006" lon="0.0004"/>
      <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/></way>
      <way id="11"><nd ref="3"/><nd ref="4"/><nd ref="1"/></way>
      <way id="12"><nd ref="5"/><nd ref="6"/><nd ref="7"/><nd ref="8"/><nd ref="5"/></way>
      <relation id="20"><member type="way" ref="11" role="outer"/><member type="way" ref="10" role="outer"/>
        <member type="way" ref="12" role="inner"/><tag k="type" v="multipolygon"/><tag k="building" v="yes"/></relation>
    </osm>"#;

    #[test]
    fn a_multipolygon_of_two_outer_ways_and_a_hole_is_one_footprint_with_its_hole() {
        let (f, found) = footprints(&data(SQUARE));
        assert_eq!(
            found,
            Assembly {
                inner_rings: 1,
                ..Assembly::default()
            }
        );
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].id, "relation/20");
        assert_eq!(f[0].outer.len(), 4);
        assert_eq!(f[0].holes.len(), 1);
        assert_eq!(f[0].holes[0].len(), 4);
    }

    /// A 0.001-degree square outline (way 30) and `part` (a closed way of nodes 1-8 and 40-44).
    fn outline_with(part: &str) -> String {
        format!(
            r#"<osm version="0.6">
      <node id="1" lat="0" lon="0"/><node id="2" lat="0" lon="0.001"/>
      <node id="3" lat="0.001" lon="0.001"/><node id="4" lat="0.001" lon="0"/>
      <node id="40" lat="0.0005" lon="0.0005"/><node id="41" lat="0.0005" lon="0.001"/>
      <node id="43" lat="0.001" lon="0.0005"/>
      <way id="30"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="building" v="yes"/><tag k="height" v="40"/></way>
      {part}
      <way id="14"><nd ref="1"/><nd ref="2"/><tag k="building" v="yes"/></way>
    </osm>"#
        )
    }

    fn area(ring: &[[f64; 2]]) -> f64 {
        let n = ring.len();
        (0..n)
            .map(|i| {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            .abs()
            / 2.0
    }

    #[test]
    fn a_part_covering_its_outline_replaces_it_and_an_open_way_is_counted() {
        let part = r#"<way id="31"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="building:part" v="yes"/></way>"#;
        let (f, found) = footprints(&data(&outline_with(part)));
        assert_eq!(
            f.iter().map(|f| f.id.as_str()).collect::<Vec<_>>(),
            ["way/31"]
        );
        assert_eq!((found.outlines_replaced, found.open_ways), (1, 1));
    }

    /// The outline's volume the part does not cover stays a building: a part over the NE
    /// quarter leaves an L of three quarters with the outline's tags.
    #[test]
    fn a_part_covering_a_quarter_leaves_the_other_three_quarters_of_its_outline() {
        let part = r#"<way id="31"><nd ref="40"/><nd ref="41"/><nd ref="3"/><nd ref="43"/><nd ref="40"/><tag k="building:part" v="yes"/><tag k="height" v="10"/></way>"#;
        let (f, found) = footprints(&data(&outline_with(part)));
        assert_eq!(
            f.iter().map(|f| f.id.as_str()).collect::<Vec<_>>(),
            ["way/30", "way/31"]
        );
        assert_eq!((found.outlines_replaced, found.outlines_trimmed), (0, 1));
        let left = &f[0];
        assert!(!left.part && left.holes.is_empty());
        assert!(
            (area(&left.outer) - 0.75e-6).abs() < 1e-15,
            "{:?}",
            left.outer
        );
        assert_eq!(tag(&left.tags, "height"), Some("40"));
        // The L does not reach into the quarter (its centre is outside it).
        assert!(!contains(&left.outer, [0.00075, 0.00075]));
        assert!(contains(&left.outer, [0.00025, 0.00025]));
    }

    #[test]
    fn a_part_in_an_outlines_courtyard_leaves_the_outline_whole() {
        let (f, found) = footprints(&data(&SQUARE.replace(
            "<relation",
            r#"<way id="13"><nd ref="5"/><nd ref="6"/><nd ref="7"/><nd ref="8"/><nd ref="5"/><tag k="building:part" v="yes"/></way><relation"#,
        )));
        assert_eq!(
            f.iter().map(|f| f.id.as_str()).collect::<Vec<_>>(),
            ["relation/20", "way/13"]
        );
        assert_eq!(f[0].holes.len(), 1);
        assert_eq!((found.outlines_replaced, found.outlines_trimmed), (0, 0));
    }

    /// Two courtyards drawn along a common side (Monaco's relation 11384697, two pitches in a
    /// garden) are one hole around both, as libosmium assembles them (it was two holes).
    #[test]
    fn two_inner_rings_sharing_a_side_are_one_hole() {
        let two = SQUARE
            .replace(
                r#"<node id="8" lat="0.0006" lon="0.0004"/>"#,
                r#"<node id="8" lat="0.0006" lon="0.0004"/><node id="9" lat="0.0004" lon="0.0008"/><node id="15" lat="0.0006" lon="0.0008"/>"#,
            )
            .replace(
                r#"<way id="12">"#,
                r#"<way id="16"><nd ref="6"/><nd ref="9"/><nd ref="15"/><nd ref="7"/><nd ref="6"/></way><way id="12">"#,
            )
            .replace(
                r#"<member type="way" ref="12" role="inner"/>"#,
                r#"<member type="way" ref="12" role="inner"/><member type="way" ref="16" role="inner"/>"#,
            );
        let (f, found) = footprints(&data(&two));
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].holes.len(), 1, "{:?}", f[0].holes);
        assert_eq!(f[0].holes[0].len(), 6);
        assert!((area(&f[0].holes[0]) - 0.08e-6).abs() < 1e-15);
        assert_eq!(found.inner_rings, 1);
    }

    /// A part standing wholly inside its outline (Monaco's Tour Odeon, way 627772921, tagged
    /// both) leaves the outline's piece with a hole the part fills: counted as cut by the part,
    /// not as a courtyard (libosmium's inner rings: none).
    #[test]
    fn a_hole_a_part_cuts_is_not_a_courtyard() {
        let part = r#"<node id="50" lat="0.0004" lon="0.0004"/><node id="51" lat="0.0004" lon="0.0006"/>
          <node id="52" lat="0.0006" lon="0.0006"/><node id="53" lat="0.0006" lon="0.0004"/>
          <way id="31"><nd ref="50"/><nd ref="51"/><nd ref="52"/><nd ref="53"/><nd ref="50"/><tag k="building:part" v="yes"/></way>"#;
        let (f, found) = footprints(&data(&outline_with(part)));
        assert_eq!(f[0].holes.len(), 1);
        assert_eq!((found.inner_rings, found.holes_cut_by_parts), (0, 1));
        // A courtyard the outline keeps is not counted as cut.
        let (_, found) = footprints(&data(&SQUARE.replace(
            "<relation",
            r#"<node id="60" lat="0.0001" lon="0.0001"/><node id="61" lat="0.0001" lon="0.0002"/><node id="62" lat="0.0002" lon="0.0002"/>
               <way id="13"><nd ref="60"/><nd ref="61"/><nd ref="62"/><nd ref="60"/><tag k="building:part" v="yes"/></way><relation"#,
        )));
        assert_eq!((found.inner_rings, found.holes_cut_by_parts), (1, 1));
    }

    #[test]
    fn heights_and_positions_beyond_any_building_or_place_are_not_taken() {
        let tags = |t: &[(&str, &str)]| -> Tags {
            t.iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        let p = HeightPolicy::default();
        assert_eq!(
            heights(&tags(&[("height", "1e300")]), p),
            Some((0.0, 10.0, HeightSource::Default))
        );
        assert_eq!(
            heights(&tags(&[("height", "1e300"), ("building:levels", "1e9")]), p),
            Some((0.0, 10.0, HeightSource::Default))
        );
        let mut d = OsmData::default();
        insert_node(&mut d, 1, 200.0, 0.0);
        insert_node(&mut d, 2, 0.0, -91.0);
        insert_node(&mut d, 3, f64::NAN, 0.0);
        insert_node(&mut d, 4, 179.0, 89.0);
        assert_eq!(d.nodes.len(), 1);
    }

    #[test]
    fn bad_files_are_errors_not_panics() {
        assert!(parse_xml("<kml/>").is_err());
        assert!(parse_xml("not xml").is_err());
        assert!(parse_pbf(b"\0\0\0\x0dnot a pbf blob").is_err());
        assert!(parse_pbf(&[0xff; 64]).is_err());
        let broken = SQUARE.replace(r#"<member type="way" ref="10" role="outer"/>"#, "");
        let (f, found) = footprints(&data(&broken));
        assert!(f.is_empty());
        assert_eq!(found.broken_relations, 1);
    }
}
