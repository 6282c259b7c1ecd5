//! The one place that wires things together: commands, threads, channels, signals, files.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use crate::bundled::{bundled, DEMO_FLIGHT, DEMO_SCENE};
use crate::cli::{
    BenchArgs, Cli, CollisionArgs, Command, DemoArgs, FeedArgs, LinkArgs, LiveArgs, RecordArgs,
    ReplayArgs, SceneCommand, SceneKind, SigningMode,
};
use crate::codec::signing::SigningKey;
use crate::collision::events::EventKind;
use crate::collision::sensing::threat::AhpWeights;
use crate::companion::slot::CompanionConfig;
use crate::error::{Error, Result};
use crate::links::address::ConnectAddress;
use crate::live::{self, LiveOptions, LiveRun};
use crate::pipeline::{CollisionConfig, SensorFan};
use crate::replay::{replay, Speed};
use crate::scene::{self, gen, Scene};
use crate::session::{write_json_atomic, Session};
use crate::world::SenderId;
use savsim_core::bounds::{positive, MAX_DURATION_S};

fn collision_config(args: &CollisionArgs) -> Result<CollisionConfig> {
    let defaults = CollisionConfig::default();
    let ahp = match &args.ahp_matrix {
        None => defaults.ahp,
        Some(text) => parse_ahp(text)?,
    };
    let config = CollisionConfig {
        mode: args.mode.into(),
        ray_length_m: args.ray_length_m,
        look_ahead_s: args.look_ahead_s,
        mesh_beta: args.mesh_beta,
        mesh_within_m: args.mesh_within_m,
        box_beyond_m: args.box_beyond_m,
        hold_s: args.hold_s,
        near_miss_m: args.near_miss_m,
        max_gap_s: args.max_gap_s,
        max_below_terrain_m: args.max_below_terrain_m,
        sensor_hz: args.sensor_hz,
        sensor_fan: SensorFan::parse(&args.sensor_fan)
            .map_err(|why| Error::Usage(format!("--sensor-fan {why}")))?,
        mesh_budget_mib: args.mesh_budget_mib,
        ahp,
        ..defaults
    };
    config.validate()?;
    Ok(config)
}

/// Parse nine comma-separated numbers (fractions like `7/3` allowed) into AHP weights.
fn parse_ahp(text: &str) -> Result<AhpWeights> {
    let bad = |why: &str| Error::Usage(format!("--ahp-matrix {text:?}: {why}"));
    let values = text
        .split(',')
        .map(|v| {
            let v = v.trim();
            match v.split_once('/') {
                Some((a, b)) => Some(a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?),
                None => v.parse::<f64>().ok(),
            }
        })
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| bad("not numbers"))?;
    let [a, b, c, d, e, f, g, h, i] = values[..] else {
        return Err(bad("give nine numbers, row by row"));
    };
    AhpWeights::from_matrix([[a, b, c], [d, e, f], [g, h, i]])
        .ok_or_else(|| bad("every entry must be positive and finite"))
}

/// A session as the collision options ask for: scene, thresholds, events file, rerun.
fn session_for(args: &CollisionArgs) -> Result<Session> {
    session_over(args, load_scene(args.scene.as_deref())?)
}

/// The largest `--separation-m`, metres: within the reach every tick judges approaches in
/// (NMAC's 152 m is always in it; the contact layer's and the feed's reaches often more).
const MAX_SEPARATION_M: f64 = 1000.0;

/// The largest `--slot-tolerance-m`, metres (`daa::slots` takes no more).
const MAX_SLOT_TOLERANCE_M: f64 = 1000.0;

/// The largest slots file read, bytes.
const SLOTS_MAX_BYTES: u64 = 1 << 30;

