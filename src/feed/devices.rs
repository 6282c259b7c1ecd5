//! The feed from modelled devices (`--sensors` other than `ideal`): each device reads at its
//! own instants on the vehicle's clock (`k / rate`), from the device's place on the vehicle and
//! along its own rays, with its errors (`savsim_core::sensors`); each reading reaches the
//! autopilot its latency later; the feed then sends what the devices measured.
//!
//! - Range devices fill the 72 bins (and up, and down) from their beams' readings: a beam
//!   within 45 degrees of the horizon goes to the bin of its bearing, one more than 60 degrees
//!   down to the rangefinder, more than 60 up to the upward reading; the nearest return in a
//!   bin wins. A bin no fresh reading covers is *no data*: OBSTACLE_DISTANCE says UINT16_MAX
//!   ("unknown": ArduPilot skips it, the sector reads clear; PX4 leaves the bin to expire
//!   after 500 ms, then with CP_GO_NO_DATA 0 blocks motion into it, with 1 only if a sensor
//!   ever covered it), and no DISTANCE_SENSOR is sent for a sector or a rangefinder without
//!   data (ArduPilot's face expires after 1 s and reads clear; its rangefinder reports no data
//!   after 500 ms). A reading is fresh for 1.5 of its device's periods after it arrived.
//! - ADS-B devices report the aircraft that carry a transponder; radar and EO/IR report the
//!   others (or every aircraft when the vehicle has no ADS-B device), each as an
//!   ADSB_VEHICLE with an ICAO address of its own (`0xF2xxxx`): ArduPilot and PX4 take any
//!   ADSB_VEHICLE as traffic. A report is sent when it arrives; a track without a newer report
//!   is sent again at each of the device's instants with its age as `tslc`, for 20 s
//!   (ArduPilot drops a track whose report is 5 s old).

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

use glam::DVec3;

use savsim_core::collision::fan::segment_of;
use savsim_core::pipeline::ObstacleRef;
use savsim_core::sensors::device::{Device, Model, RangeModel};
use savsim_core::sensors::draws::{mix, Draws};
use savsim_core::sensors::image::{DepthImage, PointCloud, Segment};
use savsim_core::sensors::range::{Beam, BeamReading, BeamTruth, RangeState};
use savsim_core::sensors::surveillance::{Look, Own, Target, TargetReport, TargetState};

use super::aircraft::{aircraft, body_velocity, has_transponder};
use super::capture::{Capture, CaptureData};
use super::cast::{self, mount_rotation, CastScratch};
use super::picture::{bin_of, nearer, Picture};
use super::sectors::Levelled;
use super::tracks::{in_range, send_report, Told};
use super::wire::Range;
use super::Frame;
use crate::pipeline::Pipeline;
use crate::scene::Kind;

/// A reading on its way to the autopilot.
#[derive(Debug, Clone)]
pub(super) enum Pending {
    Range(Box<Picture>),
    Report {
        report: TargetReport,
        measured_s: f64,
        icao: u32,
        kind: Kind,
    },
}

/// One device on one vehicle.
#[derive(Debug, Clone, Default)]
pub(super) struct DeviceState {
    pub(super) last_k: Option<u64>,
    pub(super) range: RangeState,
    pub(super) targets: BTreeMap<u64, TargetState>,
    /// Readings not arrived yet, with when they arrive (vehicle's clock, s), in order.
    pub(super) pending: VecDeque<(f64, Pending)>,
    /// The newest range picture that arrived, and when.
    pub(super) latest: Option<(f64, Picture)>,
    /// Each aircraft's newest report that arrived: the report, when it was made, its ICAO
    /// address and kind, and when it was last sent.
    pub(super) tracks: BTreeMap<u64, (TargetReport, f64, u32, Kind, f64)>,
}

/// The devices of one vehicle.
#[derive(Debug, Clone, Default)]
pub(super) struct VehicleDevices {
    generation: u64,
    devices: Vec<DeviceState>,
    /// Per aircraft (by key), what the vehicle was told.
    pub(super) told: BTreeMap<u64, Told>,
}

/// The modelled devices of a feed: their definitions, their beams (computed once), the draws.
#[derive(Debug, Clone)]
pub(super) struct Devices {
    devices: Vec<Device>,
    beams: Vec<Arc<Vec<Beam>>>,
    /// Each device's columns when it spins (its beams read over its turn: `feed::cast`).
    turns: Vec<Option<usize>>,
    draws: Draws,
    seed: u64,
    /// Whether reports of other aircraft are sent (`--feed adsb`).
    send_adsb: bool,
    /// The combined range of the range devices (the messages' min and max).
    pub(super) range: Range,
    /// Scratch: the cast's, hits, truths, readings, what each beam met.
    cast: CastScratch,
    hits: Vec<Option<(ObstacleRef, f64)>>,
    truths: Vec<BeamTruth>,
    readings: Vec<BeamReading>,
    segments: Vec<Segment>,
    /// Whether readings are kept whole for the viewer ([`Devices::captures`]).
    pub(super) keep_captures: bool,
    /// The readings kept whole at this sample.
    pub(super) captures: Vec<Arc<Capture>>,
}

