//! A device as written built into a device: its preset resolved under it, every field checked
//! (each error names the device and the field), the model of its kind made.

use crate::bounds::shown;
use crate::sensors::device::{
    nacp_bound95_m, nacv_bound95_mps, AdsbModel, Burst, Device, EoIrModel, Model, Mount,
    RadarModel, RangeModel, Reception, Stereo,
};
use crate::sensors::errors::{sigma_from_bound95, GaussMarkov};
use crate::sensors::presets;
use crate::sensors::range::focal_px;
use crate::sensors::spec::{DeviceSpec, MountSpec, SpecError};

/// The kind a spec makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Range,
    Adsb,
    Radar,
    EoIr,
}

/// `DeviceSpec { f: a.f.or(b.f), ... }` for every listed field.
macro_rules! each_or {
    ($a:ident, $b:ident; $($f:ident),* $(,)?) => {
        DeviceSpec { $($f: $a.$f.or($b.$f)),* }
    };
}

impl DeviceSpec {
    /// This spec over its preset's (the fields it sets win), or itself without one.
    fn resolved(&self) -> Result<DeviceSpec, SpecError> {
        let Some(name) = &self.preset else {
            return Ok(self.clone());
        };
        let base = presets::spec(name).ok_or_else(|| SpecError {
            device: self.name.clone().unwrap_or_else(|| name.clone()),
            field: "preset",
            why: format!("{name:?} is not a preset ({})", presets::NAMES.join(", ")),
        })?;
        Ok(self.clone().over(base))
    }

    /// The fields of `self`, and `base`'s where `self` has none (a mount field by field).
    fn over(self, base: DeviceSpec) -> DeviceSpec {
        let mount = match (&self.mount, &base.mount) {
            (Some(m), Some(b)) => Some(MountSpec {
                position_frd_m: m.position_frd_m.or(b.position_frd_m),
                yaw_deg: m.yaw_deg.or(b.yaw_deg),
                pitch_deg: m.pitch_deg.or(b.pitch_deg),
            }),
            (m, b) => m.clone().or(b.clone()),
        };
        let (a, b) = (self, base);
        let mut out = each_or!(a, b;
            name, preset, kind, mount, rate_hz, latency_s, fov_deg, step_deg, beam_deg, image_px,
            channels, range_m,
            sigma_m, proportional, stereo_subpixel_px, stereo_focal_px, stereo_baseline_m, bias_m,
            markov_sigma_m, markov_tau_s, quantum_m, dropout, burst_enter, burst_mean_readings,
            invalid_ray, false_return, nacp, nacv, tau_s, position_sigma_m, velocity_sigma_mps,
            vertical_rate_b_mps, annex10_altimetry,
            altitude_quantum_ft, reception, latency_jitter_s, field_of_regard_deg, range_sigma_m,
            range_bias_m, range_rate_sigma_mps, range_rate_bias_mps, angle_sigma_deg,
            angle_bias_deg, max_range_m, angle_sigma_mrad, range_tau_s, range_proportional,
        );
        out.mount = mount;
        out
    }

    /// The device this spec (over its preset) defines, or the first field that is wrong.
    pub fn build(&self) -> Result<Device, SpecError> {
        let s = self.resolved()?;
        let device = s
            .name
            .clone()
            .or_else(|| s.preset.clone())
            .unwrap_or_else(|| "sensor".into());
        let check = Check { device: &device };
        let kind = match s.kind.as_deref() {
            Some("range") => Kind::Range,
            Some("adsb") => Kind::Adsb,
            Some("radar") => Kind::Radar,
            Some("eoir") => Kind::EoIr,
            Some(other) => {
                return Err(check.err(
                    "kind",
                    format!("{other:?}: give range, adsb, radar or eoir"),
                ))
            }
            None => {
                return Err(check.err(
                    "kind",
                    "give a preset, or a kind: range, adsb, radar or eoir".into(),
                ))
            }
        };
        check.only_for(&s, kind)?;
        let mount = s.mount.clone().unwrap_or_default();
        let position = mount.position_frd_m.unwrap_or([0.0; 3]);
        for v in position {
            check.number("mount.position_frd_m", v, -100.0, 100.0)?;
        }
        let mount = Mount {
            position_frd_m: position,
            yaw_deg: check.number("mount.yaw_deg", mount.yaw_deg.unwrap_or(0.0), -360.0, 360.0)?,
            pitch_deg: check.number(
                "mount.pitch_deg",
                mount.pitch_deg.unwrap_or(0.0),
                -90.0,
                90.0,
            )?,
        };
        let rate_hz = check.required("rate_hz", s.rate_hz)?;
        if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1000.0) {
            return Err(check.err(
                "rate_hz",
                format!(
                    "{}: give more than 0 and at most 1000 per second",
                    shown(rate_hz)
                ),
            ));
        }
        let latency_s = check.number("latency_s", s.latency_s.unwrap_or(0.0), 0.0, 60.0)?;
        let model = match kind {
            Kind::Range => Model::Range(range_model(&s, &check)?),
            Kind::Adsb => Model::Adsb(adsb_model(&s, &check)?),
            Kind::Radar => Model::Radar(radar_model(&s, &check)?),
            Kind::EoIr => Model::EoIr(eoir_model(&s, &check)?),
        };
        Ok(Device {
            name: device,
            mount,
            rate_hz,
            latency_s,
            model,
        })
    }
}