/// `--slots` read, with `--slot-tolerance-m` (which needs it).
fn slots_of(args: &CollisionArgs) -> Result<Option<crate::daa::slots::Slots>> {
    let Some(path) = &args.slots else {
        return match args.slot_tolerance_m {
            Some(_) => Err(Error::Usage("--slot-tolerance-m needs --slots".into())),
            None => Ok(None),
        };
    };
    let tolerance_m = args
        .slot_tolerance_m
        .map(|m| savsim_core::bounds::positive("--slot-tolerance-m", m, MAX_SLOT_TOLERANCE_M))
        .transpose()?
        .unwrap_or(1.0);
    let text = crate::files::read_text(path, SLOTS_MAX_BYTES).map_err(|e| Error::file(path, e))?;
    crate::daa::slots::Slots::parse(&text, tolerance_m)
        .map(Some)
        .map_err(|e| Error::Usage(format!("--slots {}: {e}", path.display())))
}

/// [`session_for`] over `scene` (loaded, or made).
fn session_over(args: &CollisionArgs, scene: Option<Arc<Scene>>) -> Result<Session> {
    let mut session = Session::new(scene, collision_config(args)?, args.events.as_deref())?;
    let volume = crate::daa::well_clear::setting(&args.well_clear).ok_or_else(|| {
        Error::Usage(format!(
            "--well-clear {}: {}",
            args.well_clear,
            crate::daa::well_clear::SETTING_HELP
        ))
    })?;
    let separation = args
        .separation_m
        .map(|m| savsim_core::bounds::positive("--separation-m", m, MAX_SEPARATION_M))
        .transpose()?
        .map(|minimum_m| crate::daa::separation::Separation { minimum_m });
    session.set_approaches(
        crate::daa::approach::Approaches::with_volume(volume).with_separation(separation),
    );
    if let Some(slots) = slots_of(args)? {
        session.set_slots(slots);
    }
    session.set_summary_pairs((args.summary_pairs > 0).then_some(args.summary_pairs));
    if let Some(target) = &args.rerun {
        start_viz(&mut session, target, args.rerun_octree)?;
    }
    Ok(session)
}

/// Turn the feed on if `--feed` asks for it; returns its rate.
fn start_feed(session: &mut Session, args: &FeedArgs) -> Result<Option<f64>> {
    let Some(list) = &args.feed else {
        return Ok(None);
    };
    let kinds = crate::feed::FeedKinds::parse(list)
        .map_err(|e| Error::Usage(format!("--feed {list}: {e}")))?;
    session.start_feed(crate::feed::FeedConfig {
        kinds,
        hz: args.feed_hz,
        range: crate::feed::wire::Range {
            min_m: args.feed_min_m,
            max_m: args.feed_max_m,
        },
        orientations: args.feed_orientations.clone(),
        sensor_type: args.feed_sensor_type,
        adsb_radius_m: args.feed_adsb_radius_m,
        sensors: crate::feed::sensors_for(args.sensors.as_deref(), session.scene())?,
        sensor_seed: args.sensor_seed,
        ..Default::default()
    })?;
    Ok(Some(args.feed_hz))
}

#[cfg(feature = "viz")]
fn start_viz(session: &mut Session, target: &str, whole_octree: bool) -> Result<()> {
    let target: crate::viz::RerunTarget = target.parse()?;
    let start = session
        .run_start()
        .ok_or_else(|| Error::Usage("--rerun needs --scene".into()))?;
    let options = crate::viz::VizOptions {
        whole_octree,
        ..Default::default()
    };
    session.observe(Box::new(crate::viz::logger(&target, options, start)?));
    Ok(())
}

#[cfg(not(feature = "viz"))]
fn start_viz(_: &mut Session, _: &str, _: bool) -> Result<()> {
    Err(Error::Usage(
        "this savsim was built without the `viz` feature: rebuild with it for --rerun".into(),
    ))
}

fn load_scene(path: Option<&Path>) -> Result<Option<Arc<Scene>>> {
    Ok(match path {
        Some(p) => Some(Arc::new(scene::load(p)?)),
        None => None,
    })
}

