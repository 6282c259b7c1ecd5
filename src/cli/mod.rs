//! The command line, parsed raw by clap and then validated into typed options.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::pipeline::Mode;

mod runs;

pub use runs::{
    BatchArgs, BatchCommand, ReportArgs, RunsArgs, SitlArgs, StudyArgs, StudyCommand, StudyGenKind,
    SummarizeArgs,
};

/// savsim: sense-and-avoid simulation for UAVs over MAVLink.
#[derive(Debug, Parser)]
#[command(name = "savsim", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// savsim's commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Replay the bundled flight over the bundled city and print what happened.
    Demo(DemoArgs),
    /// Replay a tlog, a PX4 ULog or an ArduPilot DataFlash log, optionally over a scene.
    Replay(ReplayArgs),
    /// Connect to a vehicle or SITL and mirror it live, optionally over a scene.
    Live(LiveArgs),
    /// Record what a live connection receives as a standard tlog.
    Record(RecordArgs),
    /// Generate or inspect scenes.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Measure every collision mode's cost and accuracy (against the reference) on a
    /// generated flight set, scene sizes 10^2..10^6 and fleets of 1..1000 vehicles.
    Bench(BenchArgs),
    /// Run a manifest of tlogs and encounters on every core, one Parquet row per run; or
    /// generate encounters (`batch gen-encounters`).
    Batch(BatchArgs),
    /// Alerting on a DAIDALUS state file (.daa) with a DAIDALUS configuration (.conf): one CSV
    /// row per time step and intruder, in the columns, order and units of DAIDALUS's
    /// DaidalusAlerting (docs/daa.md).
    Daa(DaaArgs),
    /// Closed-loop studies: each row starts its own SITL autopilot, flies its plan with
    /// savsim's feed and scene, and is scored; `study summarize` gives the risk ratios,
    /// `study gen` writes obstacle-approach pairs (docs/study.md).
    Study(StudyArgs),
    /// Fly ArduCopter SITLs in savsim's world by hand: savsim flies the vehicles (lockstep),
    /// each autopilot's SERIAL1 goes to a ground station, the world to the viewer
    /// (docs/lockstep.md).
    Sim(SimArgs),
}

/// `savsim sim`.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// How many ArduCopters, each 5 m east of the last (system ids 1..N).
    #[arg(long, default_value_t = 1)]
    pub count: usize,
    /// The frame: a preset (arducopter-quad, arducopter-quad-x, iris) or a TOML file.
    #[arg(long, default_value = "arducopter-quad")]
    pub frame: String,
    /// The physics step, milliseconds.
    #[arg(long, default_value_t = 2.5)]
    pub step_ms: f64,
    /// Times real time (0: as fast as the autopilots go).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// A constant wind, `E N U` m/s where the air goes.
    #[arg(long)]
    pub wind: Option<String>,
    /// Stop after this many seconds of the clock (default: at Ctrl-C).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Each vehicle's SERIAL1 goes here (where QGroundControl listens; MAVProxy:
    /// `--master udp:127.0.0.1:14550`).
    #[arg(long, default_value = "udpclient:127.0.0.1:14550")]
    pub gcs: String,
    /// The first vehicle's SITL instance (`-I`; its physics port 9002 + 10 N); the next
    /// vehicles take the next ones.
    #[arg(long, default_value_t = 0)]
    pub instance: u16,
    /// Where each SITL's folder goes (its eeprom, logs): `DIR/vehicle-K`.
    #[arg(long, default_value = "sim-work")]
    pub work: PathBuf,
    /// Collision options (the scene; without one, flat ground at CMAC).
    #[command(flatten)]
    pub collision: CollisionArgs,
    /// The feed each vehicle gets.
    #[command(flatten)]
    pub feed: FeedArgs,
    /// ArduCopter SITL.
    #[command(flatten)]
    pub sitl: SitlArgs,
}

/// savsim's own MAVLink identity on a live link (docs/live.md).
#[derive(Debug, Clone, Copy, Args)]
pub struct IdentityArgs {
    /// savsim's system id (default 245: not 255, the ground stations' and ArduPilot's
    /// SYSID_MYGCS). Its feed is this system's component 196.
    #[arg(long, default_value_t = 245, value_parser = clap::value_parser!(u8).range(1..=255))]
    pub sysid: u8,
    /// savsim's component id as a ground station (default 190, MAV_COMP_ID_MISSIONPLANNER;
    /// not 196, the feed's).
    #[arg(long, default_value_t = 190, value_parser = clap::value_parser!(u8).range(1..=255))]
    pub compid: u8,
}

