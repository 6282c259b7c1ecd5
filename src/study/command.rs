//! `savsim study` on the command line: the network namespace, the manifest, the shard, the
//! rows, the shard's file; `study summarize` and `study gen`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::cli::{StudyArgs, StudyCommand, StudyGenKind, SummarizeArgs};
use crate::error::{Error, Result};
use crate::runs::shard::Shard;
use crate::runs::table::Settings;
use crate::study::netns::{in_own_namespace, INSIDE_NETNS};
use crate::study::result::{Outcome, StudyResult};
use crate::study::row::ids::MAX_JOBS;
use crate::study::row::{Setup, SPEEDUP_RANGE};
use crate::study::sitl::{ArduCopter, Px4};
use crate::study::{converge, manifest};

/// Run `savsim study ...`.
pub fn run(args: &StudyArgs, shutdown: Arc<AtomicBool>) -> Result<()> {
    match &args.command {
        Some(StudyCommand::Summarize(SummarizeArgs { dir, nominal, json })) => {
            summarize(dir, nominal, *json)
        }
        Some(StudyCommand::Report(report)) => {
            let summary = crate::study::summarize::read_dir(&report.dir)?;
            let options = crate::runs::report::Options {
                command: "study",
                nominal: &report.nominal,
                failing_rows_only: false,
            };
            crate::runs::report::command(&report.dir, report.out.as_deref(), &summary, options)
        }
        Some(StudyCommand::Gen {
            kind,
            autopilot,
            n,
            seed,
            model,
            sensors,
            equipage,
            out,
        }) => gen(
            *kind,
            autopilot,
            (*n, *seed),
            (model.as_deref(), equipage.as_deref()),
            sensors,
            out,
        ),
        None => study(args, shutdown),
    }
}

/// `study summarize`.
fn summarize(dir: &Path, nominal: &str, json: bool) -> Result<()> {
    crate::study::summarize::read_dir(dir)?.print(nominal, json);
    Ok(())
}

/// `study MANIFEST --out DIR`: the flags checked, the shard chosen (and skipped if done), or
/// the rounds of `--until-converged`; the study run in a network namespace of its own where
/// one can be made.
fn study(args: &StudyArgs, shutdown: Arc<AtomicBool>) -> Result<()> {
    let (Some(manifest_path), Some(out)) = (&args.runs.manifest, &args.runs.out) else {
        return Err(Error::Usage("give a manifest and --out DIR".into()));
    };
    check_flags(args)?;
    let rows = manifest::load(manifest_path)?;
    let plan = match args.until_converged {
        None => Plan::Shard(Shard::from_args(args.runs.shard.as_deref(), |v| {
            std::env::var(v).ok()
        })?),
        Some(pct) => Plan::Rounds(pct),
    };
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    if let Plan::Shard(shard) = plan {
        let path = out.join(shard.file_name());
        if path.exists() && !args.runs.force {
            eprintln!(
                "study: shard {}/{} is done ({} exists): skipped",
                shard.index,
                shard.count,
                path.display()
            );
            return Ok(());
        }
    }
    if !args.no_netns && std::env::var_os(INSIDE_NETNS).is_none() {
        if let Some(status) = in_own_namespace(&shutdown)? {
            return status;
        }
    }
    // Absolute: each SITL runs in its own folder and reads its files from there.
    let work = std::fs::canonicalize(out)
        .map_err(|e| Error::file(out, e))?
        .join("work");
    // Each scene the process's rows name is loaded once: a shard's rows, or every round's.
    let flown = match plan {
        Plan::Shard(shard) => &rows[shard.rows(rows.len())],
        Plan::Rounds(_) => &rows[..],
    };
    let mut setup = Setup::new(
        flown,
        (
            ArduCopter::from_flag_or_env(args.sitl.arducopter.as_deref()),
            px4(args.sitl.px4.as_deref()),
        ),
        args.speedup,
        work,
        shutdown,
    );
    setup.record_feed = args.keep_work;
    setup.record_rows = args.runs.rerun_rows.clone();
    let study = Study {
        args,
        manifest: manifest_path,
        rows: &rows,
        out,
        setup: &setup,
    };
    match plan {
        Plan::Shard(shard) => {
            let range: Vec<usize> = shard.rows(rows.len()).collect();
            study.fly_part(&range, shard, &out.join(shard.file_name()))
        }
        Plan::Rounds(pct) => study.until_converged(pct),
    }
}