/// ICAO addresses of radar and EO/IR tracks: `0xF2xxxx`.
const SENSED_ICAO: u32 = 0xF2_0000;
/// A track without a newer report is sent again for this long, seconds.
const TRACK_KEPT_S: f64 = 20.0;

impl Devices {
    /// The feed's devices, drawing from `seed`; their reports of other aircraft are sent when
    /// `send_adsb`.
    pub(super) fn new(devices: Vec<Device>, seed: u64, send_adsb: bool) -> Self {
        let beams = devices
            .iter()
            .map(|d| match &d.model {
                Model::Range(m) => Arc::new(m.beams()),
                _ => Arc::new(Vec::new()),
            })
            .collect::<Vec<Arc<Vec<Beam>>>>();
        let turns = devices
            .iter()
            .zip(&beams)
            .map(|(d, b)| match &d.model {
                Model::Range(m) => m.turn_columns().filter(|&n| cast::fits(b, n)),
                _ => None,
            })
            .collect();
        let ranges: Vec<[f64; 2]> = devices
            .iter()
            .filter_map(|d| match &d.model {
                Model::Range(m) => Some(m.range_m),
                _ => None,
            })
            .collect();
        let range = Range {
            min_m: ranges
                .iter()
                .map(|r| r[0])
                .fold(f64::INFINITY, f64::min)
                .min(650.0),
            max_m: ranges.iter().map(|r| r[1]).fold(0.0, f64::max).min(650.0),
        };
        Self {
            devices,
            beams,
            turns,
            draws: Draws::new(seed),
            seed,
            send_adsb,
            range: if ranges.is_empty() {
                Range {
                    min_m: 0.2,
                    max_m: 40.0,
                }
            } else {
                range
            },
            cast: CastScratch::default(),
            hits: Vec::new(),
            truths: Vec::new(),
            readings: Vec::new(),
            segments: Vec::new(),
            keep_captures: false,
            captures: Vec::new(),
        }
    }

    /// The draws' key of device `index` on vehicle `v` in its generation.
    fn key(&self, v: &VehicleDevices, vehicle: u64, index: usize) -> u64 {
        mix(mix(mix(self.seed, vehicle), v.generation), index as u64)
    }

    /// The vehicle's clock restarted: its devices start again (new draws).
    pub(super) fn restart(v: &mut VehicleDevices) {
        v.generation += 1;
        v.devices.clear();
    }

    /// At a sample: each device whose instant came reads, what arrived by now is taken, and
    /// the reports that arrived or are due again are sent. Returns the range picture of the
    /// fresh readings.
    pub(super) fn on_sample(
        &mut self,
        v: &mut VehicleDevices,
        pipeline: &mut Pipeline,
        f: &mut Frame<'_, '_>,
    ) -> Picture {
        let t_s = f64::from(f.input.current.time_boot_ms) / 1000.0;
        self.captures.clear();
        if v.devices.len() != self.devices.len() {
            v.devices = vec![DeviceState::default(); self.devices.len()];
        }
        let vehicle =
            u64::from(f.input.sender.system_id) << 8 | u64::from(f.input.sender.component_id);
        let has_adsb = self
            .devices
            .iter()
            .any(|d| matches!(d.model, Model::Adsb(_)));
        for i in 0..self.devices.len() {
            let rate = self.devices[i].rate_hz;
            let k = (t_s * rate).floor().max(0.0) as u64;
            if v.devices[i].last_k.is_some_and(|last| k <= last) {
                continue;
            }
            v.devices[i].last_k = Some(k);
            let key = self.key(v, vehicle, i);
            let arrive_s = k as f64 / rate + self.devices[i].latency_s;
            if matches!(self.devices[i].model, Model::Range(_)) {
                let picture = self.read_range(i, key, k, &mut v.devices[i], pipeline, f);
                v.devices[i]
                    .pending
                    .push_back((arrive_s, Pending::Range(Box::new(picture))));
            } else {
                self.survey(i, key, k, has_adsb, v, f);
                if self.send_adsb {
                    self.resend(i, t_s, v, f);
                }
            }
        }
        let mut picture = Picture::default();
        let own_enu_m = f.input.current.position_enu_m;
        for (i, d) in v.devices.iter_mut().enumerate() {
            take_arrived(
                d,
                t_s,
                &mut v.told,
                self.send_adsb.then_some(&mut *f),
                own_enu_m,
            );
            if let Some((at, p)) = &d.latest {
                if t_s - at <= 1.5 / self.devices[i].rate_hz {
                    picture.take(p);
                }
            }
        }
        picture
    }