/// Ground stations through savsim, and MAVLink 2 signing (docs/live.md).
#[derive(Debug, Clone, Args)]
pub struct NetworkArgs {
    /// A ground station to route the vehicles to and its commands back from, addressed as
    /// --connect is (e.g. udpout:127.0.0.1:14550 where QGroundControl listens). Repeatable.
    #[arg(long)]
    pub forward: Vec<String>,
    /// Let the stations see savsim's own frames too (its heartbeat, requests and feed).
    #[arg(long)]
    pub forward_own: bool,
    /// Sign every frame savsim sends with this key, and check what vehicles send: a file of
    /// exactly 32 bytes is the key; anything else is a passphrase (one trailing newline
    /// ignored), hashed as MAVProxy's `signing setup` does.
    #[arg(long)]
    pub signing_key: Option<PathBuf>,
    /// accept: unsigned frames are taken (signed ones must be right); require: they are
    /// dropped. Needs --signing-key.
    #[arg(long, value_enum, default_value_t = SigningMode::Accept)]
    pub signing: SigningMode,
}

/// What `--signing` does with unsigned frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SigningMode {
    /// Taken (and counted).
    Accept,
    /// Dropped (and counted).
    Require,
}

/// `savsim daa`.
#[derive(Debug, Args)]
pub struct DaaArgs {
    /// The state file (.daa).
    pub scenario: PathBuf,
    /// The configuration (.conf), in DAIDALUS's format.
    #[arg(long)]
    pub conf: PathBuf,
    /// Where to write the CSV (default: standard output).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Decimal places (DAIDALUS's default, 6).
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u8).range(0..=16))]
    pub precision: u8,
}

/// `savsim bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Scenes: `city`, `mountain` (the bundled ones) or a scene file; repeat or separate with
    /// commas.
    #[arg(long, value_delimiter = ',', default_value = "city,mountain")]
    pub scene: Vec<String>,
    /// Only flights whose name contains one of these (comma-separated); default all.
    #[arg(long, value_delimiter = ',')]
    pub flights: Vec<String>,
    /// Modes to compare (`box` and `reference` always run: they are the cost and truth
    /// references).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "none,box,mesh,paper,exact,reference"
    )]
    pub modes: Vec<ModeArg>,
    /// Write the full report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw the cost-against-missed-collisions chart here (PNG).
    #[arg(long, default_value = "bench.png")]
    pub chart: PathBuf,
    /// Largest static scene of the scale run (10^2, 10^3, ... up to this; 0 skips it).
    #[arg(long, default_value_t = 1_000_000)]
    pub scale_max: usize,
    /// Largest fleet of the fleet run (1, 10, 100, ... up to this; 0 skips it).
    #[arg(long, default_value_t = 1000)]
    pub fleet_max: usize,
    /// The residency run's mesh budget, MiB: the first scene with every building a triangle
    /// mesh, the flight set in one run (0 skips it).
    #[arg(long, default_value_t = 64.0)]
    pub residency_budget_mib: f64,
    /// Do not run: print the report and draw the chart of a saved `--json` report.
    #[arg(long)]
    pub from_json: Option<PathBuf>,
    /// Length of the six rays, metres (0 shows what the rays cost).
    #[arg(long, default_value_t = 300.0)]
    pub ray_length_m: f64,
}

