//! Named devices from their references (docs/sensors.md gives each number's source): the
//! specs a `preset` starts from.

use crate::sensors::spec::{DeviceSpec, MountSpec};

/// Every preset's name.
pub const NAMES: [&str; 15] = [
    "realsense-d435",
    "realsense-d435-depth",
    "realsense-d455-depth",
    "depth-160x120",
    "velodyne-vlp16",
    "ouster-os1-64",
    "rplidar-a2",
    "tfmini",
    "tfmini-down",
    "adsb-1090es",
    "adsb-uat",
    "radar-appq",
    "eoir-appq",
    "ideal-adsb",
    "gps-ins",
];

/// DO-365 Appendix Q's ADS-B reception: at least one report in 3 s (to 10 NM) and in 7 s (to
/// 20 NM) with chance 0.95; none beyond 20 NM.
const APPQ_RECEPTION: [[f64; 2]; 2] = [[18_520.0, 3.0], [37_040.0, 7.0]];

fn kind(k: &str, name: &str) -> DeviceSpec {
    DeviceSpec {
        name: Some(name.into()),
        kind: Some(k.into()),
        ..DeviceSpec::default()
    }
}

/// The spec of preset `name`.
pub fn spec(name: &str) -> Option<DeviceSpec> {
    range_device(name).or_else(|| surveillance_device(name))
}

/// The range devices: depth camera, lidar, single-beam rangefinders.
fn range_device(name: &str) -> Option<DeviceSpec> {
    Some(match name {
        // Intel RealSense D435 at 848 x 480 and 30 Hz: 87 x 58 degrees, 0.2 to 10 m, depth
        // RMS z^2 0.08 / (424 px 0.05 m); 2% of pixels invalid; rays every degree across and
        // every 9.7 degrees up-down (7 rows).
        "realsense-d435" => DeviceSpec {
            rate_hz: Some(30.0),
            latency_s: Some(0.03),
            fov_deg: Some([87.0, 58.0]),
            step_deg: Some([1.0, 58.0 / 6.0]),
            range_m: Some([0.2, 10.0]),
            stereo_subpixel_px: Some(0.08),
            stereo_focal_px: Some(424.0),
            stereo_baseline_m: Some(0.05),
            quantum_m: Some(0.001),
            invalid_ray: Some(0.02),
            ..kind("range", name)
        },
        // Slamtec RPLIDAR A2M8 at 10 Hz: 360 degrees every 0.45 degree, 0.15 to 12 m, 1% of
        // the distance.
        "rplidar-a2" => DeviceSpec {
            rate_hz: Some(10.0),
            latency_s: Some(0.1),
            fov_deg: Some([360.0, 0.0]),
            step_deg: Some([0.45, 0.0]),
            range_m: Some([0.15, 12.0]),
            proportional: Some(0.01),
            quantum_m: Some(0.001),
            ..kind("range", name)
        },
        // Benewake TFmini: one 2.3-degree beam, 0.3 to 12 m, 100 Hz, 1% of the distance,
        // 5 mm resolution; looking forward.
        "tfmini" => DeviceSpec {
            rate_hz: Some(100.0),
            latency_s: Some(0.01),
            beam_deg: Some(2.3),
            range_m: Some([0.3, 12.0]),
            proportional: Some(0.01),
            quantum_m: Some(0.005),
            ..kind("range", name)
        },
        // The same, looking down: a rangefinder.
        "tfmini-down" => DeviceSpec {
            mount: Some(MountSpec {
                pitch_deg: Some(-90.0),
                ..MountSpec::default()
            }),
            ..spec("tfmini")?
        }
        .named(name),
        _ => return image_or_lidar(name),
    })
}

/// The image devices (depth cameras) and the multi-channel lidars.
fn image_or_lidar(name: &str) -> Option<DeviceSpec> {
    Some(match name {
        // Intel RealSense D435's depth stream at 848 x 480 (Intel's best depth resolution for
        // it), 30 Hz: 87 x 58 degrees, 0.2 to 10 m; depth RMS z^2 0.08 / (focal 446.8 px x
        // 0.05 m), the focal length the image's own; 2% of pixels invalid; 1 mm steps.
        "realsense-d435-depth" => DeviceSpec {
            rate_hz: Some(30.0),
            latency_s: Some(0.03),
            image_px: Some([848, 480]),
            fov_deg: Some([87.0, 58.0]),
            range_m: Some([0.2, 10.0]),
            stereo_subpixel_px: Some(0.08),
            stereo_baseline_m: Some(0.05),
            quantum_m: Some(0.001),
            invalid_ray: Some(0.02),
            ..kind("range", name)
        },
        // Intel RealSense D455 at 848 x 480, 30 Hz: 87 x 58 degrees, 95 mm baseline, 0.4 to
        // 20 m.
        "realsense-d455-depth" => DeviceSpec {
            stereo_baseline_m: Some(0.095),
            range_m: Some([0.4, 20.0]),
            ..spec("realsense-d435-depth")?
        }
        .named(name),
        // A planner's input: the D435's 848 x 480 depth image decimated to 160 x 120, its
        // errors those of the full image (focal 446.8 px).
        "depth-160x120" => DeviceSpec {
            image_px: Some([160, 120]),
            stereo_focal_px: Some(crate::sensors::range::focal_px(848, 87.0)),
            ..spec("realsense-d435-depth")?
        }
        .named(name),
        // Velodyne VLP-16 at 10 Hz: 16 channels over +-15 degrees (2 degrees apart), every 0.2
        // degree around (28,800 points a turn, 288,000 a second); to 100 m (from 0.9 m, the
        // ROS driver's default), +-3 cm, 2 mm steps.
        "velodyne-vlp16" => DeviceSpec {
            rate_hz: Some(10.0),
            latency_s: Some(0.1),
            fov_deg: Some([360.0, 30.0]),
            step_deg: Some([0.2, 2.0]),
            channels: Some(16),
            range_m: Some([0.9, 100.0]),
            sigma_m: Some(0.03),
            quantum_m: Some(0.002),
            ..kind("range", name)
        },
        // Ouster OS1-64 (gen 1) at 1024 x 10 Hz: 64 channels over 33.2 degrees, 0.35 degree
        // around (655,360 points a second); 0.8 to 120 m, +-3 cm, 3 mm steps.
        "ouster-os1-64" => DeviceSpec {
            rate_hz: Some(10.0),
            latency_s: Some(0.1),
            fov_deg: Some([360.0, 33.2]),
            step_deg: Some([360.0 / 1024.0, 33.2 / 63.0]),
            channels: Some(64),
            range_m: Some([0.8, 120.0]),
            sigma_m: Some(0.03),
            quantum_m: Some(0.003),
            ..kind("range", name)
        },
        _ => return None,
    })
}

