//! `kiln`: the command-line front of the Kiln renderer.
//!
//! This binary only parses flags, wires the crates together and maps errors to
//! exit codes; the work lives in the library crates.

mod denoise;
mod farm;
mod listing;
mod output;
mod render;
mod shot;
mod tokens;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "kiln",
    version,
    about = "A physically based renderer and render farm for pbrt-v4 scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a pbrt-v4 scene to an EXR on this machine.
    Render(render::RenderArgs),
    /// Denoise a Kiln render's EXR with its feature buffers.
    Denoise(denoise::DenoiseArgs),
    /// Render a scene through a farm on this machine: a coordinator and N worker processes.
    Farm(farm::FarmArgs),
    /// Run a coordinator: the HTTP API, the job store and the tile leases.
    Coordinator(farm::CoordinatorArgs),
    /// Run a worker that renders tiles for a coordinator.
    Worker(farm::WorkerArgs),
    /// Upload a scene to a coordinator and create a job.
    Submit(farm::SubmitArgs),
    /// Follow or change a job on a coordinator: status, stop after the pass in progress,
    /// extend with more passes, cancel.
    Job(farm::JobCommandArgs),
    /// List a coordinator's jobs: state, progress, passes, priority, what each waits for.
    Jobs(listing::ListArgs),
    /// List the workers a coordinator has heard from: what each renders, its tags, its
    /// record.
    Workers(listing::ListArgs),
    /// Issue, list and revoke a coordinator's tokens: submitters' and workers' credentials
    /// (the admin's token is the coordinator's --token).
    Tokens(tokens::TokensArgs),
    /// Check that a coordinator answers (exit status 0), for container health checks.
    Health(farm::HealthArgs),
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render::run(args),
        Command::Denoise(args) => denoise::run(args),
        Command::Farm(args) => farm::farm(args),
        Command::Coordinator(args) => farm::coordinator(args),
        Command::Worker(args) => farm::worker(args),
        Command::Submit(args) => farm::submit(args),
        Command::Health(args) => farm::health(args),
        Command::Job(args) => farm::job(args),
        Command::Jobs(args) => listing::jobs(args),
        Command::Workers(args) => listing::workers(args),
        Command::Tokens(args) => tokens::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
