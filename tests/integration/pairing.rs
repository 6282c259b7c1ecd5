//! Importance-sampled pairing (`gen-encounters --model --pairing`): the encounters hold their
//! construction at TCA (read back from the written waypoints), the sampled HMD follows the
//! proposal, the kept VMD follows the model's own VMD times the rejection's acceptance (the
//! natural VMD drawn here from independent model tracks), and the weights undo both: weighted
//! frequencies equal the natural ones.

use glam::DVec3;
use rand::SeedableRng;
use savsim::batch::gen::GenOptions;
use savsim::daa::encounter_model::{track, Model};
use savsim::daa::pairing_ini::PairingSettings;
use savsim::runs::waypoints::parse_waypoints;

use crate::common::root;
use crate::daa::chi_square_p;

const FT: f64 = 0.3048;

/// Short encounters (as MIT LL's rotorcraft example) so that the debug build draws many; no
/// start-separation rejection (`H_min = 0`), which would couple VMD and geometry.
const INI: &str = "\
bin_edges_VMD = -1500, -500, -100, 0, 100, 500, 1500
desired_proportions_VMD = 1/2 1/1.5 1 1 1/1.5 1/2
bin_edges_HMD = -18240, -1500, -500, 0, 500, 1500, 18240
desired_proportions_HMD = 1/1.5 1/1.25 1 1 1/1.25 1/1.5
tCPA = 30
sample_time = 60
H_min = 0
R_min = 1.5
";

const VMD_EDGES_FT: [f64; 7] = [-1500.0, -500.0, -100.0, 0.0, 100.0, 500.0, 1500.0];
const VMD_KEEP: [f64; 6] = [0.5, 1.0 / 1.5, 1.0, 1.0, 1.0 / 1.5, 0.5];
/// |HMD| folded onto the positive bins: each twice the one-sided probability.
const HMD_EDGES_FT: [f64; 4] = [0.0, 500.0, 1500.0, 18240.0];
const HMD_PROPORTIONS: [f64; 3] = [1.0, 1.0 / 1.25, 1.0 / 1.5];