/// What one `savsim study` process flies.
#[derive(Clone, Copy)]
enum Plan {
    /// One shard of the manifest.
    Shard(Shard),
    /// Rounds until the ratios are within this percentage (`--until-converged`).
    Rounds(f64),
}

/// The flags that need no file to be checked.
fn check_flags(args: &StudyArgs) -> Result<()> {
    if !(1..=MAX_JOBS).contains(&args.jobs) {
        return Err(Error::Usage(format!(
            "--jobs {}: give 1 to {MAX_JOBS}",
            args.jobs
        )));
    }
    if !(SPEEDUP_RANGE.0..=SPEEDUP_RANGE.1).contains(&args.speedup) {
        return Err(Error::Usage(format!(
            "--speedup {}: give {} to {}",
            args.speedup, SPEEDUP_RANGE.0, SPEEDUP_RANGE.1
        )));
    }
    if let Some(pct) = args.until_converged {
        if !(pct > 0.0 && pct <= 100.0) {
            return Err(Error::Usage(format!(
                "--until-converged {pct}: give a percentage above 0 and at most 100"
            )));
        }
        if args.runs.shard.is_some() {
            return Err(Error::Usage(
                "--until-converged flies its rounds one after another: not with --shard".into(),
            ));
        }
    }
    if args.round_pairs == 0 {
        return Err(Error::Usage("--round-pairs 0: give at least 1".into()));
    }
    Ok(())
}

/// A study ready to fly: its flags, manifest, rows, results directory and setup.
struct Study<'a> {
    args: &'a StudyArgs,
    manifest: &'a Path,
    rows: &'a [manifest::StudyRow],
    out: &'a Path,
    setup: &'a Setup,
}

impl Study<'_> {
    /// Fly the rows at `indexes` and write their results to `path` (as part `part` of the
    /// study, in its metadata); what they found printed.
    fn fly_part(&self, indexes: &[usize], part: Shard, path: &Path) -> Result<()> {
        let rows: Vec<(usize, &manifest::StudyRow)> =
            indexes.iter().map(|&i| (i, &self.rows[i])).collect();
        let results = fly_rows(&rows, self.args, self.setup);
        if self.setup.stop.load(Ordering::Relaxed) {
            return Err(Error::Runtime(format!(
                "study: stopped by a signal; {} was not written (run it again)",
                path.display()
            )));
        }
        crate::study::table::write_atomic(&results, &self.settings(part), path)?;
        print!("{}", report(&results, path));
        Ok(())
    }

    /// `--until-converged PCT`: rounds of `--round-pairs` pairs (a round whose file exists is
    /// kept, unless `--force`), the ratios of every round so far judged after each from the
    /// second on; stops when they are within `pct`, or when the manifest is flown.
    fn until_converged(&self, pct: f64) -> Result<()> {
        let rounds = converge::rounds(self.rows, self.args.round_pairs);
        let nominal = self.args.runs.nominal.as_str();
        let mut pairs = 0;
        for (k, indexes) in rounds.iter().enumerate() {
            let path = self.out.join(converge::file_name(k));
            let part = Shard {
                index: k,
                count: rounds.len(),
            };
            if path.exists() && !self.args.runs.force {
                eprintln!("study: round {k} is done ({} exists): kept", path.display());
            } else {
                self.fly_part(indexes, part, &path)?;
            }
            pairs += distinct_pairs(self.rows, indexes);
            if k + 1 < converge::MIN_ROUNDS {
                continue;
            }
            let summary = crate::study::summarize::read_dir(self.out)?;
            let ratios = crate::daa::ratios::ratios(&summary.outcomes, nominal);
            let (within, judged) = converge::judge(&ratios, &self.args.converge_on, pct, nominal);
            let said = format!(
                "after {} rounds ({pairs} pairs): {}",
                k + 1,
                converge::line(&judged)
            );
            if within {
                println!("study: converged within {pct}% {said}");
                return Ok(());
            }
            eprintln!("study: not yet within {pct}% {said}");
        }
        println!(
            "study: the manifest's {pairs} pairs are flown and the ratios are not within {pct}% \
             (a larger manifest goes on from here: its first rounds' files are kept)"
        );
        Ok(())
    }

    /// What a part's file says of how it was made.
    fn settings(&self, part: Shard) -> Settings {
        let setup = self.setup;
        let mut more = vec![
            ("speedup", self.args.speedup.to_string()),
            ("jobs", self.args.jobs.to_string()),
            (
                "arducopter",
                setup
                    .arducopter
                    .as_ref()
                    .map(|a| a.binary.display().to_string())
                    .unwrap_or_default(),
            ),
            (
                "px4",
                setup
                    .px4
                    .as_ref()
                    .map(|p| p.binary.display().to_string())
                    .unwrap_or_default(),
            ),
        ];
        if let Some(pct) = self.args.until_converged {
            more.push(("until_converged", pct.to_string()));
            let on: Vec<String> = self
                .args
                .converge_on
                .iter()
                .map(|r| format!("{r:?}"))
                .collect();
            more.push(("converge_on", on.join(",").to_lowercase()));
            more.push(("round_pairs", self.args.round_pairs.to_string()));
        }
        Settings {
            command: "study",
            manifest: self.manifest.display().to_string(),
            shard: part,
            more,
        }
    }
}