/// Checks of one device's fields, naming it in their errors.
struct Check<'a> {
    device: &'a str,
}

impl Check<'_> {
    fn err(&self, field: &'static str, why: String) -> SpecError {
        SpecError {
            device: self.device.to_owned(),
            field,
            why,
        }
    }

    /// `v` if it is a number within `lo..=hi`.
    fn number(&self, field: &'static str, v: f64, lo: f64, hi: f64) -> Result<f64, SpecError> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(self.err(
                field,
                format!("{}: give a number from {lo} to {hi}", shown(v)),
            ))
        }
    }

    /// A chance: 0 to 1.
    fn chance(&self, field: &'static str, v: Option<f64>) -> Result<f64, SpecError> {
        self.number(field, v.unwrap_or(0.0), 0.0, 1.0)
    }

    fn required<T>(&self, field: &'static str, v: Option<T>) -> Result<T, SpecError> {
        v.ok_or_else(|| self.err(field, "missing (no preset gives it)".into()))
    }

    /// Fields that belong to another kind are errors.
    fn only_for(&self, s: &DeviceSpec, kind: Kind) -> Result<(), SpecError> {
        let range = [
            ("fov_deg", s.fov_deg.is_some()),
            ("step_deg", s.step_deg.is_some()),
            ("beam_deg", s.beam_deg.is_some()),
            ("image_px", s.image_px.is_some()),
            ("channels", s.channels.is_some()),
            ("sigma_m", s.sigma_m.is_some()),
            ("proportional", s.proportional.is_some()),
            ("stereo_subpixel_px", s.stereo_subpixel_px.is_some()),
            ("stereo_focal_px", s.stereo_focal_px.is_some()),
            ("stereo_baseline_m", s.stereo_baseline_m.is_some()),
            ("bias_m", s.bias_m.is_some()),
            ("markov_sigma_m", s.markov_sigma_m.is_some()),
            ("markov_tau_s", s.markov_tau_s.is_some()),
            ("quantum_m", s.quantum_m.is_some()),
            ("dropout", s.dropout.is_some()),
            ("burst_enter", s.burst_enter.is_some()),
            ("burst_mean_readings", s.burst_mean_readings.is_some()),
            ("invalid_ray", s.invalid_ray.is_some()),
            ("false_return", s.false_return.is_some()),
        ];
        let adsb = [
            ("nacp", s.nacp.is_some()),
            ("nacv", s.nacv.is_some()),
            ("tau_s", s.tau_s.is_some()),
            ("position_sigma_m", s.position_sigma_m.is_some()),
            ("velocity_sigma_mps", s.velocity_sigma_mps.is_some()),
            ("vertical_rate_b_mps", s.vertical_rate_b_mps.is_some()),
            ("annex10_altimetry", s.annex10_altimetry.is_some()),
            ("altitude_quantum_ft", s.altitude_quantum_ft.is_some()),
            ("reception", s.reception.is_some()),
            ("latency_jitter_s", s.latency_jitter_s.is_some()),
        ];
        let radar = [
            ("range_bias_m", s.range_bias_m.is_some()),
            ("range_rate_sigma_mps", s.range_rate_sigma_mps.is_some()),
            ("range_rate_bias_mps", s.range_rate_bias_mps.is_some()),
            ("angle_sigma_deg", s.angle_sigma_deg.is_some()),
            ("angle_bias_deg", s.angle_bias_deg.is_some()),
        ];
        let eoir = [
            ("max_range_m", s.max_range_m.is_some()),
            ("angle_sigma_mrad", s.angle_sigma_mrad.is_some()),
            ("range_tau_s", s.range_tau_s.is_some()),
            ("range_proportional", s.range_proportional.is_some()),
        ];
        let shared = [
            ("range_m", s.range_m.is_some(), [Kind::Range, Kind::Radar]),
            (
                "field_of_regard_deg",
                s.field_of_regard_deg.is_some(),
                [Kind::Radar, Kind::EoIr],
            ),
            (
                "range_sigma_m",
                s.range_sigma_m.is_some(),
                [Kind::Radar, Kind::EoIr],
            ),
        ];
        let groups: [(&[(&'static str, bool)], Kind); 4] = [
            (&range, Kind::Range),
            (&adsb, Kind::Adsb),
            (&radar, Kind::Radar),
            (&eoir, Kind::EoIr),
        ];
        for (fields, k) in groups {
            if k != kind {
                if let Some((f, _)) = fields.iter().find(|(_, set)| *set) {
                    return Err(self.err(f, format!("not a setting of a {kind:?} device")));
                }
            }
        }
        for (f, set, kinds) in shared {
            if set && !kinds.contains(&kind) {
                return Err(self.err(f, format!("not a setting of a {kind:?} device")));
            }
        }
        Ok(())
    }
}

/// The most pixels an image has across or down.
pub const MAX_IMAGE_SIDE_PX: u32 = 4096;
/// The most channels a lidar has.
pub const MAX_CHANNELS: u32 = 256;

/// A range device's rays as written: its field of view and steps (a grid), or an image's
/// pixels, or a lidar's channels; each checked.
struct Pattern {
    fov_deg: [f64; 2],
    step_deg: [f64; 2],
    image_px: Option<[u32; 2]>,
    channels: Option<u32>,
}

fn pattern(s: &DeviceSpec, c: &Check<'_>) -> Result<Pattern, SpecError> {
    let fov = s.fov_deg.unwrap_or([0.0, 0.0]);
    if let Some(px) = s.image_px {
        return image_pattern(s, c, fov, px);
    }
    c.number("fov_deg", fov[0], 0.0, 360.0)?;
    c.number("fov_deg", fov[1], 0.0, 180.0)?;
    let step = s.step_deg.unwrap_or([1.0, 1.0]);
    for (i, v) in step.into_iter().enumerate() {
        let v = c.number("step_deg", v, 0.0, 90.0)?;
        if i == 1 && s.channels.is_some() {
            continue;
        }
        if fov[i] > 0.0 && v < 0.05 {
            return Err(c.err(
                "step_deg",
                format!("{v}: at least 0.05 degrees across a field"),
            ));
        }
        if fov[i] > 0.0 && fov[i] / v.max(1e-9) > 10_000.0 {
            return Err(c.err("step_deg", "more than 10,000 rays along a field".into()));
        }
    }
    if let Some(n) = s.channels {
        if !(1..=MAX_CHANNELS).contains(&n) {
            return Err(c.err("channels", format!("{n}: give 1 to {MAX_CHANNELS}")));
        }
        if n > 1 && fov[1] <= 0.0 {
            return Err(c.err(
                "channels",
                format!("{n} channels need a field of view up-down (fov_deg's second)"),
            ));
        }
    }
    Ok(Pattern {
        fov_deg: fov,
        step_deg: step,
        image_px: None,
        channels: s.channels,
    })
}

/// A pinhole image's pattern: 1 to 4096 pixels a side, a field of view above 0 and below 180
/// degrees each way; no steps, channels or beam width.
fn image_pattern(
    s: &DeviceSpec,
    c: &Check<'_>,
    fov: [f64; 2],
    px: [u32; 2],
) -> Result<Pattern, SpecError> {
    for side in px {
        if !(1..=MAX_IMAGE_SIDE_PX).contains(&side) {
            return Err(c.err(
                "image_px",
                format!("{px:?}: give 1 to {MAX_IMAGE_SIDE_PX} pixels across and down"),
            ));
        }
    }
    for v in fov {
        if !(v.is_finite() && v > 0.0 && v < 180.0) {
            return Err(c.err(
                "fov_deg",
                format!(
                    "{}: a camera's field of view is above 0 and below 180 degrees",
                    shown(v)
                ),
            ));
        }
    }
    for (field, set) in [
        ("step_deg", s.step_deg.is_some()),
        ("channels", s.channels.is_some()),
        ("beam_deg", s.beam_deg.is_some()),
    ] {
        if set {
            return Err(c.err(field, "not a setting of an image (image_px)".into()));
        }
    }
    Ok(Pattern {
        fov_deg: fov,
        step_deg: [0.0, 0.0],
        image_px: Some(px),
        channels: None,
    })
}

fn range_model(s: &DeviceSpec, c: &Check<'_>) -> Result<RangeModel, SpecError> {
    let p = pattern(s, c)?;
    let range = c.required("range_m", s.range_m)?;
    c.number("range_m", range[0], 0.0, 650.0)?;
    c.number("range_m", range[1], 0.0, 650.0)?;
    if range[0] >= range[1] {
        return Err(c.err(
            "range_m",
            format!("{range:?}: the nearest must be below the farthest"),
        ));
    }
    // An image's stereo focal length is its own unless given.
    let image_focal = p
        .image_px
        .filter(|_| s.stereo_subpixel_px.is_some() || s.stereo_baseline_m.is_some())
        .map(|px| focal_px(px[0], p.fov_deg[0]));
    let stereo =
        match (
            s.stereo_subpixel_px,
            s.stereo_focal_px.or(image_focal),
            s.stereo_baseline_m,
        ) {
            (None, None, None) => None,
            (Some(subpixel_px), Some(focal_px), Some(baseline_m)) => Some(Stereo {
                subpixel_px: c.number("stereo_subpixel_px", subpixel_px, 0.0, 10.0)?,
                focal_px: c.number("stereo_focal_px", focal_px, 1.0, 1e5)?,
                baseline_m: c.number("stereo_baseline_m", baseline_m, 1e-3, 10.0)?,
            }),
            _ => return Err(c.err(
                "stereo_subpixel_px",
                "a stereo error needs stereo_subpixel_px, stereo_focal_px and stereo_baseline_m"
                    .into(),
            )),
        };
    let burst = match (s.burst_enter, s.burst_mean_readings) {
        (None, None) => None,
        (enter, mean) => Some(Burst {
            enter: c.chance("burst_enter", enter)?,
            mean_readings: c.number("burst_mean_readings", mean.unwrap_or(1.0), 1.0, 1e6)?,
        }),
    };
    Ok(RangeModel {
        fov_deg: p.fov_deg,
        step_deg: p.step_deg,
        image_px: p.image_px,
        channels: p.channels,
        beam_deg: c.number("beam_deg", s.beam_deg.unwrap_or(0.0), 0.0, 45.0)?,
        range_m: range,
        sigma_m: c.number("sigma_m", s.sigma_m.unwrap_or(0.0), 0.0, 100.0)?,
        proportional: c.number("proportional", s.proportional.unwrap_or(0.0), 0.0, 1.0)?,
        stereo,
        bias_m: c.number("bias_m", s.bias_m.unwrap_or(0.0), 0.0, 100.0)?,
        markov: GaussMarkov {
            sigma: c.number(
                "markov_sigma_m",
                s.markov_sigma_m.unwrap_or(0.0),
                0.0,
                100.0,
            )?,
            tau_s: c.number("markov_tau_s", s.markov_tau_s.unwrap_or(0.0), 0.0, 1e6)?,
        },
        quantum_m: c.number("quantum_m", s.quantum_m.unwrap_or(0.0), 0.0, 10.0)?,
        dropout: c.chance("dropout", s.dropout)?,
        burst,
        invalid_ray: c.chance("invalid_ray", s.invalid_ray)?,
        false_return: c.chance("false_return", s.false_return)?,
    })
}

fn adsb_model(s: &DeviceSpec, c: &Check<'_>) -> Result<AdsbModel, SpecError> {
    let nacp = c.required("nacp", s.nacp)?;
    let bound =
        nacp_bound95_m(nacp).ok_or_else(|| c.err("nacp", format!("{nacp}: give 1 to 11")))?;
    let nacv = c.required("nacv", s.nacv)?;
    let vbound =
        nacv_bound95_mps(nacv).ok_or_else(|| c.err("nacv", format!("{nacv}: give 1 to 4")))?;
    let tau_s = c.number("tau_s", s.tau_s.unwrap_or(300.0), 0.0, 1e6)?;
    let mut reception = Vec::new();
    for [within_m, window_s] in s.reception.clone().unwrap_or_default() {
        let within_m = c.number("reception", within_m, 0.0, 1e6)?;
        let window_s = c.number("reception", window_s, 1e-3, 1e4)?;
        if reception
            .last()
            .is_some_and(|r: &Reception| r.within_m >= within_m)
        {
            return Err(c.err(
                "reception",
                "give the ranges nearest first, each farther".into(),
            ));
        }
        reception.push(Reception { within_m, window_s });
    }
    if reception.is_empty() {
        return Err(c.err("reception", "give at least one [within_m, window_s]".into()));
    }
    Ok(AdsbModel {
        nacp,
        nacv,
        position: GaussMarkov {
            sigma: match s.position_sigma_m {
                Some(v) => c.number("position_sigma_m", v, 0.0, 1e5)?,
                None => sigma_from_bound95(bound),
            },
            tau_s,
        },
        velocity: GaussMarkov {
            sigma: match s.velocity_sigma_mps {
                Some(v) => c.number("velocity_sigma_mps", v, 0.0, 1e3)?,
                None => sigma_from_bound95(vbound),
            },
            tau_s,
        },
        vertical_rate_b_mps: c.number(
            "vertical_rate_b_mps",
            s.vertical_rate_b_mps.unwrap_or(0.0),
            0.0,
            100.0,
        )?,
        annex10_altimetry: s.annex10_altimetry.unwrap_or(false),
        altitude_quantum_m: 0.3048
            * c.number(
                "altitude_quantum_ft",
                s.altitude_quantum_ft.unwrap_or(0.0),
                0.0,
                1000.0,
            )?,
        reception,
        latency_jitter_s: c.number(
            "latency_jitter_s",
            s.latency_jitter_s.unwrap_or(0.0),
            0.0,
            10.0,
        )?,
    })
}

fn field_of_regard(
    s: &DeviceSpec,
    c: &Check<'_>,
    default: [f64; 2],
) -> Result<[f64; 2], SpecError> {
    let f = s.field_of_regard_deg.unwrap_or(default);
    Ok([
        c.number("field_of_regard_deg", f[0], 0.0, 180.0)?,
        c.number("field_of_regard_deg", f[1], 0.0, 90.0)?,
    ])
}

fn radar_model(s: &DeviceSpec, c: &Check<'_>) -> Result<RadarModel, SpecError> {
    let range = c.required("range_m", s.range_m)?;
    c.number("range_m", range[0], 0.0, 1e6)?;
    c.number("range_m", range[1], 0.0, 1e6)?;
    if range[0] >= range[1] {
        return Err(c.err(
            "range_m",
            format!("{range:?}: the nearest must be below the farthest"),
        ));
    }
    let n = |f: &'static str, v: Option<f64>, hi: f64| c.number(f, v.unwrap_or(0.0), 0.0, hi);
    Ok(RadarModel {
        range_m: range,
        field_of_regard_deg: field_of_regard(s, c, [180.0, 90.0])?,
        range_sigma_m: n("range_sigma_m", s.range_sigma_m, 1e4)?,
        range_bias_m: n("range_bias_m", s.range_bias_m, 1e4)?,
        range_rate_sigma_mps: n("range_rate_sigma_mps", s.range_rate_sigma_mps, 1e3)?,
        range_rate_bias_mps: n("range_rate_bias_mps", s.range_rate_bias_mps, 1e3)?,
        angle_sigma_deg: n("angle_sigma_deg", s.angle_sigma_deg, 90.0)?,
        angle_bias_deg: n("angle_bias_deg", s.angle_bias_deg, 90.0)?,
    })
}

fn eoir_model(s: &DeviceSpec, c: &Check<'_>) -> Result<EoIrModel, SpecError> {
    let max = c.required("max_range_m", s.max_range_m)?;
    Ok(EoIrModel {
        max_range_m: c.number("max_range_m", max, 1.0, 1e6)?,
        field_of_regard_deg: field_of_regard(s, c, [180.0, 90.0])?,
        angle_sigma_mrad: c.number(
            "angle_sigma_mrad",
            s.angle_sigma_mrad.unwrap_or(0.0),
            0.0,
            1e3,
        )?,
        range_tau_s: c.number("range_tau_s", s.range_tau_s.unwrap_or(0.0), 0.0, 1e6)?,
        range_sigma_m: c.number("range_sigma_m", s.range_sigma_m.unwrap_or(0.0), 0.0, 1e4)?,
        range_proportional: c.number(
            "range_proportional",
            s.range_proportional.unwrap_or(0.0),
            0.0,
            1.0,
        )?,
    })
}