/// Run a parsed command line; `shutdown` turns true on SIGINT/SIGTERM.
pub fn run(cli: Cli, shutdown: Arc<AtomicBool>) -> Result<()> {
    match cli.command {
        Command::Replay(args) => replay_command(&args, &shutdown),
        Command::Demo(args) => demo(args, &shutdown),
        Command::Live(args) => live_command(&args, shutdown),
        Command::Record(args) => record_command(&args, shutdown),
        Command::Bench(args) => bench_command(&args),
        Command::Batch(args) => crate::batch::command::run(&args),
        Command::Daa(args) => crate::daa_csv::command(&args),
        Command::Study(args) => crate::study::command::run(&args, shutdown),
        Command::Sim(args) => sim_command(&args, &shutdown),
        Command::Scene(SceneCommand::Gen { kind, seed, out }) => {
            let text = match kind {
                SceneKind::City => gen::city(seed, gen::DEFAULT_ORIGIN),
                SceneKind::Mountain => gen::mountain(seed, gen::DEFAULT_ORIGIN),
            };
            match out {
                Some(path) => std::fs::write(&path, text).map_err(|e| Error::file(path, e)),
                None => {
                    print!("{text}");
                    Ok(())
                }
            }
        }
        Command::Scene(SceneCommand::Show { scene, rerun }) => {
            let s = Arc::new(scene::load(&scene)?);
            let mut session = Session::new(Some(s), CollisionConfig::default(), None)?;
            // No flight: the whole octree is what there is to see of it.
            start_viz(&mut session, &rerun, true)?;
            session.finish()
        }
        Command::Scene(SceneCommand::Info { scene }) => {
            let s = scene::load(&scene)?;
            print!("{}", scene::info::describe(&s));
            Ok(())
        }
    }
}

/// Powers of ten from 10^2 (or 1 for fleets) up to `max`.
fn decades(from: usize, max: usize) -> Vec<usize> {
    std::iter::successors(Some(from), |n| n.checked_mul(10))
        .take_while(|&n| n <= max)
        .collect()
}

fn bench_command(args: &BenchArgs) -> Result<()> {
    savsim_core::bounds::within("--ray-length-m", args.ray_length_m, 0.0, 100_000.0)?;
    savsim_core::bounds::within(
        "--residency-budget-mib",
        args.residency_budget_mib,
        0.0,
        1048576.0,
    )?;
    // A scene of 10^7 obstacles is about 10 GB; a fleet of 10^5 vehicles as much again.
    if args.scale_max > 10_000_000 || args.fleet_max > 100_000 {
        return Err(Error::Usage(format!(
            "--scale-max {} --fleet-max {}: at most 10000000 and 100000",
            args.scale_max, args.fleet_max
        )));
    }
    let options = crate::bench::BenchOptions {
        scenes: args
            .scene
            .iter()
            .map(|s| s.parse().expect("infallible"))
            .collect(),
        flights: args.flights.clone(),
        modes: args.modes.iter().map(|&m| m.into()).collect(),
        config: CollisionConfig {
            ray_length_m: args.ray_length_m,
            ..CollisionConfig::default()
        },
        scale_sizes: decades(100, args.scale_max),
        fleet_sizes: decades(1, args.fleet_max),
        residency_budget_mib: args.residency_budget_mib,
    };
    let report = match &args.from_json {
        Some(path) => {
            let text = crate::files::read_text(path, crate::files::MAX_TABLE_FILE_BYTES)
                .map_err(|e| Error::file(path, e))?;
            serde_json::from_str(&text)
                .map_err(|e| Error::Usage(format!("{}: not a bench report: {e}", path.display())))?
        }
        None => crate::bench::run(&options, |what| eprintln!("bench: {what}"))?,
    };
    print!("{}", crate::bench::markdown(&report));
    if let (Some(path), None) = (&args.json, &args.from_json) {
        write_json_atomic(path, &report)?;
    }
    crate::bench::chart::draw(&report, &args.chart)?;
    eprintln!("bench: chart written to {}", args.chart.display());
    Ok(())
}

