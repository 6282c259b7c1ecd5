//! The air a vehicle flies in: its pressure and density with altitude.

/// Air density at `alt_m` metres above mean sea level, kg/m^3: the International Standard
/// Atmosphere's pressure (troposphere, geopotential altitude) over the gas constant of dry air
/// times a fixed 25 degrees C, as ArduPilot's SITL multicopter takes it (its thrust and drag are
/// calibrated at that temperature). Altitudes are held to -500 .. 11000 m.
///
/// ```
/// use savsim_core::dynamics::air::density_kgpm3;
/// assert!((density_kgpm3(0.0) - 1.1839).abs() < 1e-3);
/// assert!((density_kgpm3(593.0) - 1.1022).abs() < 1e-3);
/// ```
pub fn density_kgpm3(alt_m: f64) -> f64 {
    pressure_pa(alt_m) / (287.058 * (25.0 + 273.15))
}

/// Static pressure at `alt_m` metres above mean sea level, pascals: the International Standard
/// Atmosphere's troposphere (geopotential altitude), altitudes held to -500 .. 11000 m.
///
/// ```
/// use savsim_core::dynamics::air::pressure_pa;
/// assert!((pressure_pa(0.0) - 101_325.0).abs() < 1e-6);
/// assert!((pressure_pa(1000.0) - 89_876.0).abs() < 5.0);
/// ```
pub fn pressure_pa(alt_m: f64) -> f64 {
    const EARTH_RADIUS_KM: f64 = 6356.766;
    let z_km = alt_m.clamp(-500.0, 11_000.0) / 1000.0;
    let h_km = z_km * EARTH_RADIUS_KM / (z_km + EARTH_RADIUS_KM);
    let theta = (288.15 - 6.5 * h_km) / 288.15;
    101_325.0 * theta.powf(34.163_195 / 6.5)
}
