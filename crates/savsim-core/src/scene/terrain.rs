//! Elevation files: SRTM `.hgt` tiles, geographic GeoTIFF DEMs and ArduPilot terrain `.DAT`
//! files, resampled onto a regular grid in the scene's ENU frame.
//!
//! SRTM: 1 or 3 arc-second tiles, big-endian i16 metres AMSL, row 0 at the north edge, the
//! file name giving the south-west corner (`N44W072.hgt`); voids (-32768) are filled from their
//! valid neighbours and counted, never read as heights. ArduPilot: the 2048-byte grid blocks
//! AP_Terrain keeps on its SD card (28 x 32 heights per block, blocks overlapping by one
//! sample), read and interpolated the way ArduPilot does, so a scene agrees with what SITL's
//! terrain following saw. Blocks never filled (all zero, or a bad CRC) are gaps: an area that
//! needs them is an error, not ground at 0 m.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use crate::geo::{Geodetic, LocalTangentPlane};
use crate::scene::geometry::HeightGrid;
use crate::scene::Files;

/// A source of ground heights, metres AMSL.
#[derive(Debug, Clone)]
pub enum Elevation {
    /// An SRTM tile or a geographic GeoTIFF DEM.
    Grid(LatLonGrid),
    /// An ArduPilot terrain file.
    ArduPilot(ArduPilotTerrain),
}

/// Why an elevation file could not be read or used.
#[derive(Debug, thiserror::Error)]
pub enum TerrainError {
    /// The file could not be read.
    #[error("{0}")]
    Read(std::io::Error),
    /// Not a kind of file savsim reads.
    #[error("{name}: expected an SRTM .hgt, a GeoTIFF .tif or an ArduPilot .DAT file")]
    Extension {
        /// The file's name.
        name: String,
    },
    /// An error in the file `name`.
    #[error("{name}: {error}")]
    Named {
        /// The file's name.
        name: String,
        /// What is wrong in it.
        error: Box<TerrainError>,
    },
    /// An SRTM tile whose name gives no corner.
    #[error("{name}: an SRTM file is named after its corner, like N44W072.hgt")]
    SrtmName {
        /// The file's name.
        name: String,
    },
    /// An SRTM tile of neither size.
    #[error("{name}: {bytes} bytes is neither a 3 arc-second (1201 x 1201) nor a 1 arc-second (3601 x 3601) tile")]
    SrtmSize {
        /// The file's name.
        name: String,
        /// Its length.
        bytes: usize,
    },
    /// A grid too small, or with the wrong number of samples.
    #[error("a {nx} x {ny} grid needs at least 2 x 2 samples")]
    GridSize {
        /// Columns.
        nx: usize,
        /// Rows.
        ny: usize,
    },
    /// The TIFF decoder's error.
    #[error("{0}")]
    Tiff(String),
    /// A TIFF that is not a DEM savsim reads.
    #[error("{0}")]
    GeoTiff(&'static str),
    /// An ArduPilot terrain file savsim cannot use.
    #[error("{0}")]
    ArduPilot(&'static str),
    /// A point of the area the file does not cover.
    #[error("no elevation data at {lat_deg:.6}, {lon_deg:.6} (E {east_m:.0} N {north_m:.0} m): the area is larger than the file covers")]
    Uncovered {
        /// Latitude, degrees.
        lat_deg: f64,
        /// Longitude, degrees.
        lon_deg: f64,
        /// East of the scene's origin, metres.
        east_m: f64,
        /// North of the scene's origin, metres.
        north_m: f64,
    },
}

impl Elevation {
    /// Read an elevation file through `files`, by its extension (`.hgt`, `.tif` or `.dat`,
    /// any case).
    pub fn read(path: &Path, files: &dyn Files) -> Result<Elevation, TerrainError> {
        let bytes = files.read(path).map_err(TerrainError::Read)?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "hgt" => parse_srtm(&name, &bytes).map(Elevation::Grid),
            "tif" | "tiff" => {
                parse_geotiff(&bytes)
                    .map(Elevation::Grid)
                    .map_err(|e| TerrainError::Named {
                        name,
                        error: Box::new(e),
                    })
            }
            "dat" => ArduPilotTerrain::parse(&bytes).map(Elevation::ArduPilot),
            _ => Err(TerrainError::Extension { name }),
        }
    }

    /// Ground height at a position, metres AMSL; `None` outside the data.
    pub fn height_amsl_m(&self, lat_deg: f64, lon_deg: f64) -> Option<f64> {
        match self {
            Elevation::Grid(t) => t.height_amsl_m(lat_deg, lon_deg),
            Elevation::ArduPilot(t) => t.height_amsl_m(lat_deg, lon_deg),
        }
    }

    /// The source's own sample spacing, metres (north-south, for latitude/longitude grids).
    pub fn spacing_m(&self) -> f64 {
        match self {
            Elevation::Grid(t) => 111_320.0 * t.dlat_deg,
            Elevation::ArduPilot(t) => f64::from(t.spacing_m),
        }
    }

    /// Voids filled (SRTM, GeoTIFF) when the file was read.
    pub fn voids_filled(&self) -> usize {
        match self {
            Elevation::Grid(t) => t.voids_filled,
            Elevation::ArduPilot(_) => 0,
        }
    }
}

/// Heights on a regular latitude/longitude grid (an SRTM tile, a geographic GeoTIFF).
#[derive(Debug, Clone)]
pub struct LatLonGrid {
    /// Samples along longitude.
    pub nx: usize,
    /// Samples along latitude.
    pub ny: usize,
    /// Longitude of sample column 0, degrees.
    pub lon0_deg: f64,
    /// Latitude of sample row 0 (the northern edge), degrees.
    pub lat0_deg: f64,
    /// Degrees between columns.
    pub dlon_deg: f64,
    /// Degrees between rows (southwards).
    pub dlat_deg: f64,
    heights_m: Vec<f32>,
    /// Void samples that were filled from neighbours.
    pub voids_filled: usize,
}

impl LatLonGrid {
    /// A grid from row-major heights, north row first; NaN marks voids, which are filled.
    pub fn new(
        nx: usize,
        ny: usize,
        (lat0_deg, lon0_deg): (f64, f64),
        (dlat_deg, dlon_deg): (f64, f64),
        mut heights_m: Vec<f32>,
    ) -> Result<LatLonGrid, TerrainError> {
        if nx < 2 || ny < 2 || heights_m.len() != nx * ny {
            return Err(TerrainError::GridSize { nx, ny });
        }
        let voids_filled = fill_voids(&mut heights_m, nx, ny);
        Ok(LatLonGrid {
            nx,
            ny,
            lon0_deg,
            lat0_deg,
            dlon_deg,
            dlat_deg,
            heights_m,
            voids_filled,
        })
    }