fn replay_command(args: &ReplayArgs, shutdown: &AtomicBool) -> Result<()> {
    let playback = &args.playback;
    let speed: Speed = playback.speed.parse()?;
    if let Some(until_s) = playback.until_s {
        if !(until_s.is_finite() && until_s >= 0.0) {
            return Err(Error::Usage(format!(
                "--until-s {}: give seconds after the first message, 0 or more",
                savsim_core::bounds::shown(until_s)
            )));
        }
    }
    let mut session = session_for(&args.collision)?;
    start_feed(&mut session, &playback.feed)?;
    if let Some(path) = &playback.feed_out {
        let from = SenderId {
            system_id: playback.identity.sysid,
            component_id: live::FEED_COMPONENT,
        };
        session.write_feed_to(path, from)?;
    }
    let result = replay(
        &args.flight,
        speed,
        !args.no_progress,
        playback.until_s,
        &mut session,
        shutdown,
    );
    let finished = session.finish();
    write_summary(
        &session,
        "replay",
        &args.flight,
        args.collision.summary_json.as_deref(),
    )?;
    result.and(finished)?;
    print_report(&session);
    Ok(())
}

fn write_summary(
    session: &Session,
    command: &str,
    input: &Path,
    path: Option<&Path>,
) -> Result<()> {
    match path {
        Some(path) => write_json_atomic(
            path,
            &session.summary(command, &input.display().to_string()),
        ),
        None => Ok(()),
    }
}

/// A live run's summary: the session's, with the links' report under `link`.
fn write_live_summary(run: &LiveRun, command: &str, path: Option<&Path>) -> Result<()> {
    let Some(path) = path else { return Ok(()) };
    let input = run.report.endpoints.join(",");
    let mut summary = run.session.summary(command, &input);
    summary["link"] = serde_json::to_value(&run.report).unwrap_or_default();
    write_json_atomic(path, &summary)
}

fn demo(mut args: DemoArgs, shutdown: &AtomicBool) -> Result<()> {
    if args.collision.scene.is_none() {
        args.collision.scene = Some(bundled(DEMO_SCENE));
    }
    let flight = bundled(DEMO_FLIGHT);
    println!(
        "savsim demo: replaying {} over {} ({} mode)",
        flight.display(),
        args.collision
            .scene
            .as_ref()
            .map_or(String::new(), |p| p.display().to_string()),
        crate::pipeline::Mode::from(args.collision.mode).name()
    );
    replay_command(
        &ReplayArgs {
            flight,
            collision: args.collision,
            no_progress: false,
            playback: args.playback,
        },
        shutdown,
    )
}

/// Print what a run found, for a person at a terminal.
pub fn print_report(session: &Session) {
    let stats = &session.stats();
    let span = stats.time_span_s.map_or(0.0, |(a, b)| b - a);
    println!(
        "{} messages over {:.1} s from {} vehicle(s); {} bad frames, {} values rejected",
        stats.messages_total(),
        span,
        session.world().seen.len(),
        stats.bad_frames(),
        stats.rejected_total()
    );
    let Some(p) = session.pipeline() else { return };
    let (median_us, p99_us) = session.tick_costs().percentiles_us();
    println!(
        "{} ticks in {} mode: {} collisions, {} near misses, {} collider swaps, {} telemetry gaps",
        p.totals().ticks,
        p.config().mode.name(),
        p.totals().collisions,
        p.totals().near_misses,
        p.totals().swaps,
        p.totals().telemetry_gaps
    );
    println!(
        "tick cost median {median_us:.1} us, p99 {p99_us:.1} us; {} meshes built ({} triangles)",
        p.meshes().counts().built,
        p.meshes().counts().triangles
    );
    // Times relative to the first message, as a person reads a flight (`Session::elapsed_s`).
    let t0 = stats.time_span_s.map_or(0.0, |(first, _)| first);
    for e in session.notable() {
        match &e.kind {
            EventKind::Collision {
                obstacle,
                obstacle_kind,
                point_enu_m,
                time_of_impact,
                ..
            } => println!(
                "  COLLISION  vehicle {} with {obstacle} ({obstacle_kind}) at +{:.2} s, \
                 point E {:.1} N {:.1} U {:.1} m",
                e.vehicle,
                time_of_impact - t0,
                point_enu_m[0],
                point_enu_m[1],
                point_enu_m[2]
            ),
            EventKind::NearMiss {
                obstacle,
                closest_m,
                closest_t,
            } => println!(
                "  near miss  vehicle {} passed {obstacle} at {closest_m:.2} m (+{:.2} s)",
                e.vehicle,
                closest_t - t0
            ),
            EventKind::WellClearLost {
                track,
                lost_t,
                horizontal_m,
                vertical_m,
            } => println!(
                "  lost well clear  vehicle {} of {track} at +{:.2} s ({horizontal_m:.0} m \
                 horizontally, {vertical_m:.0} m vertically)",
                e.vehicle,
                lost_t - t0
            ),
            EventKind::LeftSlot {
                left_t,
                deviation_m,
                ..
            } => println!(
                "  left its slot  vehicle {} {deviation_m:.2} m from it at +{:.2} s",
                e.vehicle,
                left_t - t0
            ),
            EventKind::SeparationLost {
                track,
                lost_t,
                minimum_m,
            } => println!(
                "  lost separation  vehicle {} within {minimum_m} m of {track} at +{:.2} s",
                e.vehicle,
                lost_t - t0
            ),
            _ => {}
        }
    }
    if session.notable_not_kept() > 0 {
        println!(
            "  ... and {} more collisions, near misses and losses of well clear, not listed \
             (every one is in --events)",
            session.notable_not_kept()
        );
    }
}