    /// Device `i` reads its beams at instant `k`: cast from its place along its rays, then its
    /// errors; the picture of that reading.
    fn read_range(
        &mut self,
        i: usize,
        key: u64,
        k: u64,
        state: &mut DeviceState,
        pipeline: &mut Pipeline,
        f: &Frame<'_, '_>,
    ) -> Picture {
        let beams = self.beams[i].clone();
        self.hits.clear();
        self.hits.resize(beams.iter().map(|b| b.len()).sum(), None);
        let device = &self.devices[i];
        let (turn, input) = (self.turns[i], f.input);
        cast::cast_beams(
            device,
            turn,
            (k, &beams),
            pipeline,
            input,
            &mut self.cast,
            &mut self.hits,
        );
        let Model::Range(model) = &device.model else {
            return Picture::default();
        };
        let current = f.input.current;
        let enu_from_frd = current.attitude.enu_from_frd;
        let mount = mount_rotation(device.mount.yaw_deg, device.mount.pitch_deg);
        let origin =
            current.position_enu_m + enu_from_frd * DVec3::from_array(device.mount.position_frd_m);
        self.truths.clear();
        self.segments.clear();
        let scene = f.input.scene;
        let mut at = 0;
        for b in beams.iter() {
            let hits = &self.hits[at..at + b.len()];
            at += b.len();
            let nearest = hits
                .iter()
                .flatten()
                .copied()
                .min_by(|a, b| a.1.total_cmp(&b.1));
            self.truths
                .push(BeamTruth::along(b, nearest.map(|(_, d)| d)));
            // What each beam met: only for a reading kept whole.
            if self.keep_captures {
                self.segments
                    .push(nearest.map_or_else(Segment::default, |(o, _)| {
                        segment_of(o, |i| scene.obstacles.get(i).map(|s| s.kind))
                    }));
            }
        }
        self.readings.clear();
        self.readings.resize(beams.len(), BeamReading::NoData);
        model.read(
            &mut state.range,
            &self.draws,
            key,
            (k, 1.0 / device.rate_hz),
            &self.truths,
            &mut self.readings,
        );
        if self.keep_captures {
            let capture = Capture {
                device: device.name.clone(),
                system_id: f.input.sender.system_id,
                instant_s: k as f64 / device.rate_hz,
                origin_enu_m: origin,
                enu_from_device: current.attitude.enu_from_frd * mount,
                data: self.capture_data(model, &beams),
            };
            self.captures.push(Arc::new(capture));
        }
        let down_enu = (enu_from_frd * DVec3::Z).normalize_or(-f.up_enu);
        let mut picture = Picture::default();
        let Some(levelled) = Levelled::new(current.attitude.forward_enu(), down_enu, f.up_enu)
        else {
            return picture;
        };
        for (b, reading) in beams.iter().zip(&self.readings) {
            let Some(dir) = b.first().map(|d| enu_from_frd * (mount * *d)) else {
                continue;
            };
            let up = dir.dot(f.up_enu).clamp(-1.0, 1.0).asin().to_degrees();
            let cell = if up > 60.0 {
                &mut picture.up
            } else if up < -60.0 {
                &mut picture.down
            } else if up.abs() <= 45.0 {
                let bearing = dir
                    .dot(levelled.right_enu)
                    .atan2(dir.dot(levelled.forward_enu))
                    .to_degrees();
                &mut picture.bins[bin_of(bearing)]
            } else {
                continue;
            };
            *cell = nearer(*cell, *reading);
        }
        picture
    }

    /// The last reading whole: a depth image for an image device, else a point cloud.
    fn capture_data(&self, model: &RangeModel, beams: &[Beam]) -> CaptureData {
        match model.image_px {
            Some([w, h]) => {
                let mut image = DepthImage::default();
                image.fill(w, h, &self.readings, &self.truths, &self.segments);
                CaptureData::Depth {
                    image,
                    fov_deg: model.fov_deg,
                }
            }
            None => {
                let mut cloud = PointCloud::default();
                cloud.fill(beams, &self.readings, &self.segments);
                CaptureData::Points(cloud)
            }
        }
    }