    /// Bilinear height at a position, metres; `None` outside the grid.
    pub fn height_amsl_m(&self, lat_deg: f64, lon_deg: f64) -> Option<f64> {
        let fx = (lon_deg - self.lon0_deg) / self.dlon_deg;
        let fy = (self.lat0_deg - lat_deg) / self.dlat_deg;
        let (mx, my) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        if !(0.0..=mx).contains(&fx) || !(0.0..=my).contains(&fy) {
            return None;
        }
        let (ix, iy) = (
            (fx as usize).min(self.nx - 2),
            (fy as usize).min(self.ny - 2),
        );
        let (u, v) = (fx - ix as f64, fy - iy as f64);
        let h = |x: usize, y: usize| f64::from(self.heights_m[y * self.nx + x]);
        let top = h(ix, iy) * (1.0 - u) + h(ix + 1, iy) * u;
        let bottom = h(ix, iy + 1) * (1.0 - u) + h(ix + 1, iy + 1) * u;
        Some(top * (1.0 - v) + bottom * v)
    }
}

/// The SRTM void marker.
pub const SRTM_VOID: i16 = -32768;

/// Parse an SRTM tile; `name` is its file name (it carries the corner).
///
/// ```
/// use savsim_core::scene::terrain::parse_srtm;
/// // A 1201 x 1201 tile of flat 100 m with one void.
/// let mut bytes: Vec<u8> = (0..1201 * 1201).flat_map(|_| 100i16.to_be_bytes()).collect();
/// bytes[2 * 600_000..2 * 600_000 + 2].copy_from_slice(&(-32768i16).to_be_bytes());
/// let t = parse_srtm("S36E149.hgt", &bytes).unwrap();
/// assert_eq!((t.lat0_deg, t.lon0_deg, t.voids_filled), (-35.0, 149.0, 1));
/// assert_eq!(t.height_amsl_m(-35.5, 149.5), Some(100.0));
/// assert_eq!(t.height_amsl_m(-34.5, 149.5), None);
/// ```
pub fn parse_srtm(name: &str, bytes: &[u8]) -> Result<LatLonGrid, TerrainError> {
    let upper = name.to_ascii_uppercase();
    // The corner is the first N/S dd E/W ddd in the name (`N44W072.hgt`, `srtm3_N44W072.hgt`).
    let parse_at = |i: usize| -> Option<(i32, i32)> {
        let t = upper.get(i..i + 7)?;
        let lat: i32 = t.get(1..3)?.parse().ok()?;
        let lon: i32 = t.get(4..7)?.parse().ok()?;
        let lat = match &t[0..1] {
            "N" => lat,
            "S" => -lat,
            _ => return None,
        };
        let lon = match &t[3..4] {
            "E" => lon,
            "W" => -lon,
            _ => return None,
        };
        Some((lat, lon))
    };
    let (lat, lon) = (0..upper.len())
        .find_map(parse_at)
        .ok_or_else(|| TerrainError::SrtmName { name: name.into() })?;
    let size = match bytes.len() {
        n if n == 1201 * 1201 * 2 => 1201,
        n if n == 3601 * 3601 * 2 => 3601,
        n => {
            return Err(TerrainError::SrtmSize {
                name: name.into(),
                bytes: n,
            })
        }
    };
    let heights_m = bytes
        .chunks_exact(2)
        .map(|b| match i16::from_be_bytes([b[0], b[1]]) {
            SRTM_VOID => f32::NAN,
            h => f32::from(h),
        })
        .collect();
    let step = 1.0 / (size - 1) as f64;
    LatLonGrid::new(
        size,
        size,
        (f64::from(lat) + 1.0, f64::from(lon)),
        (step, step),
        heights_m,
    )
}

/// Parse a GeoTIFF DEM in geographic coordinates (longitude, latitude degrees; e.g. EPSG:4326):
/// one band of integer or float heights, georeferenced by ModelTiepoint and ModelPixelScale,
/// no-data from GDAL_NODATA and NaN (filled like SRTM voids).
pub fn parse_geotiff(bytes: &[u8]) -> Result<LatLonGrid, TerrainError> {
    use tiff::decoder::{Decoder, DecodingResult};
    use tiff::tags::Tag;
    let tiff = |e: tiff::TiffError| TerrainError::Tiff(e.to_string());
    let mut d = Decoder::new(std::io::Cursor::new(bytes)).map_err(tiff)?;
    let (w, h) = d.dimensions().map_err(tiff)?;
    let (nx, ny) = (w as usize, h as usize);
    let scale = d.get_tag_f64_vec(Tag::ModelPixelScaleTag).map_err(|_| {
        TerrainError::GeoTiff("no ModelPixelScale tag: not a georeferenced GeoTIFF")
    })?;
    let tie = d
        .get_tag_f64_vec(Tag::ModelTiepointTag)
        .map_err(|_| TerrainError::GeoTiff("no ModelTiepoint tag: not a georeferenced GeoTIFF"))?;
    if scale.len() < 2 || tie.len() < 6 || scale[0] <= 0.0 || scale[1] <= 0.0 {
        return Err(TerrainError::GeoTiff(
            "ModelPixelScale / ModelTiepoint are malformed",
        ));
    }
    let keys = d
        .get_tag_u16_vec(Tag::GeoKeyDirectoryTag)
        .unwrap_or_default();
    let key = |id: u16| {
        keys.chunks_exact(4)
            .skip(1)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    };
    // GTModelTypeGeoKey (1024): 2 = geographic. GTRasterTypeGeoKey (1025): 1 area, 2 point.
    if key(1024).is_some_and(|t| t != 2) {
        return Err(TerrainError::GeoTiff("a projected GeoTIFF: savsim reads geographic (longitude/latitude) DEMs; reproject it to EPSG:4326"));
    }
    let centre = if key(1025) == Some(2) { 0.0 } else { 0.5 };
    let nodata: Option<f64> = match d.get_tag(Tag::GdalNodata) {
        Ok(v) => v
            .into_string()
            .ok()
            .and_then(|s| s.trim().trim_end_matches('\0').parse().ok()),
        Err(_) => None,
    };
    let values: Vec<f64> = match d.read_image().map_err(tiff)? {
        DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F64(v) => v,
        _ => {
            return Err(TerrainError::GeoTiff(
                "unsupported sample type (use 16/32-bit integers or floats)",
            ))
        }
    };
    if values.len() != nx * ny {
        return Err(TerrainError::GeoTiff(
            "more than one band: savsim reads single-band DEMs",
        ));
    }
    let heights = values
        .into_iter()
        .map(|v| {
            if Some(v) == nodata || !v.is_finite() {
                f32::NAN
            } else {
                v as f32
            }
        })
        .collect();
    let lon0 = tie[3] + (centre - tie[0]) * scale[0];
    let lat0 = tie[4] - (centre - tie[1]) * scale[1];
    LatLonGrid::new(nx, ny, (lat0, lon0), (scale[1], scale[0]), heights)
}

/// Replace voids (NaN) with the mean of their valid neighbours, growing inwards until none is
/// left (a grid that is all void becomes 0). Returns how many were filled.
fn fill_voids(heights: &mut [f32], nx: usize, ny: usize) -> usize {
    let total = heights.iter().filter(|h| h.is_nan()).count();
    if total == heights.len() {
        heights.fill(0.0);
        return total;
    }
    let mut left = total;
    while left > 0 {
        let snapshot = heights.to_vec();
        for y in 0..ny {
            for x in 0..nx {
                if !snapshot[y * nx + x].is_nan() {
                    continue;
                }
                let neighbours = [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                    .iter()
                    .filter_map(|(dx, dy)| {
                        let (x, y) = (x as i64 + dx, y as i64 + dy);
                        (x >= 0 && y >= 0 && x < nx as i64 && y < ny as i64)
                            .then(|| snapshot[y as usize * nx + x as usize])
                    })
                    .filter(|h| !h.is_nan());
                let (sum, n) =
                    neighbours.fold((0.0f64, 0u32), |(s, n), h| (s + f64::from(h), n + 1));
                if n > 0 {
                    heights[y * nx + x] = (sum / f64::from(n)) as f32;
                    left -= 1;
                }
            }
        }
    }
    total
}

/// ArduPilot's grid geometry (AP_Terrain.h).
const BLOCK_SIZE_X: usize = 28; // north
const BLOCK_SIZE_Y: usize = 32; // east
const BLOCK_SPACING_X: u32 = 24;
const BLOCK_SPACING_Y: u32 = 28;
const IO_BLOCK_SIZE: usize = 2048;
const IO_BLOCK_DATA_SIZE: usize = 1821;
/// ArduPilot's metres per 1e-7 degree of latitude, and its inverse (as f32, like the firmware).
const LOCATION_SCALING_FACTOR: f64 = 0.011_131_884_502_145_034;

/// One 28 (north) x 32 (east) block.
#[derive(Debug, Clone)]
struct Block {
    heights_m: Vec<i16>,
}

/// An ArduPilot terrain file (one degree square at its `lat_degrees`, `lon_degrees`).
#[derive(Debug, Clone)]
pub struct ArduPilotTerrain {
    /// Grid spacing, metres.
    pub spacing_m: u16,
    /// The degree square's south-west corner.
    pub lat_degrees: i32,
    /// The degree square's south-west corner.
    pub lon_degrees: i32,
    blocks: HashMap<(u32, u32), Block>,
    /// Blocks in the file that were empty or failed their CRC.
    pub skipped_blocks: usize,
}

fn longitude_scale(lat_deg: f64) -> f64 {
    (lat_deg.to_radians().cos() as f32 as f64).max(0.01)
}

impl ArduPilotTerrain {
    /// Parse the blocks of a `.DAT` file.
    pub fn parse(bytes: &[u8]) -> Result<ArduPilotTerrain, TerrainError> {
        let mut blocks = HashMap::new();
        let mut skipped_blocks = 0;
        let mut meta: Option<(u16, i32, i32)> = None;
        for raw in bytes.chunks(IO_BLOCK_SIZE) {
            if raw.len() < IO_BLOCK_DATA_SIZE {
                skipped_blocks += 1;
                continue;
            }
            let u16_at = |i: usize| u16::from_le_bytes([raw[i], raw[i + 1]]);
            let (crc, version, spacing) = (u16_at(16), u16_at(18), u16_at(20));
            if version != 1 || spacing == 0 {
                skipped_blocks += 1;
                continue;
            }
            let mut zeroed = raw[..IO_BLOCK_DATA_SIZE].to_vec();
            zeroed[16] = 0;
            zeroed[17] = 0;
            if crc16_xmodem(&zeroed) != crc {
                skipped_blocks += 1;
                continue;
            }
            let tail = 22 + 2 * BLOCK_SIZE_X * BLOCK_SIZE_Y;
            let grid_idx_x = u32::from(u16_at(tail));
            let grid_idx_y = u32::from(u16_at(tail + 2));
            let lon_degrees = i32::from(i16::from_le_bytes([raw[tail + 4], raw[tail + 5]]));
            let lat_degrees = i32::from(raw[tail + 6] as i8);
            match meta {
                None => meta = Some((spacing, lat_degrees, lon_degrees)),
                Some(m) if m != (spacing, lat_degrees, lon_degrees) => {
                    return Err(TerrainError::ArduPilot(
                        "blocks of different spacings or degree squares in one file",
                    ))
                }
                Some(_) => {}
            }
            let heights_m = raw[22..tail]
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]]))
                .collect();
            blocks.insert((grid_idx_x, grid_idx_y), Block { heights_m });
        }
        let (spacing_m, lat_degrees, lon_degrees) = meta.ok_or(TerrainError::ArduPilot(
            "no filled terrain block in the file",
        ))?;
        Ok(ArduPilotTerrain {
            spacing_m,
            lat_degrees,
            lon_degrees,
            blocks,
            skipped_blocks,
        })
    }

    /// Filled blocks.
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Height as AP_Terrain::height_amsl computes it: offsets from the degree corner with
    /// ArduPilot's flat-earth scaling, then bilinear within one block.
    pub fn height_amsl_m(&self, lat_deg: f64, lon_deg: f64) -> Option<f64> {
        let ref_lat_e7 = f64::from(self.lat_degrees) * 1e7;
        let ref_lon_e7 = f64::from(self.lon_degrees) * 1e7;
        let (lat_e7, lon_e7) = (lat_deg * 1e7, lon_deg * 1e7);
        let north_m = (lat_e7 - ref_lat_e7) * LOCATION_SCALING_FACTOR;
        let east_m = (lon_e7 - ref_lon_e7)
            * LOCATION_SCALING_FACTOR
            * longitude_scale((lat_e7 + ref_lat_e7) * 0.5 * 1e-7);
        if north_m < 0.0 || east_m < 0.0 {
            return None;
        }
        let spacing = f64::from(self.spacing_m);
        let (idx_x, idx_y) = ((north_m / spacing) as u32, (east_m / spacing) as u32);
        let block = self
            .blocks
            .get(&(idx_x / BLOCK_SPACING_X, idx_y / BLOCK_SPACING_Y))?;
        let (ix, iy) = (
            (idx_x % BLOCK_SPACING_X) as usize,
            (idx_y % BLOCK_SPACING_Y) as usize,
        );
        let frac_x = (north_m - f64::from(idx_x) * spacing) / spacing;
        let frac_y = (east_m - f64::from(idx_y) * spacing) / spacing;
        let h = |x: usize, y: usize| f64::from(block.heights_m[x * BLOCK_SIZE_Y + y]);
        let h00 = h(ix, iy);
        let h01 = h(ix, iy + 1);
        let h10 = h(ix + 1, iy);
        let h11 = h(ix + 1, iy + 1);
        let avg1 = (1.0 - frac_x) * h00 + frac_x * h10;
        let avg2 = (1.0 - frac_x) * h01 + frac_x * h11;
        Some((1.0 - frac_y) * avg1 + frac_y * avg2)
    }
}