/// Options shared by everything that checks collisions.
#[derive(Debug, Clone, Args)]
pub struct CollisionArgs {
    /// The scene (TOML); without one, savsim only ingests.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// How contacts are decided (see docs/threat-model.md and docs/accuracy-vs-speed.md).
    #[arg(long, value_enum, default_value = "exact")]
    pub mode: ModeArg,
    /// Sensing frames per second (the paper's node, rays and beta) in `exact` mode.
    #[arg(long, default_value_t = 20.0)]
    pub sensor_hz: f64,
    /// The sensing layer's rays: `six` (the paper's body axes), `ring:N` (N around the body's
    /// horizontal plane, plus up and down) or `level-ring:N` (N around the horizon, levelled,
    /// plus up and down).
    #[arg(long, default_value = "six")]
    pub sensor_fan: String,
    /// Most memory resident triangle meshes may hold, MiB.
    #[arg(long, default_value_t = 512.0)]
    pub mesh_budget_mib: f64,
    /// Write events as JSON lines here.
    #[arg(long)]
    pub events: Option<PathBuf>,
    /// Write a JSON summary here at exit (also on Ctrl-C).
    #[arg(long)]
    pub summary_json: Option<PathBuf>,
    /// Most pairs each of the summary's lists of pairs holds (the closest; 0: every pair).
    #[arg(long, default_value_t = crate::session::summary::LISTED_PAIRS_MAX, allow_negative_numbers = true)]
    pub summary_pairs: usize,
    /// Length of the six rays, metres.
    #[arg(long, default_value_t = 300.0)]
    pub ray_length_m: f64,
    /// Near-miss distance, metres.
    #[arg(long, default_value_t = 10.0)]
    pub near_miss_m: f64,
    /// The well-clear volume losses of well clear are judged with: `small-uas` (2000 ft,
    /// 250 ft), `phase-1`, `phase-2`, `non-coop` (DO-365), `DTHR_M,ZTHR_M,TTHR_S,TCOA_S`, or
    /// `none` (not judged).
    #[arg(long, default_value = "small-uas")]
    pub well_clear: String,
    /// A separation minimum, metres: every pair of vehicles (and moving bodies) nearer than
    /// this (3D, between their reference points) is an event and in the summary, as a drone
    /// show or a swarm keeps its own spacing (at most 1000 m). Default: not judged.
    #[arg(long, allow_negative_numbers = true)]
    pub separation_m: Option<f64>,
    /// A show's slots (CSV: vehicle,t_s,east_m,north_m,up_m keyframes, seconds after the run's
    /// first vehicle position, scene ENU metres; docs/daa.md): a vehicle seen farther than
    /// --slot-tolerance-m from its slot has left it (an event, and in the summary).
    #[arg(long)]
    pub slots: Option<PathBuf>,
    /// How far from its slot a vehicle may be, metres (above 0, at most 1000; default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub slot_tolerance_m: Option<f64>,
    /// Telemetry gaps longer than this are reported and not swept, seconds.
    #[arg(long, default_value_t = 1.0)]
    pub max_gap_s: f64,
    /// Look-ahead time for the activation box around the vehicle, seconds.
    #[arg(long, default_value_t = 3.0)]
    pub look_ahead_s: f64,
    /// Beta above which a seen obstacle gets a mesh collider (paper: 50).
    #[arg(long, default_value_t = 50.0)]
    pub mesh_beta: f64,
    /// ... if it is closer than this, metres (paper: 300).
    #[arg(long, default_value_t = 300.0)]
    pub mesh_within_m: f64,
    /// A mesh collider farther than this turns back into a box, metres (paper: 800).
    #[arg(long, default_value_t = 800.0)]
    pub box_beyond_m: f64,
    /// A sample this far below the terrain is implausible and skipped, metres.
    #[arg(long, default_value_t = 50.0)]
    pub max_below_terrain_m: f64,
    /// Least time a collider keeps its state before it is downgraded, seconds.
    #[arg(long, default_value_t = 2.0)]
    pub hold_s: f64,
    /// Stream to rerun: save=OUT.rrd, connect[=URL] (a running viewer) or spawn.
    #[arg(long)]
    pub rerun: Option<String>,
    /// With --rerun: draw every octree leaf (default: each vehicle's node and the leaves
    /// touching it).
    #[arg(long)]
    pub rerun_octree: bool,
    /// AHP judgment matrix for T, V, A: nine numbers row by row, fractions allowed
    /// (default: the paper's Table 3, "1,7/3,3/2,3/7,1,5/4,2/3,4/5,1").
    #[arg(long)]
    pub ahp_matrix: Option<String>,
}

