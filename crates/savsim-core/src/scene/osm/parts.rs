//! An outline and its `building:part`s: the outline keeps the volume its parts leave uncovered
//! (polygon boolean operations of the `geo` crate in the plane of lon and lat), the slivers
//! of parts drawn a hair inside their outline left out.

use super::{Assembly, Footprint};

/// Replace each outline by what its `building:part`s leave of it: the outline's area minus the
/// union of every part whose box meets its box (`geo`'s boolean operations, in the plane of
/// lon and lat, exact where rings share nodes). An outline the parts cover entirely is dropped
/// (its volume is the parts'), one they do not touch is kept as it is, and one they cover in
/// part is kept as the pieces they leave, each with the outline's tags (`ID/k` after the
/// first). Pieces thinner than [`SLIVER_WIDTH_M`] on average (twice the area over the
/// perimeter) or smaller than [`SLIVER_AREA_M2`], the seams of parts drawn a hair inside
/// their outline, are left out and counted.
pub(super) fn prefer_parts(footprints: Vec<Footprint>, found: &mut Assembly) -> Vec<Footprint> {
    use geo::{BooleanOps, BoundingRect};
    let (parts, outlines): (Vec<Footprint>, Vec<Footprint>) =
        footprints.into_iter().partition(|f| f.part);
    let part_shapes: Vec<geo::Polygon> = parts.iter().map(polygon).collect();
    let tree = rstar::RTree::bulk_load(
        part_shapes
            .iter()
            .enumerate()
            .filter_map(|(k, p)| Some(PartBox::new(k, p.bounding_rect()?)))
            .collect(),
    );
    let mut out = Vec::with_capacity(outlines.len() + parts.len());
    for outline in outlines {
        let shape = polygon(&outline);
        let Some(rect) = shape.bounding_rect() else {
            continue;
        };
        let near: Vec<geo::Polygon> = tree
            .locate_in_envelope_intersecting(&envelope(rect))
            .map(|b| part_shapes[b.index].clone())
            .collect();
        if near.is_empty() {
            out.push(outline);
            continue;
        }
        let left = shape.difference(&geo::MultiPolygon::new(near));
        let scale = metres_per_degree(&outline.outer);
        let (kept, slivers): (Vec<geo::Polygon>, Vec<geo::Polygon>) =
            left.into_iter().partition(|piece| !is_sliver(piece, scale));
        found.slivers_dropped += slivers.len();
        if kept.is_empty() {
            found.outlines_replaced += 1;
        } else if kept.len() == 1 && slivers.is_empty() && same_area(&kept[0], &shape) {
            out.push(outline);
        } else {
            found.outlines_trimmed += 1;
            found.holes_cut_by_parts += kept
                .iter()
                .flat_map(|piece| piece.interiors())
                .filter(|hole| !outline.holes.iter().any(|h| same_ring_area(h, hole)))
                .count();
            out.extend(kept.iter().enumerate().map(|(k, piece)| Footprint {
                id: if k == 0 {
                    outline.id.clone()
                } else {
                    format!("{}/{k}", outline.id)
                },
                outer: ring_points(piece.exterior()),
                holes: piece.interiors().iter().map(ring_points).collect(),
                tags: outline.tags.clone(),
                part: false,
            }));
        }
    }
    out.extend(parts);
    out
}

/// Whether a piece's hole is one of its outline's own courtyards (the same area, in the plane
/// of lon and lat, within a millionth): the boolean operations may start a ring elsewhere.
fn same_ring_area(courtyard: &[[f64; 2]], hole: &geo::LineString) -> bool {
    use geo::Area;
    let a = geo::Polygon::new(
        geo::LineString::from(courtyard.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>()),
        Vec::new(),
    )
    .unsigned_area();
    let b = geo::Polygon::new(hole.clone(), Vec::new()).unsigned_area();
    (a - b).abs() <= 1e-6 * a.max(b)
}

/// An outline's piece is a sliver below this mean width (2 x area / perimeter), metres.
pub const SLIVER_WIDTH_M: f64 = 0.2;

/// ... or below this area, square metres.
pub const SLIVER_AREA_M2: f64 = 0.5;

/// A part's box in the R-tree, by its index among the parts.
struct PartBox {
    index: usize,
    envelope: rstar::AABB<[f64; 2]>,
}

impl PartBox {
    fn new(index: usize, rect: geo::Rect) -> Self {
        Self {
            index,
            envelope: envelope(rect),
        }
    }
}

impl rstar::RTreeObject for PartBox {
    type Envelope = rstar::AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        self.envelope
    }
}

fn envelope(rect: geo::Rect) -> rstar::AABB<[f64; 2]> {
    rstar::AABB::from_corners([rect.min().x, rect.min().y], [rect.max().x, rect.max().y])
}

/// A footprint as a `geo` polygon (lon, lat).
fn polygon(f: &Footprint) -> geo::Polygon {
    let ring = |points: &[[f64; 2]]| {
        geo::LineString::from(points.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>())
    };
    geo::Polygon::new(ring(&f.outer), f.holes.iter().map(|h| ring(h)).collect())
}

/// A `geo` ring as footprint points: closed, the first point not repeated.
fn ring_points(ring: &geo::LineString) -> Vec<[f64; 2]> {
    let mut points: Vec<[f64; 2]> = ring.coords().map(|c| [c.x, c.y]).collect();
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    points
}

/// Metres per degree of longitude and of latitude at a ring (its first point), spherical.
fn metres_per_degree(ring: &[[f64; 2]]) -> (f64, f64) {
    let lat = ring.first().map_or(0.0, |p| p[1]);
    let m = 6_371_008.8_f64.to_radians();
    (m * lat.to_radians().cos(), m)
}

fn is_sliver(piece: &geo::Polygon, (kx, ky): (f64, f64)) -> bool {
    use geo::Area;
    let area_m2 = piece.unsigned_area() * kx * ky;
    let perimeter_m: f64 = std::iter::once(piece.exterior())
        .chain(piece.interiors())
        .flat_map(|r| r.lines())
        .map(|l| ((l.dx() * kx).powi(2) + (l.dy() * ky).powi(2)).sqrt())
        .sum();
    area_m2 < SLIVER_AREA_M2 || 2.0 * area_m2 < SLIVER_WIDTH_M * perimeter_m
}

fn same_area(a: &geo::Polygon, b: &geo::Polygon) -> bool {
    use geo::Area;
    let (x, y) = (a.unsigned_area(), b.unsigned_area());
    (x - y).abs() <= 1e-9 * y.max(f64::MIN_POSITIVE)
}