/// The surveillance devices (ADS-B, radar, EO/IR) and the ownship's navigation.
fn surveillance_device(name: &str) -> Option<DeviceSpec> {
    Some(match name {
        // 1090 MHz extended squitter: position and velocity twice a second, NACp 8, NACv 2,
        // errors correlated over 300 s, vertical rate Laplace 2.02 ft/s, altitude with its
        // Annex 10 altimetry bias in 25 ft steps, Appendix Q reception, up to 0.4 s late.
        "adsb-1090es" => DeviceSpec {
            rate_hz: Some(2.0),
            nacp: Some(8),
            nacv: Some(2),
            tau_s: Some(300.0),
            vertical_rate_b_mps: Some(2.0203 * 0.3048),
            annex10_altimetry: Some(true),
            altitude_quantum_ft: Some(25.0),
            reception: Some(APPQ_RECEPTION.to_vec()),
            latency_jitter_s: Some(0.4),
            ..kind("adsb", name)
        },
        // UAT (978 MHz): one report a second, otherwise as 1090ES.
        "adsb-uat" => DeviceSpec {
            rate_hz: Some(1.0),
            ..spec("adsb-1090es")?
        }
        .named(name),
        // ADS-B without errors: twice a second, on time, exact (reported as NACp 11, NACv 4),
        // every report received out to 20 NM.
        "ideal-adsb" => DeviceSpec {
            rate_hz: Some(2.0),
            nacp: Some(11),
            nacv: Some(4),
            tau_s: Some(0.0),
            position_sigma_m: Some(0.0),
            velocity_sigma_mps: Some(0.0),
            reception: Some(vec![[37_040.0, 1e-3]]),
            ..kind("adsb", name)
        },
        // Appendix Q's airborne radar: 1 Hz; range 21.34 m + bias 15.24 m, range rate 3.0 +
        // 2.4 m/s, angles 1.0 + 0.5 degrees; +-110 by +-15 degrees; out to 5.4 NM.
        "radar-appq" => DeviceSpec {
            rate_hz: Some(1.0),
            range_m: Some([0.0, 10_000.0]),
            field_of_regard_deg: Some([110.0, 15.0]),
            range_sigma_m: Some(21.34),
            range_bias_m: Some(15.24),
            range_rate_sigma_mps: Some(3.0),
            range_rate_bias_mps: Some(2.4),
            angle_sigma_deg: Some(1.0),
            angle_bias_deg: Some(0.5),
            ..kind("radar", name)
        },
        // Appendix Q's EO/IR: 10 Hz; angles 1 mrad; range 15.24 m + 3% of the range,
        // correlated over 5 s; out to 2.5 NM, all around.
        "eoir-appq" => DeviceSpec {
            rate_hz: Some(10.0),
            max_range_m: Some(4_630.0),
            angle_sigma_mrad: Some(1.0),
            range_tau_s: Some(5.0),
            range_sigma_m: Some(15.24),
            range_proportional: Some(0.03),
            ..kind("eoir", name)
        },
        // Appendix Q's ownship navigation (GPS/INS): NACp 8 and NACv 2 (37.8 m, 1.22 m/s),
        // correlated over 300 s, 10 Hz, always available; what a DAA system knows of its own
        // state (batch rows' sensed alerting).
        "gps-ins" => DeviceSpec {
            rate_hz: Some(10.0),
            nacp: Some(8),
            nacv: Some(2),
            tau_s: Some(300.0),
            altitude_quantum_ft: Some(1.0),
            reception: Some(vec![[1e6, 1e-3]]),
            ..kind("adsb", name)
        },
        _ => return None,
    })
}

impl DeviceSpec {
    fn named(self, name: &str) -> DeviceSpec {
        DeviceSpec {
            name: Some(name.into()),
            ..self
        }
    }
}