/// The closed-loop feed (docs/closed-loop.md): savsim as the vehicle's range sensors and
/// traffic source.
#[derive(Debug, Clone, Args)]
pub struct FeedArgs {
    /// What to send each vehicle, comma-separated: proximity (DISTANCE_SENSOR, 8 levelled
    /// sectors + up), rangefinder (DISTANCE_SENSOR down), obstacle-distance
    /// (OBSTACLE_DISTANCE, 72 bins, body FRD), adsb (ADSB_VEHICLE for the other aircraft),
    /// collision (COLLISION for savsim's threats). Off by default; needs --scene.
    #[arg(long)]
    pub feed: Option<String>,
    /// Feed frames per second of the vehicle's clock (every sample when telemetry is slower).
    #[arg(long, default_value_t = 20.0)]
    pub feed_hz: f64,
    /// The range sensors' nearest reading, metres.
    #[arg(long, default_value_t = 0.2)]
    pub feed_min_m: f64,
    /// The range sensors' farthest reading, metres ("nothing seen" is sent as this + 1 cm).
    #[arg(long, default_value_t = 40.0)]
    pub feed_max_m: f64,
    /// Proximity orientations sent (MAV_SENSOR_ORIENTATION): 0..7 the 45-degree sectors
    /// clockwise from the nose, 24 up.
    #[arg(long, value_delimiter = ',', default_value = "0,1,2,3,4,5,6,7,24")]
    pub feed_orientations: Vec<u8>,
    /// MAV_DISTANCE_SENSOR type of the readings (0 laser, 1 ultrasound, 2 infrared, 3 radar).
    #[arg(long, default_value_t = 0)]
    pub feed_sensor_type: u8,
    /// Aircraft farther than this are not sent as ADS-B, metres (ArduCopter's
    /// ADSB_LIST_RADIUS default; ArduPlane's is 10000): where they are sent at, their truth or a
    /// modelled receiver's report of them.
    #[arg(long, default_value_t = 2000.0)]
    pub feed_adsb_radius_m: f64,
    /// The vehicle's sensors the feed sends from: `ideal` (exact), or devices: presets with
    /// settings and files of [[sensor]] tables, e.g.
    /// `realsense-d435,tfmini-down,adsb-1090es:nacp=7` (docs/sensors.md). Default: the
    /// scene's [[sensor]] tables if it has any, else `ideal`.
    #[arg(long)]
    pub sensors: Option<String>,
    /// The seed of the sensors' errors (the same seed, the same errors at the same instants
    /// of the vehicle's clock).
    #[arg(long, default_value_t = 1)]
    pub sensor_seed: u64,
}

/// `savsim demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Collision options (the scene defaults to the bundled city).
    #[command(flatten)]
    pub collision: CollisionArgs,
    /// Pace, end, and the feed a live run would have sent.
    #[command(flatten)]
    pub playback: PlaybackArgs,
}

/// `savsim replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The tlog, ULog (.ulg) or DataFlash log (.bin) to replay (told apart by their first bytes).
    pub flight: PathBuf,
    /// Collision options.
    #[command(flatten)]
    pub collision: CollisionArgs,
    /// Never draw a progress bar.
    #[arg(long)]
    pub no_progress: bool,
    /// Pace, end, and the feed a live run would have sent.
    #[command(flatten)]
    pub playback: PlaybackArgs,
}

/// How a flight is played back (`savsim replay`, `savsim demo`): its pace, where it ends, and
/// the feed a live run would have sent.
#[derive(Debug, Args)]
pub struct PlaybackArgs {
    /// Replay speed: a factor of real time (1 = as flown), or `max`.
    #[arg(long, default_value = "max")]
    pub speed: String,
    /// Stop this many seconds after the first message (the clock of the report's "+N s"): for
    /// a recording that ends at a moment of interest.
    #[arg(long, allow_negative_numbers = true)]
    pub until_s: Option<f64>,
    /// The feed a live run would have sent.
    #[command(flatten)]
    pub feed: FeedArgs,
    /// savsim's MAVLink identity (`--sysid`, `--compid`).
    #[command(flatten)]
    pub identity: IdentityArgs,
    /// Write that feed here as a tlog, on the flight's time base (needs --feed).
    #[arg(long)]
    pub feed_out: Option<PathBuf>,
}

/// `savsim live`.
#[derive(Debug, Args)]
pub struct LiveArgs {
    /// The links, savsim's identity on them, ground stations and signing.
    #[command(flatten)]
    pub link: LinkArgs,
    /// Also record what is received to this tlog.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Collision options.
    #[command(flatten)]
    pub collision: CollisionArgs,
    /// The closed-loop feed.
    #[command(flatten)]
    pub feed: FeedArgs,
    /// Record every frame the feed sends to this tlog, as sent (needs --feed).
    #[arg(long)]
    pub feed_out: Option<PathBuf>,
    /// A planner of your own beside the vehicle.
    #[command(flatten)]
    pub companion: CompanionArgs,
}