/// CRC-16/XMODEM (the checksum of ArduPilot's terrain blocks).
fn crc16_xmodem(data: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &b in data {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Sample `elevation` on a regular grid of the scene's ENU plane: `size_m` (east, north) with
/// its south-west corner at `corner_enu_m`, every `cell_m`. Heights are the ENU up coordinate
/// of the ground (so the earth's curvature is in them). Fails naming the first point the data
/// does not cover.
pub fn resample(
    elevation: &Elevation,
    plane: &LocalTangentPlane,
    corner_enu_m: DVec3,
    size_m: [f64; 2],
    cell_m: f64,
) -> Result<HeightGrid, TerrainError> {
    let nx = (size_m[0] / cell_m).round() as usize + 1;
    let ny = (size_m[1] / cell_m).round() as usize + 1;
    let mut heights_m = Vec::with_capacity(nx * ny);
    for iy in 0..ny {
        for ix in 0..nx {
            let p = corner_enu_m + DVec3::new(ix as f64 * cell_m, iy as f64 * cell_m, 0.0);
            let g = plane.geodetic_from_enu_m(DVec3::new(p.x, p.y, 0.0));
            let h =
                elevation
                    .height_amsl_m(g.lat_deg, g.lon_deg)
                    .ok_or(TerrainError::Uncovered {
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        east_m: p.x,
                        north_m: p.y,
                    })?;
            let ground = plane.enu_m_from_geodetic(&Geodetic::new(g.lat_deg, g.lon_deg, h));
            heights_m.push((ground.z - corner_enu_m.z) as f32);
        }
    }
    Ok(HeightGrid {
        nx,
        ny,
        cell_m: cell_m as f32,
        heights_m,
    })
}