/// How many pairs the rows at `indexes` fly.
fn distinct_pairs(rows: &[manifest::StudyRow], indexes: &[usize]) -> usize {
    let pairs: std::collections::HashSet<String> =
        indexes.iter().map(|&i| rows[i].pair_or(i)).collect();
    pairs.len()
}

/// Fly `rows`, each reported on stderr as it ends (and its folder removed when it flew,
/// unless `--keep-work`).
fn fly_rows(
    rows: &[(usize, &manifest::StudyRow)],
    args: &StudyArgs,
    setup: &Setup,
) -> Vec<StudyResult> {
    let finished = std::sync::atomic::AtomicUsize::new(0);
    let on_done = |r: &StudyResult| {
        let k = finished.fetch_add(1, Ordering::Relaxed) + 1;
        eprintln!(
            "study: {k}/{} {}: {}{} ({:.1} s of its clock in {:.1} s)",
            rows.len(),
            r.row_id,
            r.outcome.name(),
            r.error
                .as_deref()
                .map(|e| format!(": {e}"))
                .unwrap_or_default(),
            r.sim_s,
            r.wall_s
        );
        let folder = setup.work.join(crate::runs::row_name(r.index, &r.row_id));
        keep_recording(r, &folder, setup, &args.runs.nominal);
        if !args.keep_work && r.outcome != Outcome::Error {
            let _ = std::fs::remove_dir_all(folder);
        }
    };
    crate::study::run_rows(rows, args.jobs, setup, &on_done)
}

/// Move row `r`'s recording (when it made one) beside the results if `--rerun-rows` keeps it,
/// else remove it; what happened said on stderr.
fn keep_recording(r: &StudyResult, folder: &Path, setup: &Setup, nominal: &str) {
    let made = folder.join(crate::study::row::RECORDING);
    let Some(choice) = setup.record_rows.as_ref().filter(|_| made.is_file()) else {
        return;
    };
    let variant = r.inputs.variant.as_deref().unwrap_or("nominal");
    if !choice.keeps(&r.row_id, variant, r.outcome.name(), nominal) {
        let _ = std::fs::remove_file(&made);
        return;
    }
    // The results directory: the work folder's parent.
    let out = setup.work.parent().unwrap_or(&setup.work);
    match crate::runs::recordings::keep(&made, out, r.index, &r.row_id) {
        Ok(kept) => eprintln!("study: {}: recording {}", r.row_id, kept.display()),
        Err(e) => eprintln!("study: {}: the recording was not kept: {e}", r.row_id),
    }
}

/// PX4 from `--px4` or `SAVSIM_PX4` (its `etc` folder beside its `bin` folder).
fn px4(flag: Option<&Path>) -> Option<Px4> {
    let binary = flag
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("SAVSIM_PX4").map(PathBuf::from))?;
    Some(Px4 {
        binary: std::fs::canonicalize(&binary).unwrap_or(binary),
    })
}

