//! `savsim batch` on the command line: read the manifest, pick the shard, skip it if it is
//! done, run it with a progress bar, write its file, print what it found.

use std::path::Path;

use crate::batch::gen::{self, GenOptions};
use crate::batch::manifest;
use crate::batch::row::RunRow;
use crate::cli::{BatchArgs, BatchCommand, SummarizeArgs};
use crate::error::{Error, Result};
use crate::pipeline::Mode;
use crate::runs::shard::Shard;
use crate::runs::table::Settings;

/// An MIT LL encounter model file.
fn read_model(path: &Path) -> Result<crate::daa::encounter_model::Model> {
    let text = crate::files::read_text(path, crate::files::MAX_TABLE_FILE_BYTES)
        .map_err(|e| Error::file(path, e))?;
    crate::daa::encounter_model::Model::parse(&text).map_err(|e| Error::Daa {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// An em-pairing-uncor-importancesampling `.ini` file's pairing settings.
fn read_pairing(path: &Path) -> Result<crate::daa::pairing_ini::PairingSettings> {
    let text = crate::files::read_text(path, crate::files::MAX_TABLE_FILE_BYTES)
        .map_err(|e| Error::file(path, e))?;
    crate::daa::pairing_ini::PairingSettings::parse(&text).map_err(|e| Error::Daa {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Run `savsim batch ...`: generate a manifest of encounters, summarize a results directory,
/// or run one shard of a manifest.
pub fn run(args: &BatchArgs) -> Result<()> {
    match &args.command {
        Some(BatchCommand::GenEncounters {
            n,
            seed,
            scene,
            mode,
            duration_s,
            rate_hz,
            intruder_kind,
            model,
            pairing,
            out,
        }) => {
            let scene = scene
                .as_ref()
                .map(|p| std::fs::canonicalize(p).map_err(|e| Error::file(p, e)))
                .transpose()?;
            let options = GenOptions {
                n: *n,
                seed: *seed,
                scene: scene.map(|p| p.to_string_lossy().into_owned()),
                mode: Mode::from(*mode).name().into(),
                duration_s: duration_s.unwrap_or(180.0),
                rate_hz: *rate_hz,
                intruder_kind: intruder_kind.clone(),
            };
            let runs = generate(options, model.as_deref(), pairing.as_deref(), *duration_s)?;
            write_manifest(&runs, out.as_deref())
        }
        Some(BatchCommand::Summarize(SummarizeArgs { dir, nominal, json })) => {
            crate::batch::summarize::read_dir(dir)?.print(nominal, *json);
            Ok(())
        }
        Some(BatchCommand::Report(report)) => {
            let summary = crate::batch::summarize::read_dir(&report.dir)?;
            let options = crate::runs::report::Options {
                command: "batch",
                nominal: &report.nominal,
                failing_rows_only: true,
            };
            crate::runs::report::command(&report.dir, report.out.as_deref(), &summary, options)
        }
        None => run_shard(args),
    }
}

/// The encounters: straight lines, or sampled from an encounter `model`, paired by importance
/// sampling when `pairing` is given (its `sample_time` is their length: a `duration_s` given
/// too must equal it).
fn generate(
    mut options: GenOptions,
    model: Option<&Path>,
    pairing: Option<&Path>,
    duration_s: Option<f64>,
) -> Result<Vec<manifest::Run>> {
    match (model, pairing) {
        (None, _) => gen::encounters(&options),
        (Some(path), None) => crate::batch::gen_model::encounters(&options, &read_model(path)?),
        (Some(path), Some(ini)) => {
            let settings = read_pairing(ini)?;
            let length = settings.duration_s as f64;
            if duration_s.is_some_and(|d| d != length) {
                return Err(Error::Usage(format!(
                    "--duration-s: {} s, but {} sets sample_time = {length} s: give one",
                    duration_s.unwrap_or_default(),
                    ini.display()
                )));
            }
            options.duration_s = length;
            crate::batch::gen_pairing::encounters(&options, &read_model(path)?, &settings)
        }
    }
}

/// Write a manifest as CSV to `out` (stdout when `None`).
fn write_manifest(runs: &[manifest::Run], out: Option<&Path>) -> Result<()> {
    let csv_error = |path: &Path, e: csv::Error| Error::file(path, std::io::Error::other(e));
    match out {
        Some(path) => {
            let file = std::fs::File::create(path).map_err(|e| Error::file(path, e))?;
            manifest::write_csv(runs, std::io::BufWriter::new(file)).map_err(|e| csv_error(path, e))
        }
        None => manifest::write_csv(runs, std::io::stdout().lock())
            .map_err(|e| csv_error(Path::new("stdout"), e)),
    }
}

/// One shard of a manifest (`--shard`, or the scheduler's variables) run on `--jobs` threads
/// into its Parquet file in `--out`; skipped when that file exists (unless `--force`).
fn run_shard(args: &BatchArgs) -> Result<()> {
    let (Some(manifest_path), Some(out)) = (&args.runs.manifest, &args.runs.out) else {
        return Err(Error::Usage("give a manifest and --out DIR".into()));
    };
    if let Some(jobs) = args.jobs.filter(|j| !(1..=1024).contains(j)) {
        return Err(Error::Usage(format!("--jobs {jobs}: give 1 to 1024")));
    }
    let runs = manifest::load(manifest_path)?;
    let shard = Shard::from_args(args.runs.shard.as_deref(), |v| std::env::var(v).ok())?;
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let path = out.join(shard.file_name());
    if path.exists() && !args.runs.force {
        eprintln!(
            "batch: shard {}/{} is done ({} exists): skipped",
            shard.index,
            shard.count,
            path.display()
        );
        return Ok(());
    }
    let range = shard.rows(runs.len());
    let bar = (!args.no_progress && std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .then(|| indicatif::ProgressBar::new(range.len() as u64));
    let recorder = args
        .runs
        .rerun_rows
        .as_ref()
        .map(|choice| crate::batch::record::Recorder {
            choice,
            out,
            nominal: &args.runs.nominal,
        });
    let rows = crate::batch::run_rows(
        &runs[range.clone()],
        range.start,
        args.jobs,
        recorder,
        |_| {
            if let Some(bar) = &bar {
                bar.inc(1);
            }
        },
    )?;
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let settings = Settings {
        command: "batch",
        manifest: manifest_path.display().to_string(),
        shard,
        more: vec![(
            "jobs",
            args.jobs
                .map_or_else(|| "all cores".into(), |j| j.to_string()),
        )],
    };
    crate::batch::table::write_atomic(&rows, &settings, &path)?;
    print!("{}", report(&rows, &path));
    Ok(())
}

/// What a shard found, for a person at a terminal.
pub fn report(rows: &[RunRow], path: &Path) -> String {
    let count = |f: fn(&RunRow) -> bool| rows.iter().filter(|r| f(r)).count();
    let mut text = format!(
        "{} runs: {} with a collision, {} NMAC, {} failed; written to {}\n",
        rows.len(),
        count(|r| r.measured.collisions > 0),
        count(|r| r.measured.nmac),
        count(|r| r.error.is_some()),
        path.display()
    );
    for r in rows.iter().filter(|r| r.error.is_some()).take(10) {
        text += &format!("  {}: {}\n", r.run_id, r.error.as_deref().unwrap_or(""));
    }
    text
}