fn live_options(link: &LinkArgs) -> Result<LiveOptions> {
    let LinkArgs {
        connect,
        rate_hz,
        duration_s,
        identity,
        network,
    } = link;
    let (rate_hz, duration_s) = (*rate_hz, *duration_s);
    let require = network.signing == SigningMode::Require;
    if require && network.signing_key.is_none() {
        return Err(Error::Usage(
            "--signing require needs --signing-key FILE (the key, or a passphrase)".into(),
        ));
    }
    if identity.compid == live::FEED_COMPONENT {
        return Err(Error::Usage(format!(
            "--compid {}: that is the feed's component; give another",
            live::FEED_COMPONENT
        )));
    }
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1000.0) {
        return Err(Error::Usage(format!(
            "--rate-hz {}: give 0 < rate <= 1000",
            savsim_core::bounds::shown(rate_hz)
        )));
    }
    if let Some(d) = duration_s {
        positive("--duration-s", d, MAX_DURATION_S)?;
    }
    if connect.is_empty() {
        return Err(Error::Usage("give at least one --connect".into()));
    }
    Ok(LiveOptions {
        connect: connect
            .iter()
            .map(|c| c.parse::<ConnectAddress>())
            .collect::<Result<_>>()?,
        rate_hz,
        duration: duration_s.map(Duration::from_secs_f64),
        gcs: SenderId {
            system_id: identity.sysid,
            component_id: identity.compid,
        },
        feed_from: SenderId {
            system_id: identity.sysid,
            component_id: live::FEED_COMPONENT,
        },
        forward: network
            .forward
            .iter()
            .map(|c| c.parse::<ConnectAddress>())
            .collect::<Result<_>>()?,
        forward_own: network.forward_own,
        signing_key: network
            .signing_key
            .as_deref()
            .map(SigningKey::read)
            .transpose()?,
        signing_require: require,
        ..LiveOptions::default()
    })
}

fn live_command(args: &LiveArgs, shutdown: Arc<AtomicBool>) -> Result<()> {
    let mut options = live_options(&args.link)?;
    options.feed_out = args.feed_out.clone();
    let mut session = session_for(&args.collision)?;
    if let Some(feed_hz) = start_feed(&mut session, &args.feed)? {
        // The feed is cast at samples: ask for them at least as often.
        options.rate_hz = options.rate_hz.max(feed_hz);
    }
    options.companion = companion_options(&args.companion)?;
    let mut run = live::run_blocking(&options, session, args.record.as_deref(), shutdown)?;
    let finished = run.session.finish();
    write_live_summary(&run, "live", args.collision.summary_json.as_deref())?;
    print_report(&run.session);
    print_links(&run);
    run.ended?;
    finished
}