/// A planner beside a live vehicle (docs/companion.md): handed the vehicle's state, what its
/// `--sensors` see and the traffic it was sent, at its instants on the vehicle's clock; its
/// commands go to the autopilot as a companion computer's.
#[derive(Debug, Clone, Args)]
pub struct CompanionArgs {
    /// The planner's command line, run by `sh -c` with `SAVSIM_COMPANION=127.0.0.1:PORT` set;
    /// its output goes to `companion.log` in the working folder.
    #[arg(long)]
    pub companion: Option<String>,
    /// Its instants a second of the vehicle's clock.
    #[arg(long, default_value_t = crate::companion::slot::DEFAULT_HZ, allow_negative_numbers = true)]
    pub companion_hz: f64,
    /// Its commands go at least this long after their instant, seconds of the vehicle's clock
    /// (on top of the planner's own time).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub companion_latency_s: f64,
    /// The system id of the vehicle it flies.
    #[arg(long, default_value_t = 1)]
    pub companion_sysid: u8,
    /// That vehicle's autopilot, whose mode names the planner's mode changes use: ardupilot
    /// or px4.
    #[arg(long, default_value = "ardupilot", value_parser = ["ardupilot", "px4"])]
    pub companion_autopilot: String,
}

/// `savsim record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// The links, savsim's identity on them, ground stations and signing.
    #[command(flatten)]
    pub link: LinkArgs,
    /// The tlog to write.
    pub out: PathBuf,
    /// Write a JSON summary here at exit.
    #[arg(long)]
    pub summary_json: Option<PathBuf>,
}

/// A live run's links (`savsim live`, `savsim record`; docs/live.md).
#[derive(Debug, Args)]
pub struct LinkArgs {
    /// udpin:HOST:PORT (listen), udpout:HOST:PORT, tcpout:HOST:PORT, or tcpin:HOST:PORT.
    /// Repeat for several links (SITLs on separate ports, a UDP and a TCP link).
    #[arg(long, required = true)]
    pub connect: Vec<String>,
    /// Rate to ask for GLOBAL_POSITION_INT and ATTITUDE at, Hz.
    #[arg(long, default_value_t = 20.0)]
    pub rate_hz: f64,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// savsim's MAVLink identity (`--sysid`, `--compid`).
    #[command(flatten)]
    pub identity: IdentityArgs,
    /// Ground stations and signing.
    #[command(flatten)]
    pub network: NetworkArgs,
}

/// Which scene to generate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SceneKind {
    /// Thousands of buildings, many concave.
    City,
    /// Ridged terrain with valleys and passes, and trees.
    Mountain,
}

/// `savsim scene ...`.
#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Generate a bundled-style scene (deterministic in the seed).
    Gen {
        /// city or mountain.
        kind: SceneKind,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write the scene here (default: stdout).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Describe a scene: obstacles by kind, triangles, bounds, memory.
    Info {
        /// The scene file.
        scene: PathBuf,
    },
    /// Send a scene (no flight) to rerun: save=OUT.rrd, connect[=URL] or spawn.
    Show {
        /// The scene file.
        scene: PathBuf,
        /// Where to: save=OUT.rrd, connect[=URL] or spawn.
        #[arg(long, default_value = "spawn")]
        rerun: String,
    },
}

/// `--mode` on the command line (the core's [`Mode`] knows nothing of clap).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// No collision checks.
    None,
    /// Every obstacle a box, at samples.
    Box,
    /// Every obstacle a triangle mesh, at samples.
    Mesh,
    /// The paper's algorithm as written.
    Paper,
    /// Exact shapes, swept; sensing beside it (the default).
    #[value(alias = "adaptive")]
    Exact,
    /// The ground truth (dense sub-stepping; slow).
    Reference,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::None => Mode::None,
            ModeArg::Box => Mode::Box,
            ModeArg::Mesh => Mode::Mesh,
            ModeArg::Paper => Mode::Paper,
            ModeArg::Exact => Mode::Exact,
            ModeArg::Reference => Mode::Reference,
        }
    }
}
