//! The savsim binary: parse the command line, run, map the outcome to an exit code.
//! Exit codes: 0 success, 1 runtime failure (I/O, network), 2 bad usage or bad input file.

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use clap::Parser;

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = savsim::cli::Cli::parse();
    let shutdown = Arc::new(AtomicBool::new(false));
    if let Err(e) = savsim::signals::install(shutdown.clone()) {
        eprintln!("savsim: cannot install signal handlers: {e}");
    }
    match savsim::app::run(cli, shutdown.clone()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("savsim: {e}");
            let _ = shutdown.load(Ordering::Relaxed);
            match e {
                savsim::error::Error::Usage(_)
                | savsim::error::Error::OutOfRange(_)
                | savsim::error::Error::Address { .. }
                | savsim::error::Error::Scene(_)
                | savsim::error::Error::Log { .. }
                | savsim::error::Error::Daa { .. } => ExitCode::from(2),
                _ => ExitCode::FAILURE,
            }
        }
    }
}
