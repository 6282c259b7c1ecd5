//! The air a vehicle flies in: its density with altitude.

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
    const EARTH_RADIUS_KM: f64 = 6356.766;
    let z_km = alt_m.clamp(-500.0, 11_000.0) / 1000.0;
    let h_km = z_km * EARTH_RADIUS_KM / (z_km + EARTH_RADIUS_KM);
    let theta = (288.15 - 6.5 * h_km) / 288.15;
    let pressure_pa = 101_325.0 * theta.powf(34.163_195 / 6.5);
    pressure_pa / (287.058 * (25.0 + 273.15))
}
