//! The command line of the commands that run manifests: `savsim batch` and `savsim study`,
//! their shards, recordings, SITL builds, summaries, reports and generators.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};

use super::ModeArg;

/// `savsim study`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct StudyArgs {
    /// Summarize or generate instead of running.
    #[command(subcommand)]
    pub command: Option<StudyCommand>,
    /// The manifest, its results, its shard, its recordings.
    #[command(flatten)]
    pub runs: RunsArgs,
    /// SITLs at once (default 1).
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// SITL speedup for rows that name none.
    #[arg(long, default_value_t = 1.0)]
    pub speedup: f64,
    /// The autopilots' SITL builds.
    #[command(flatten)]
    pub sitl: SitlArgs,
    /// Keep each row's SITL folder (eeprom, logs, console, savsim's summary and, for a row
    /// with a feed, every frame the feed sent as `feed.tlog`) under OUT/work (default: removed
    /// after a row that flew).
    #[arg(long)]
    pub keep_work: bool,
    /// Run without a network namespace even where one can be made (SITL then binds its TCP
    /// ports on every interface).
    #[arg(long)]
    pub no_netns: bool,
    /// Fly the manifest's pairs in rounds (OUT/round-NNNNN.parquet) until every ratio of
    /// --converge-on has a 95% interval whose half-width is within PCT percent of its value,
    /// judged after each round from the second on; the manifest is the budget.
    #[arg(long, value_name = "PCT")]
    pub until_converged: Option<f64>,
    /// The ratios --until-converged judges, separated by commas.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = crate::runs::summary::Ratio::DEFAULT)]
    pub converge_on: Vec<crate::runs::summary::Ratio>,
    /// Pairs per round of --until-converged.
    #[arg(long, default_value_t = 50)]
    pub round_pairs: usize,
}

/// A manifest's runs (`savsim batch`, `savsim study`): where the results go, which shard this
/// process runs, which rows are kept as recordings.
#[derive(Debug, Args)]
pub struct RunsArgs {
    /// The manifest: .csv, .toml (`[[run]]` tables) or .json (docs/batch.md, docs/study.md).
    #[arg(required = true)]
    pub manifest: Option<PathBuf>,
    /// The directory the shard files are written to (created if missing; a study's rows'
    /// SITL folders go under its work/).
    #[arg(long, required = true)]
    pub out: Option<PathBuf>,
    /// Run one shard: `K/N` (K from 0), or `N` with K from SLURM_ARRAY_TASK_ID or
    /// JOB_COMPLETION_INDEX. A Slurm array task needs no flag.
    #[arg(long)]
    pub shard: Option<String>,
    /// Run the shard even if its file exists (replacing it).
    #[arg(long)]
    pub force: bool,
    /// Save rows as rerun recordings in OUT/rows/: `failed` (rows not `pass` in a variant
    /// other than the nominal one, `pass` in the nominal one, or errors), `all`, or row ids
    /// separated by commas (docs/batch.md, docs/study.md).
    #[arg(long)]
    pub rerun_rows: Option<crate::runs::recordings::RowChoice>,
    /// The variant the others are compared with (--until-converged, and which rows
    /// `--rerun-rows failed` keeps).
    #[arg(long, default_value = "nominal")]
    pub nominal: String,
}

/// The autopilots' SITL builds a study flies (docs/study.md).
#[derive(Debug, Args)]
pub struct SitlArgs {
    /// ArduCopter SITL binary (default: SAVSIM_ARDUCOPTER); defaults files from
    /// SAVSIM_ARDUCOPTER_DEFAULTS (comma-separated).
    #[arg(long)]
    pub arducopter: Option<PathBuf>,
    /// PX4 SITL binary, `px4` of px4_sitl_default, flown with SIH (default: SAVSIM_PX4).
    #[arg(long)]
    pub px4: Option<PathBuf>,
}

/// What `savsim study gen` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StudyGenKind {
    /// A box across a straight path.
    Approaches,
    /// An intruder crossing a hovering copter, reported as ADS-B.
    Encounters,
}