/// What a shard found, for a person at a terminal.
fn report(results: &[StudyResult], path: &Path) -> String {
    let count = |o: Outcome| results.iter().filter(|r| r.outcome == o).count();
    let mut text = format!(
        "{} rows: {} collision, {} nmac, {} soft_fail, {} pass, {} error; written to {}\n",
        results.len(),
        count(Outcome::Collision),
        count(Outcome::Nmac),
        count(Outcome::SoftFail),
        count(Outcome::Pass),
        count(Outcome::Error),
        path.display()
    );
    for r in results.iter().filter(|r| r.error.is_some()).take(10) {
        text += &format!("  {}: {}\n", r.row_id, r.error.as_deref().unwrap_or(""));
    }
    text
}

/// `--equipage none,one,both`: each named once at most.
fn parse_equipage(text: &str) -> Result<Vec<crate::study::gen::Equipage>> {
    let mut list = Vec::new();
    for name in text.split(',') {
        let e = crate::study::gen::Equipage::parse(name).ok_or_else(|| {
            Error::Usage(format!(
                "--equipage {text:?}: {name:?} is not none, one or both"
            ))
        })?;
        if list.contains(&e) {
            return Err(Error::Usage(format!("--equipage {text:?}: {name:?} twice")));
        }
        list.push(e);
    }
    Ok(list)
}

/// `study gen`: the manifest `study.csv` in `out`, and one scene per approach.
fn gen(
    kind: StudyGenKind,
    autopilot: &str,
    (n, seed): (usize, u64),
    (model, equipage): (Option<&Path>, Option<&str>),
    sensors: &[String],
    out: &Path,
) -> Result<()> {
    let equipage = equipage.map(parse_equipage).transpose()?;
    if equipage.is_some() && (kind != StudyGenKind::Encounters || model.is_some()) {
        return Err(Error::Usage(
            "--equipage: only with --kind encounters and no --model (a model's aircraft fly \
             at a manned aircraft's speeds, beyond a copter's)"
                .into(),
        ));
    }
    for set in sensors {
        crate::feed::sensors_for(Some(set), None)?;
    }
    if n == 0 || n > 1_000_000 {
        return Err(Error::Usage(format!("--n {n}: give 1 to 1000000")));
    }
    if model.is_some() && kind != StudyGenKind::Encounters {
        return Err(Error::Usage("--model: only with --kind encounters".into()));
    }
    let px4 = match (autopilot, kind) {
        ("arducopter", _) => false,
        ("px4", StudyGenKind::Encounters) if equipage.is_some() || model.is_some() => {
            return Err(Error::Usage(
                "--autopilot px4 --kind encounters: the straight crossings only (not \
                 --equipage or --model)"
                    .into(),
            ))
        }
        ("px4", _) => true,
        (other, _) => {
            return Err(Error::Usage(format!(
                "--autopilot {other:?}: give arducopter or px4"
            )))
        }
    };
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let rows: Vec<_> = match kind {
        StudyGenKind::Approaches => {
            let approaches = crate::study::gen::approaches_for(n, seed, px4);
            for a in &approaches {
                let path = out.join(&a.scene_file);
                std::fs::write(&path, &a.scene_toml).map_err(|e| Error::file(&path, e))?;
            }
            approaches.into_iter().flat_map(|a| a.rows).collect()
        }
        StudyGenKind::Encounters if equipage.is_some() => {
            let equipage = equipage.unwrap_or_default();
            crate::study::gen::cooperative_encounters(n, seed, &equipage)
                .into_iter()
                .flatten()
                .collect()
        }
        StudyGenKind::Encounters => match model {
            None => crate::study::gen::encounters_for(n, seed, px4),
            Some(path) => {
                let text = crate::files::read_text(path, crate::files::MAX_TABLE_FILE_BYTES)
                    .map_err(|e| Error::file(path, e))?;
                let model = crate::daa::encounter_model::Model::parse(&text)
                    .map_err(|e| Error::Usage(format!("--model {}: {e}", path.display())))?;
                crate::study::gen::model_encounters(n, seed, &model)?
            }
        }
        .into_iter()
        .flatten()
        .collect(),
    };
    let rows = crate::study::gen::per_sensor_set(rows, sensors);
    let path = out.join("study.csv");
    let file = std::fs::File::create(&path).map_err(|e| Error::file(&path, e))?;
    manifest::write_csv(&rows, std::io::BufWriter::new(file))
        .map_err(|e| Error::file(&path, std::io::Error::other(e)))?;
    println!(
        "{} rows ({n} pairs) written to {}",
        rows.len(),
        path.display()
    );
    Ok(())
}