fn model() -> Model {
    let path = root().join("scenes/encounter-models/uncor_1200code_v2p1.txt");
    Model::parse(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn bin_of(edges: &[f64], x: f64) -> Option<usize> {
    (0..edges.len() - 1).find(|&i| x >= edges[i] && x < edges[i + 1])
}

/// What each generated encounter is at TCA, read from its waypoints: |HMD|, VMD (feet), w.
struct AtTca {
    hmd_ft: f64,
    vmd_ft: f64,
    /// The two horizontal speeds added.
    speeds_ftps: f64,
    w: f64,
}

fn generated(n: usize) -> Vec<AtTca> {
    let settings = PairingSettings::parse(INI).unwrap();
    let options = GenOptions {
        n,
        seed: 11,
        scene: None,
        mode: "exact".into(),
        duration_s: 60.0,
        rate_hz: 10.0,
        intruder_kind: "dji".into(),
    };
    let runs = savsim::batch::gen_pairing::encounters(&options, &model(), &settings).unwrap();
    runs.iter()
        .map(|r| {
            assert_eq!(r.tca_s, Some(30.0));
            let own = parse_waypoints(r.own.as_deref().unwrap()).unwrap();
            let int = parse_waypoints(r.intruder.as_deref().unwrap()).unwrap();
            let p = |w: &[savsim::scene::Waypoint], k: usize| DVec3::from(w[k].position_enu_m);
            assert_eq!(own[30].t_s, 30.0);
            let d = p(&int, 30) - p(&own, 30);
            let v = (p(&int, 31) - p(&int, 30)) - (p(&own, 31) - p(&own, 30));
            // The horizontal CPA of the relative motion at TCA is TCA itself: the offset is
            // perpendicular to the relative velocity (waypoints are written to the millimetre).
            let cos =
                d.truncate().dot(v.truncate()) / (d.truncate().length() * v.truncate().length());
            assert!(d.truncate().length() < 1.0 || cos.abs() < 1e-3, "{d} {v}");
            assert!((d.truncate().length() - r.hmd_at_tca_m.unwrap()).abs() < 0.01);
            assert!((d.z - r.vmd_at_tca_m.unwrap()).abs() < 0.01);
            AtTca {
                hmd_ft: d.truncate().length() / FT,
                vmd_ft: d.z / FT,
                speeds_ftps: ((p(&own, 31) - p(&own, 30)).truncate().length()
                    + (p(&int, 31) - p(&int, 30)).truncate().length())
                    / FT,
                w: r.w.unwrap(),
            }
        })
        .collect()
}

/// The relative speed integrated over a turn of relative heading (midpoint rule: the
/// integrand is smooth and periodic), feet per second.
fn flux_ftps(own: DVec3, int: DVec3) -> f64 {
    let (v1, v2, dz) = (
        own.truncate().length(),
        int.truncate().length(),
        int.z - own.z,
    );
    let n = 256;
    let h = std::f64::consts::TAU / n as f64;
    (0..n)
        .map(|k| {
            let psi = (k as f64 + 0.5) * h;
            ((v2 * psi.cos() - v1).powi(2) + (v2 * psi.sin()).powi(2) + dz * dz).sqrt() * h
        })
        .sum::<f64>()
        / FT
}

/// The model's own VMD at TCA over the VMD bins, from independent pairs of tracks (each
/// redrawn until it lasts): each bin's share of pairs, and its share of pairs weighted by
/// their relative-speed flux (encounters happen in proportion to it); and the flux-weighted
/// mean of the two horizontal speeds added.
fn natural_vmd(pairs: usize) -> (Vec<f64>, Vec<f64>, f64) {
    let model = model();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
    let mut draw = || loop {
        if let Some(t) = track(&model, 60, &mut rng) {
            return (
                t[30].position_enu_m,
                t[31].position_enu_m - t[30].position_enu_m,
            );
        }
    };
    let (mut counts, mut fluxes) = (vec![0.0; 6], vec![0.0; 6]);
    let mut flux_speeds = 0.0;
    for _ in 0..pairs {
        let ((own, v_own), (int, v_int)) = (draw(), draw());
        if let Some(b) = bin_of(&VMD_EDGES_FT, (int.z - own.z) / FT) {
            let flux = flux_ftps(v_own, v_int);
            counts[b] += 1.0;
            fluxes[b] += flux;
            flux_speeds += flux * (v_own.truncate().length() + v_int.truncate().length()) / FT;
        }
    }
    let share = |x: Vec<f64>| {
        let total: f64 = x.iter().sum();
        x.iter().map(|c| c / total).collect::<Vec<_>>()
    };
    let mean = flux_speeds / fluxes.iter().sum::<f64>();
    (share(counts), share(fluxes), mean)
}

#[test]
fn importance_pairing_reproduces_its_hmd_vmd_and_tca_and_the_weights_undo_it() {
    let encounters = generated(20_000);
    // HMD: the proposal's folded bin probabilities.
    let mut hmd_counts = vec![0.0; 3];
    for e in &encounters {
        hmd_counts[bin_of(&HMD_EDGES_FT, e.hmd_ft).unwrap()] += 1.0;
    }
    let sum: f64 = HMD_PROPORTIONS.iter().sum();
    let hmd_p: Vec<f64> = HMD_PROPORTIONS.iter().map(|p| p / sum).collect();
    let p = chi_square_p(&hmd_counts, &hmd_p);
    assert!(p > 0.01, "HMD: p = {p}, {hmd_counts:?} vs {hmd_p:?}");

    // VMD: natural times acceptance (the natural from 10x as many independent pairs).
    let (natural, encountered, flux_mean_speeds) = natural_vmd(200_000);
    let kept: Vec<f64> = natural.iter().zip(VMD_KEEP).map(|(n, a)| n * a).collect();
    let kept_sum: f64 = kept.iter().sum();
    let expected: Vec<f64> = kept.iter().map(|k| k / kept_sum).collect();
    let mut vmd_counts = vec![0.0; 6];
    for e in &encounters {
        vmd_counts[bin_of(&VMD_EDGES_FT, e.vmd_ft).unwrap()] += 1.0;
    }
    let p = chi_square_p(&vmd_counts, &expected);
    assert!(p > 0.01, "VMD: p = {p}, {vmd_counts:?} vs {expected:?}");

    // Weighted, the frequencies are the true ones: the HMD uniform over the proposal's span,
    // the VMD the model's own weighted by the flux. Five standard errors of a weighted mean
    // (and the natural sample's own error) as the margin.
    let total_w: f64 = encounters.iter().map(|e| e.w).sum();
    let weighted = |hit: &dyn Fn(&AtTca) -> bool| {
        let m = encounters
            .iter()
            .filter(|e| hit(e))
            .map(|e| e.w)
            .sum::<f64>()
            / total_w;
        let var = encounters
            .iter()
            .map(|e| (e.w / total_w).powi(2) * ((hit(e) as u8 as f64) - m).powi(2))
            .sum::<f64>();
        (m, var.sqrt())
    };
    for (lo, hi) in [(0.0, 500.0), (500.0, 1500.0), (1500.0, 18240.0)] {
        let (m, se) = weighted(&|e| e.hmd_ft >= lo && e.hmd_ft < hi);
        let truth = (hi - lo) / 18240.0;
        assert!(
            (m - truth).abs() < 5.0 * se,
            "HMD {lo}-{hi} ft: weighted {m} +- {se}, true {truth}"
        );
    }
    for (b, truth) in encountered.iter().enumerate() {
        let (lo, hi) = (VMD_EDGES_FT[b], VMD_EDGES_FT[b + 1]);
        let (m, se) = weighted(&|e| e.vmd_ft >= lo && e.vmd_ft < hi);
        assert!(
            (m - truth).abs() < 5.0 * se + 0.01,
            "VMD {lo}-{hi} ft: weighted {m} +- {se}, model {truth}"
        );
    }
    // The heading norm in `w`: weighted, the speeds are the flux-weighted ones of the model
    // (without it, nearer the plain model mean: 5% slower when this was written).
    let mean = encounters.iter().map(|e| e.w * e.speeds_ftps).sum::<f64>() / total_w;
    let se = encounters
        .iter()
        .map(|e| (e.w / total_w).powi(2) * (e.speeds_ftps - mean).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        (mean - flux_mean_speeds).abs() < 5.0 * se + 0.005 * flux_mean_speeds,
        "speeds: weighted {mean} +- {se}, flux-weighted model {flux_mean_speeds}"
    );
}

#[test]
fn pairing_settings_refuse_what_savsim_does_not_do() {
    for (extra, needle) in [
        ("applyOwnshipFilterAtCPA = 1", "not supported"),
        ("ownshipSampleTrajectory = 1", "not supported"),
        ("maxOwnSpeed_kts = 200", "not supported"),
        ("bin_edgesVMD = 1", "unknown key"),
        ("tCPA = 90", "before sample_time"),
        ("desired_proportions_HMD = 1 1", "proportions for 6 bins"),
        ("H_min = -3", ">= 0"),
        ("not a line", "not `key = value`"),
    ] {
        let e = PairingSettings::parse(&format!("{INI}{extra}\n")).unwrap_err();
        assert!(e.to_string().contains(needle), "{extra}: {e}");
    }
    // The tool's own bookkeeping keys are read and ignored; off switches are accepted.
    let ok = format!(
        "{INI}encIds = 1:5\nsaveDirectory = 'Example_Outputs'\nrandSeed = 1\n\
         altLayers = 500 1200, 1200 3000\nmaxOwnAlt_ft = []\nquantizeOwnshipAlt500 = 0\n"
    );
    assert!(PairingSettings::parse(&ok).is_ok());
}

#[test]
fn gen_encounters_with_a_pairing_file_writes_weights_and_refuses_a_second_length() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("enc.csv");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
            .args(["batch", "gen-encounters", "--n", "5", "--seed", "3"])
            .arg("--model")
            .arg(root().join("scenes/encounter-models/uncor_1200code_v2p1.txt"))
            .arg("--pairing")
            .arg(root().join("scenes/encounter-models/pairing.ini"))
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    let ok = run(&[]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let mut reader = csv::Reader::from_path(&out).unwrap();
    let headers = reader.headers().unwrap().clone();
    let w_at = headers.iter().position(|h| h == "w").unwrap();
    let d_at = headers.iter().position(|h| h == "duration_s").unwrap();
    for row in reader.records() {
        let row = row.unwrap();
        let w: f64 = row[w_at].parse().unwrap();
        assert!(w.is_finite() && w > 0.0, "{w}");
        assert_eq!(row[d_at].parse::<f64>().unwrap(), 180.0);
    }
    let clash = run(&["--duration-s", "60"]);
    assert!(!clash.status.success());
    assert!(String::from_utf8_lossy(&clash.stderr).contains("sample_time"));
    let same = run(&["--duration-s", "180"]);
    assert!(same.status.success());
}

/// The exact closest approach of two aircraft linear between their states (sampled at the
/// same times): per interval, the minimum of a quadratic. Metres and seconds.
fn linear_cpa(times: &[f64], own: &[DVec3], int: &[DVec3]) -> (f64, f64) {
    let mut best = (f64::INFINITY, 0.0);
    for k in 0..times.len() - 1 {
        let (d0, d1) = (int[k] - own[k], int[k + 1] - own[k + 1]);
        let dd = d1 - d0;
        let u = if dd.length_squared() > 0.0 {
            (-d0.dot(dd) / dd.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d = (d0 + dd * u).length();
        if d < best.0 {
            best = (d, times[k] + u * (times[k + 1] - times[k]));
        }
    }
    best
}

#[test]
fn mit_ll_trajectory_outputs_are_batch_rows() {
    use arrow_array::{Array, Float64Array, StringArray};
    // Its Example_Outputs/1.txt (X11 licence, tests/fixtures/mitll/README.md): OWNSHIP and
    // INTRUDER at 10 Hz, `east, north, alt` in feet, read here by splitting its lines.
    let file = root().join("tests/fixtures/mitll/example_output_1.txt");
    let text = std::fs::read_to_string(&file).unwrap();
    let (mut times, mut own, mut int) = (Vec::new(), Vec::new(), Vec::new());
    for line in text.lines().skip(2) {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let p = DVec3::new(
            f[1].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
        ) * FT;
        match f[0] {
            "OWNSHIP" => {
                times.push(f[7].parse::<f64>().unwrap());
                own.push(p);
            }
            _ => int.push(p),
        }
    }
    assert_eq!((own.len(), int.len()), (1800, 1800));
    let (cpa_m, cpa_t_s) = linear_cpa(&times, &own, &int);
    let dir = tempfile::tempdir().unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(&manifest, format!("id,daa\nmitll-1,{}\n", file.display())).unwrap();
    let out = dir.path().join("out");
    crate::daa::batch_on_one_job(&manifest, &out);
    let batch = crate::daa::only_shard(&out);
    let error = crate::batch::column::<StringArray>(&batch, "error");
    assert!(error.is_null(0), "{}", error.value(0));
    let got = crate::batch::column::<Float64Array>(&batch, "cpa_m").value(0);
    let got_t = crate::batch::column::<Float64Array>(&batch, "cpa_t_s").value(0);
    assert!(
        (got - cpa_m).abs() < 0.01,
        "cpa {got} m, the file's {cpa_m} m"
    );
    assert!(
        (got_t - cpa_t_s).abs() < 0.1,
        "at {got_t} s, the file's {cpa_t_s} s"
    );
    // And `savsim daa` reads it as a Euclidean state file: a row per time step, its
    // horizontal separation (column 7, nmi) the file's own.
    let conf = dir.path().join("suas.conf");
    std::fs::write(
        &conf,
        "lookahead_time = 180 [s]\nalerters = A\nA_alert_1_detector = d\n\
         A_alert_1_alerting_time = 30 [s]\nA_alert_1_region = MID\nA_d_WCV_DTHR = 2000 [ft]\n\
         A_d_WCV_ZTHR = 250 [ft]\nA_d_WCV_TTHR = 0 [s]\nA_d_WCV_TCOA = 0 [s]\n\
         A_load_core_detection_d = gov.nasa.larcfm.ACCoRD.WCV_TAUMOD\n",
    )
    .unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_savsim"))
        .arg("daa")
        .arg(&file)
        .arg("--conf")
        .arg(&conf)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = String::from_utf8(run.stdout).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(2)
        .map(|l| l.split(',').map(str::trim).collect())
        .collect();
    assert_eq!(rows.len(), 1800);
    let k = times.iter().position(|t| *t == 150.0).unwrap();
    let row = rows
        .iter()
        .find(|r| r[0].parse::<f64>().unwrap() == 150.0)
        .unwrap();
    let separation_nmi = (int[k] - own[k]).truncate().length() / 1852.0;
    assert!(
        (row[6].parse::<f64>().unwrap() - separation_nmi).abs() < 2e-6,
        "{row:?} vs {separation_nmi}"
    );
}

#[test]
fn a_trajectory_file_is_a_track_placed_by_wgs84() {
    use arrow_array::{Array, Float64Array, StringArray};
    // Its Example_Trajectory_Encounters/1.csv (tests/fixtures/mitll/README.md): due north from
    // 0 N 0 E at a constant `speed_kts`, `alt_AGL_ft` up, its `lat`, `lon` and `alt_MSL_ft`
    // written by MIT LL's own conversion of that straight line. Over a scene whose origin is
    // 0 N 0 E at height 0, savsim's track must be that line again: a still intruder put where
    // speed x 100 s puts the ownship is met there, at 100 s.
    let file = root().join("tests/fixtures/mitll/trajectory_1.csv");
    let text = std::fs::read_to_string(&file).unwrap();
    let first: Vec<f64> = text
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let (agl_ft, speed_kts) = (first[4], first[5]);
    let north_m = speed_kts * 1852.0 / 3600.0 * 100.0;
    let up_m = agl_ft * FT;
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("equator.toml");
    std::fs::write(
        &scene,
        "[origin]\nlat_deg = 0.0\nlon_deg = 0.0\nalt_m = 0.0\n",
    )
    .unwrap();
    let manifest = dir.path().join("m.csv");
    std::fs::write(
        &manifest,
        format!(
            "id,scene,own,intruder\ntrajectory,{},{},0 0 {north_m} {up_m}; 182 0 {north_m} {up_m}\n",
            scene.display(),
            file.display()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    crate::daa::batch_on_one_job(&manifest, &out);
    let batch = crate::daa::only_shard(&out);
    let error = crate::batch::column::<StringArray>(&batch, "error");
    assert!(error.is_null(0), "{}", error.value(0));
    let cpa = crate::batch::column::<Float64Array>(&batch, "cpa_m").value(0);
    let t = crate::batch::column::<Float64Array>(&batch, "cpa_t_s").value(0);
    assert!(cpa < 0.5, "{cpa} m from the line");
    assert!((t - 100.0).abs() < 0.05, "at {t} s");
    // A file without the columns is the row's error, naming what it needs.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "Time,lat,lon\n0,0,0\n").unwrap();
    std::fs::write(
        &manifest,
        format!(
            "id,own,intruder\nbad,{},0 0 0 100; 10 0 0 100\n",
            bad.display()
        ),
    )
    .unwrap();
    crate::daa::batch_on_one_job(&manifest, &out.join("bad"));
    let batch = crate::daa::only_shard(&out.join("bad"));
    let error = crate::batch::column::<StringArray>(&batch, "error");
    assert!(error.value(0).contains("alt_MSL_ft"), "{}", error.value(0));
}