/// `savsim study summarize` and `savsim batch summarize`.
#[derive(Debug, Args)]
pub struct SummarizeArgs {
    /// The results directory (its *.parquet shard files).
    pub dir: PathBuf,
    /// The variant the others are compared with.
    #[arg(long, default_value = "nominal")]
    pub nominal: String,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `savsim study report` and `savsim batch report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// The results directory (its *.parquet shard files).
    pub dir: PathBuf,
    /// Where the page goes (default DIR/report.html).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The variant the others are compared with.
    #[arg(long, default_value = "nominal")]
    pub nominal: String,
}

/// `savsim study ...` subcommands.
#[derive(Debug, Subcommand)]
pub enum StudyCommand {
    /// Per variant: outcome counts and weighted collision, NMAC and loss-of-well-clear rates;
    /// each variant's ratios against the nominal one over the pairs flown under both, with
    /// 95% bootstrap intervals.
    Summarize(SummarizeArgs),
    /// One self-contained HTML page of a results directory: outcome counts and risk ratios
    /// as charts, histograms of the closest approaches, the rows with links to their
    /// recordings, and how the results were made (docs/study.md).
    Report(ReportArgs),
    /// Write pairs of rows, each as `nominal` (avoidance off) and `mitigated` (on):
    /// `approaches` (a box of random size, offset and yaw across a straight path flown at a
    /// random speed and heading; the proximity feed and ArduCopter's proximity avoidance) or
    /// `encounters` (an intruder crossing a hovering copter; the ADS-B feed and ArduCopter's
    /// ADS-B avoidance).
    Gen {
        /// `approaches` or `encounters`.
        #[arg(long, value_enum, default_value_t = StudyGenKind::Approaches)]
        kind: StudyGenKind,
        /// `arducopter` or `px4` (approaches only): which autopilot's parameters and feed.
        #[arg(long, default_value = "arducopter")]
        autopilot: String,
        /// How many pairs.
        #[arg(long)]
        n: usize,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// With `--kind encounters`: the intruder's track sampled from this MIT LL encounter
        /// model (e.g. scenes/encounter-models/uncor_1200code_v2p1.txt: turns, climbs and
        /// speed changes) instead of a straight line; misses drawn wider (docs/study.md).
        #[arg(long)]
        model: Option<PathBuf>,
        /// Fly each pair's mitigated row once per sensor set (repeat the flag; each a
        /// `--sensors` list, e.g. `--sensors ideal --sensors adsb-1090es:nacp=7`): variants
        /// `mitigated/SET`, each against the same `nominal` row (docs/sensors.md).
        #[arg(long)]
        sensors: Vec<String>,
        /// With `--kind encounters`: two ArduCopters per encounter, each on its own SITL, one
        /// row per equipage in this list (`none,one,both`: which of them avoid; the variant is
        /// its name), over the same drawn geometries (docs/study.md, "Several autopilots").
        #[arg(long)]
        equipage: Option<String>,
        /// Where the manifest and its scenes go (created).
        #[arg(long)]
        out: PathBuf,
    },
}

/// `savsim batch`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct BatchArgs {
    /// Generate a manifest instead of running one.
    #[command(subcommand)]
    pub command: Option<BatchCommand>,
    /// The manifest, its results, its shard, its recordings (a row is flown again after it
    /// ran to be recorded: a tlog replayed, an encounter's samples).
    #[command(flatten)]
    pub runs: RunsArgs,
    /// Worker threads (default: every core).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub no_progress: bool,
}

/// `savsim batch ...` subcommands.
#[derive(Debug, Subcommand)]
pub enum BatchCommand {
    /// Write a deterministic manifest of pairwise encounters, their closest approach and NMAC
    /// known by construction (distributions in docs/batch.md).
    GenEncounters {
        /// How many.
        #[arg(long)]
        n: usize,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// A scene for every encounter (default: open air).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Collision mode for every encounter.
        #[arg(long, value_enum, default_value_t = ModeArg::Exact)]
        mode: ModeArg,
        /// Length of each encounter, seconds (default 180; with `--pairing`, the file's
        /// `sample_time`).
        #[arg(long)]
        duration_s: Option<f64>,
        /// Ownship samples per second.
        #[arg(long, default_value_t = 10.0)]
        rate_hz: f64,
        /// The intruder's kind (a320, b737, dji, airship, balloon).
        #[arg(long, default_value = "dji")]
        intruder_kind: String,
        /// Sample both tracks from this MIT LL encounter model (e.g.
        /// scenes/encounter-models/uncor_1200code_v2p1.txt) instead of straight lines (docs/batch.md).
        #[arg(long)]
        model: Option<PathBuf>,
        /// Pair the model's tracks by importance sampling with the settings of this
        /// em-pairing-uncor-importancesampling `.ini` file (e.g.
        /// scenes/encounter-models/pairing.ini), each encounter with its weight `w`
        /// (docs/daa.md). Needs `--model`.
        #[arg(long, requires = "model")]
        pairing: Option<PathBuf>,
        /// Write the manifest here (.csv; default: stdout).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Weighted NMAC and loss-of-well-clear rates per `variant`, and each variant's risk
    /// ratios against the nominal one over the `pair`s flown under both, with 95% bootstrap
    /// intervals, from a results directory's shards (docs/batch.md).
    Summarize(SummarizeArgs),
    /// One self-contained HTML page of a results directory: outcome counts and risk ratios
    /// as charts, histograms of the closest approaches, the rows with links to their
    /// recordings, and how the results were made (docs/batch.md).
    Report(ReportArgs),
}
