//! `savsim study report` and `savsim batch report`: the page of a results directory, read as a
//! person reads it. The results are written by savsim's own table writer (as `study` writes
//! them); what the page must show is counted here from the rows the test made. With Debian's
//! `chromium` (`.ci/run` installs it; `SAVSIM_REQUIRE_BROWSER` makes its absence a failure) the
//! page is opened headless: the DOM after its script, and a screenshot whose pixels must hold
//! the outcome colours.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::cli::savsim;
use crate::common::assert_ran;

use savsim::study::manifest::StudyRow;
use savsim::study::result::StudyResult;

/// A flown row: `collisions` collisions, closest approach `cpa_m` to traffic.
fn row(index: usize, pair: &str, variant: &str, collisions: u64, cpa_m: f64) -> StudyResult {
    let input = StudyRow {
        id: Some(format!("{pair}-{variant}")),
        pair: Some(pair.into()),
        variant: Some(variant.into()),
        ..StudyRow::default()
    };
    let mut r = StudyResult::of_inputs(index, &input);
    r.measured.collisions = collisions;
    r.measured.cpa_m = Some(cpa_m);
    r.autopilot_did.first_acted_t_s = (variant == "mitigated").then_some(12.0 + index as f64);
    r.achieved_speedup = 9.5;
    r.judge();
    r
}

/// 12 pairs: nominal collides in 9, mitigated in 3; one more row failed to run.
fn study_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut rows = Vec::new();
    for k in 0..12 {
        let pair = format!("p{k}");
        rows.push(row(
            2 * k,
            &pair,
            "nominal",
            u64::from(k < 9),
            5.0 + k as f64,
        ));
        rows.push(row(
            2 * k + 1,
            &pair,
            "mitigated",
            u64::from(k < 3),
            40.0 + k as f64,
        ));
    }
    let mut broken = StudyResult::of_inputs(
        24,
        &StudyRow {
            id: Some("broken".into()),
            ..StudyRow::default()
        },
    );
    // Each row flies north through a box at 60 m (the scene beside the results); pair p10's
    // scene is missing; the mitigated rows meet an intruder crossing east at 60 m.
    let scene = dir.path().join("box.toml");
    std::fs::write(
        &scene,
        "[origin]\nlat_deg = -35.36\nlon_deg = 149.16\nalt_m = 584\n\n[[obstacle]]\n\
         id = \"box\"\nkind = \"building\"\nshape = { box = [20.0, 10.0, 40.0] }\n\
         position_enu_m = [0.0, 60.0, 0.0]\n",
    )
    .unwrap();
    for r in &mut rows {
        r.track = Some("0 0 0 20; 10 0 50 20; 20 0 100 20".into());
        r.inputs.scene = Some(if r.inputs.pair.as_deref() == Some("p10") {
            dir.path().join("missing.toml").display().to_string()
        } else {
            scene.display().to_string()
        });
        r.measured.cpa_t_s = Some(12.0);
        if r.inputs.variant.as_deref() == Some("mitigated") {
            r.inputs.intruder = Some("0 -500 60 20; 60 500 60 20".into());
        }
    }
    broken.error = Some("SITL: ended by itself".into());
    broken.outcome = savsim::study::result::Outcome::Error;
    rows.push(broken);
    let settings = savsim::runs::table::Settings {
        command: "study",
        manifest: "m.csv".into(),
        shard: savsim::runs::shard::Shard::WHOLE,
        more: vec![("speedup", "10".into())],
    };
    savsim::study::table::write_atomic(&rows, &settings, &dir.path().join("shard-0-of-1.parquet"))
        .unwrap();
    dir
}

/// How many times `needle` occurs in `text`, ignoring case.
fn count(text: &str, needle: &str) -> usize {
    text.to_ascii_lowercase()
        .matches(&needle.to_ascii_lowercase())
        .count()
}