    /// Device `i` surveys the aircraft around the vehicle at instant `k`: each report that gets
    /// through is queued to arrive its latency (and jitter) later. The truth is taken at the
    /// instant: the vehicle's and each aircraft's states at this sample, carried back to the
    /// instant along their velocities (a sample falls up to one of the vehicle's position
    /// intervals after the instant, and not at the same point at every speedup).
    fn survey(
        &mut self,
        i: usize,
        key: u64,
        k: u64,
        has_adsb: bool,
        v: &mut VehicleDevices,
        f: &Frame<'_, '_>,
    ) {
        let device = &self.devices[i];
        let dt_s = 1.0 / device.rate_hz;
        let current = f.input.current;
        let back_s = f64::from(current.time_boot_ms) / 1000.0 - k as f64 * dt_s;
        let own = Own {
            position_enu_m: current.position_enu_m - current.velocity_enu_mps * back_s,
            velocity_enu_mps: current.velocity_enu_mps,
            enu_from_frd: current.attitude.enu_from_frd,
        };
        let state = &mut v.devices[i];
        for (a, body) in aircraft(f.input) {
            let transponder = has_transponder(f.input, body);
            let reports_it = match device.model {
                Model::Adsb(_) => transponder,
                _ => !transponder || !has_adsb,
            };
            if !reports_it {
                continue;
            }
            let velocity_enu_mps = body_velocity(body);
            let target = Target {
                key: u64::from(a.icao_address),
                position_enu_m: body.current.position_enu_m - velocity_enu_mps * back_s,
                velocity_enu_mps,
                altitude_m: a.position.alt_m - velocity_enu_mps.z * back_s,
            };
            let range_m = (target.position_enu_m - own.position_enu_m).length();
            let t_state = state.targets.entry(target.key).or_default();
            let look = Look {
                draws: &self.draws,
                key,
                k,
                dt_s,
                own: &own,
            };
            let report = device.model.report(t_state, &look, &target);
            let told = v.told.entry(target.key).or_default();
            match report {
                Some(report) => {
                    let icao = match device.model {
                        Model::Adsb(_) => a.icao_address,
                        _ => SENSED_ICAO | (a.icao_address & 0xFFFF),
                    };
                    let arrive = k as f64 * dt_s + device.latency_s + report.jitter_s;
                    state.pending.push_back((
                        arrive,
                        Pending::Report {
                            report,
                            measured_s: k as f64 * dt_s,
                            icao,
                            kind: a.kind,
                        },
                    ));
                }
                None if in_range(device, range_m) => told.reports_lost += 1,
                None => {}
            }
        }
        // Arrivals out of order (jitter): kept sorted by arrival.
        state
            .pending
            .make_contiguous()
            .sort_by(|a, b| a.0.total_cmp(&b.0));
    }

    /// At device `i`'s instant, the tracks that got no newer report are sent again with their
    /// age.
    fn resend(&self, i: usize, t_s: f64, v: &mut VehicleDevices, f: &mut Frame<'_, '_>) {
        let period = 1.0 / self.devices[i].rate_hz;
        let state = &mut v.devices[i];
        state
            .tracks
            .retain(|_, (_, measured, ..)| t_s - *measured <= TRACK_KEPT_S);
        for (report, measured_s, icao, kind, sent_s) in state.tracks.values_mut() {
            if t_s - *sent_s >= period * 0.999 {
                send_report(f, report, *icao, *kind, t_s - *measured_s);
                *sent_s = t_s;
            }
        }
    }
}

/// Take what arrived by `t_s`: range pictures become the device's latest; reports are sent
/// and become its tracks (and what the vehicle was told).
fn take_arrived(
    d: &mut DeviceState,
    t_s: f64,
    told: &mut BTreeMap<u64, Told>,
    mut f: Option<&mut Frame<'_, '_>>,
    own_enu_m: DVec3,
) {
    while d.pending.front().is_some_and(|(at, _)| *at <= t_s) {
        let Some((at, pending)) = d.pending.pop_front() else {
            break;
        };
        match pending {
            Pending::Range(picture) => d.latest = Some((at, *picture)),
            Pending::Report {
                report,
                measured_s,
                icao,
                kind,
            } => {
                if let Some(f) = f.as_deref_mut() {
                    send_report(f, &report, icao, kind, t_s - measured_s);
                }
                let t = told.entry(report.key).or_default();
                t.reports_received += 1;
                let reported = (report.position_enu_m - own_enu_m).length();
                if t.first_detection_s.is_none() {
                    t.first_detection_s = Some(t_s);
                    t.first_detection_range_m = Some(reported);
                }
                t.sensed_closest_m = Some(t.sensed_closest_m.map_or(reported, |m| m.min(reported)));
                d.tracks
                    .insert(report.key, (report, measured_s, icao, kind, t_s));
            }
        }
    }
}