/// `--companion` and its settings, checked.
fn companion_options(args: &crate::cli::CompanionArgs) -> Result<Option<live::CompanionOptions>> {
    let Some(command) = args.companion.as_deref().filter(|c| !c.trim().is_empty()) else {
        return Ok(None);
    };
    let config = CompanionConfig::checked(command, args.companion_hz, args.companion_latency_s)
        .map_err(|(setting, why)| {
            Error::Usage(format!("--companion-{}: {why}", setting.replace('_', "-")))
        })?;
    Ok(Some(live::CompanionOptions {
        config,
        target_system_id: args.companion_sysid,
        px4: args.companion_autopilot == "px4",
        dir: PathBuf::from("."),
        intent: Default::default(),
    }))
}

fn sim_command(args: &crate::cli::SimArgs, shutdown: &Arc<AtomicBool>) -> Result<()> {
    let plan = crate::sim::SimPlan::from_args(args)?;
    let scene = match load_scene(args.collision.scene.as_deref())? {
        Some(scene) => scene,
        // Flat ground at CMAC, ArduPilot SITL's default home.
        None => Arc::new(scene::parse(
            &format!(
                "[origin]\nlat_deg = {}\nlon_deg = {}\nalt_m = {}\n",
                gen::DEFAULT_ORIGIN.lat_deg,
                gen::DEFAULT_ORIGIN.lon_deg,
                gen::DEFAULT_ORIGIN.alt_m
            ),
            Path::new("."),
            "flat ground",
        )?),
    };
    let mut session = session_over(&args.collision, Some(scene.clone()))?;
    session.use_vehicle_clock();
    start_feed(&mut session, &args.feed)?;
    let flown_s = crate::sim::fly(&plan, &scene, &mut session, shutdown);
    let finished = session.finish();
    if let Some(path) = &args.collision.summary_json {
        write_json_atomic(path, &session.summary("sim", &plan.gcs))?;
    }
    print_report(&session);
    println!("sim: {:.1} s of the clock flown", flown_s?);
    finished
}

fn record_command(args: &RecordArgs, shutdown: Arc<AtomicBool>) -> Result<()> {
    let options = live_options(&args.link)?;
    let session = Session::new(None, CollisionConfig::default(), None)?;
    let mut run = live::run_blocking(&options, session, Some(&args.out), shutdown)?;
    let finished = run.session.finish();
    write_live_summary(&run, "record", args.summary_json.as_deref())?;
    print_report(&run.session);
    print_links(&run);
    run.ended?;
    finished
}

/// One line per autopilot: where it is, what it streams, what happened to its link.
fn print_links(run: &LiveRun) {
    let r = &run.report;
    for v in &r.vehicles {
        let streams: Vec<String> = v
            .streams
            .iter()
            .map(|(name, state)| format!("{name} {state:?}").to_lowercase())
            .collect();
        println!(
            "  vehicle {} on {}: {}; {} reboot(s), {} return(s), {} re-request(s)",
            v.vehicle,
            v.endpoint,
            streams.join(", "),
            v.reboots,
            v.returns,
            v.re_requests
        );
    }
    if let Some(l) = &r.latency {
        println!(
            "  latency received -> processed: p50 {} us, p99 {} us, max {} us over {} chunks",
            l.p50_us, l.p99_us, l.max_us, l.chunks
        );
    }
    if let Some(f) = &r.forward {
        let c = &f.counts;
        println!(
            "  forwarded to {}: {} frame(s) out, {} in, {} unroutable, {} corrupt",
            f.stations.join(", "),
            c.to_stations,
            c.from_stations,
            c.unroutable,
            c.corrupt
        );
    }
    if let Some(s) = &r.signing {
        println!(
            "  signing: {} signed in, {} sent signed; dropped {} unsigned, {} bad signature(s), \
             {} replayed; {} unsigned taken",
            s.signed,
            s.sent_signed,
            s.unsigned_dropped,
            s.bad_signature,
            s.replayed,
            s.unsigned_accepted
        );
    }
}