#[test]
fn a_study_report_shows_the_counts_ratios_and_rows_it_was_given() {
    let dir = study_dir();
    let out = savsim()
        .args(["study", "report"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_ran(&out);
    let path = dir.path().join("report.html");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        path.display().to_string()
    );
    let page = std::fs::read_to_string(&path).unwrap();
    // Self-contained: nothing is fetched.
    for fetch in ["src=\"http", "href=\"http", "@import", "url(http"] {
        assert_eq!(count(&page, fetch), 0, "{fetch}");
    }
    // The summary's numbers: 9 and 3 collisions, the ratio 3/9.
    assert!(
        page.contains("nominal      collision 9, error 1, pass 3"),
        "{page}"
    );
    assert!(page.contains("mitigated    collision 3, pass 9"), "{page}");
    assert!(page.contains("collision ratio 0.333"), "{page}");
    // Outcomes: per variant a collision bar and a pass bar, and the error row's bar.
    let outcomes = section(&page, "outcomes");
    assert_eq!(
        count(outcomes, "fill=\"#D62728\""),
        2 + 1,
        "collision bars and legend"
    );
    assert_eq!(
        count(outcomes, "fill=\"#2CA02C\""),
        2 + 1,
        "pass bars and legend"
    );
    assert_eq!(
        count(outcomes, "fill=\"#7F7F7F\""),
        1 + 1,
        "the error bar and legend"
    );
    // Ratios: collision, NMAC and LoWC are defined only for collisions here (no NMAC, no
    // LoWC in the nominal rows): one point.
    let ratios = section(&page, "ratios");
    assert_eq!(count(ratios, "<circle"), 1, "{ratios}");
    // The collision ratio over the first 2, 4, 6, 8, 10 and 12 pairs (12 k / 6): six points,
    // in one panel.
    let convergence = section(&page, "convergence");
    assert_eq!(count(convergence, "<circle"), 6, "{convergence}");
    assert!(convergence.contains("mitigated collision ratio"));
    // Histograms: closest approach to traffic in two panels (12 rows each, nominal 5-16 m,
    // mitigated 40-51 m), first action in the mitigated rows only.
    let traffic = section(&page, "traffic");
    assert!(traffic.contains("nominal: 12 rows") && traffic.contains("mitigated: 12 rows"));
    let acted = section(&page, "acted");
    assert!(acted.contains("mitigated: 12 rows") && !acted.contains("nominal:"));
    // In plan, the rows worth a look: nominal passed (p9-p11), mitigated collided (p0-p2);
    // the box in each but p10's (its scene is missing, and said so); the intruder in the
    // mitigated ones.
    let plans = section(&page, "plans");
    assert_eq!(count(plans, "<figure class=\"plan\">"), 6, "{plans}");
    assert_eq!(count(plans, "<polygon"), 5, "{plans}");
    assert_eq!(count(plans, "footprints not drawn"), 1, "{plans}");
    assert_eq!(count(plans, "stroke=\"#FF7F0E\""), 3, "{plans}");
    // Every row, the error with its reason.
    let rows = section(&page, "rows");
    assert_eq!(count(rows, "<tr class="), 25);
    assert!(rows.contains("SITL: ended by itself"));
    let metadata = section(&page, "metadata");
    assert!(metadata.contains("shard-0-of-1.parquet") && metadata.contains("m.csv"));
    assert!(
        !metadata.contains("ARROW:schema"),
        "Arrow's own schema is not for a person"
    );
    browse(&path, 25);
}

/// The text of section `id` of the page.
fn section<'a>(page: &'a str, id: &str) -> &'a str {
    let start = page
        .find(&format!("<section id=\"{id}\">"))
        .unwrap_or_else(|| panic!("no section {id}"));
    let end = page[start..].find("</section>").unwrap() + start;
    &page[start..end]
}

fn chromium() -> Option<PathBuf> {
    let found = ["chromium", "chromium-browser"].iter().find(|p| {
        Command::new(p)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    });
    if found.is_none() {
        assert!(
            std::env::var_os("SAVSIM_REQUIRE_BROWSER").is_none(),
            "chromium is required here (SAVSIM_REQUIRE_BROWSER) but missing"
        );
        eprintln!(
            "SKIP: no chromium (apt-get install chromium; .ci/run does): the page was not opened"
        );
    }
    found.map(PathBuf::from)
}

/// Chromium, headless, without a network, on `args` then the page.
fn headless(chromium: &Path, profile: &Path, args: &[String], page: &Path) -> std::process::Output {
    Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap()
}

/// Open the page: after its script the DOM still holds `rows` rows and a sorted click works on
/// it; a screenshot shows the collision and pass colours.
fn browse(page: &Path, rows: usize) {
    let Some(chromium) = chromium() else { return };
    let profile = tempfile::tempdir().unwrap();
    let dom = headless(&chromium, profile.path(), &["--dump-dom".into()], page);
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert_eq!(
        count(&dom, "<tr class="),
        rows,
        "the DOM after the page's script"
    );
    assert!(count(&dom, "<svg") >= 4, "charts in the DOM");
    let png = profile.path().join("shot.png");
    let shot = headless(
        &chromium,
        profile.path(),
        &[
            format!("--screenshot={}", png.display()),
            "--window-size=1280,1600".into(),
        ],
        page,
    );
    assert!(png.is_file(), "{}", String::from_utf8_lossy(&shot.stderr));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let has = |rgb: [u8; 3]| {
        buf[..info.buffer_size()]
            .chunks(channels)
            .filter(|p| p[..3] == rgb)
            .count()
    };
    // The outcome bars, drawn: hundreds of pixels each.
    assert!(has([214, 39, 40]) > 200, "no collision bar on screen");
    assert!(has([44, 160, 44]) > 200, "no pass bar on screen");
}

#[test]
fn reports_of_what_is_not_results_fail_clearly_and_write_nothing() {
    let empty = tempfile::tempdir().unwrap();
    let fail = |args: &[&str], dir: &Path, says: &str| {
        let out = savsim().args(args).arg(dir).output().unwrap();
        // A clear error (1 or 2), never a panic (101).
        assert!(
            matches!(out.status.code(), Some(1 | 2)),
            "{args:?}: {:?}",
            out.status
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!dir.join("report.html").exists());
        assert!(!dir.join("report.html.tmp").exists());
    };
    fail(&["study", "report"], empty.path(), "no .parquet");
    // A truncated shard.
    let dir = study_dir();
    let shard = dir.path().join("shard-0-of-1.parquet");
    let bytes = std::fs::read(&shard).unwrap();
    std::fs::write(&shard, &bytes[..bytes.len() / 2]).unwrap();
    fail(&["study", "report"], dir.path(), "shard-0-of-1.parquet");
    // `--out` a directory: the rename fails, and its temporary file is not left behind.
    let dir = study_dir();
    let out = savsim()
        .args(["study", "report", "--out"])
        .arg(dir.path())
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(matches!(out.status.code(), Some(1 | 2)), "{:?}", out.status);
    assert!(!dir.path().with_extension("html.tmp").exists());
    // A study's shard given to batch: another schema.
    let dir = study_dir();
    fail(&["batch", "report"], dir.path(), "run_id");
}
