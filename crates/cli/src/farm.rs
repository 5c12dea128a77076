//! `kiln coordinator`, `kiln worker`, `kiln submit` and `kiln farm`.

use anyhow::{Context, Result, bail};
use kiln_farm::api::{JobSpec, JobState};
use kiln_farm::client::Client;
use kiln_farm::coordinator::{self, Config, Coordinator};
use kiln_farm::worker::{self, WorkerConfig};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

pub(crate) fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")
}

/// SIGTERM and ctrl-c, listened for from the moment this is made: each
/// [`Signals::next`] resolves at the next one, so a signal that comes while the process is
/// busy between two waits is not missed.
struct Signals {
    #[cfg(unix)]
    term: Option<tokio::signal::unix::Signal>,
    #[cfg(unix)]
    interrupt: Option<tokio::signal::unix::Signal>,
}

impl Signals {
    /// Starts listening. Needs a tokio runtime.
    fn new() -> Signals {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{SignalKind, signal};
            Signals {
                term: signal(SignalKind::terminate()).ok(),
                interrupt: signal(SignalKind::interrupt()).ok(),
            }
        }
        #[cfg(not(unix))]
        Signals {}
    }

    /// Resolves at the next SIGTERM or ctrl-c.
    async fn next(&mut self) {
        #[cfg(unix)]
        {
            tokio::select! { _ = wait(self.term.as_mut()) => {}, _ = wait(self.interrupt.as_mut()) => {} }
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}

/// Resolves at `signal`'s next delivery; never if it could not be listened for.
#[cfg(unix)]
async fn wait(signal: Option<&mut tokio::signal::unix::Signal>) {
    match signal {
        Some(s) => {
            s.recv().await;
        }
        None => std::future::pending::<()>().await,
    }
}

/// Resolves when the process gets SIGTERM or ctrl-c.
async fn shutdown_signal() {
    Signals::new().next().await;
}

#[derive(clap::Args)]
pub struct CoordinatorArgs {
    /// Address to listen on (port 0 picks a free one; the chosen address is printed).
    #[arg(long, default_value = "127.0.0.1:7878")]
    listen: String,
    /// Where jobs, scene bundles and finished tiles are kept; a restart resumes from it.
    #[arg(long)]
    data_dir: PathBuf,
    /// Require `Authorization: Bearer TOKEN` on every request but /healthz.
    #[arg(long, env = "KILN_TOKEN")]
    token: Option<String>,
    /// Seconds a lease lasts without a heartbeat.
    #[arg(long, env = "KILN_LEASE_TTL", default_value_t = 20.0)]
    lease_ttl: f64,
    /// The most pixels a job's frame may hold (it is kept in memory while the job runs).
    #[arg(long, default_value_t = kiln_image::MAX_PIXELS)]
    max_frame_pixels: u64,
    /// The most pixels a frame denoised for a preview (`preview.png?denoise=1`) may hold:
    /// denoising holds about 300 bytes a pixel while it runs.
    #[arg(long, default_value_t = 1 << 24)]
    max_denoised_pixels: u64,
    /// Connections open at once; one more is answered 503 (fewer where the process may not
    /// open that many files).
    #[arg(long, default_value_t = 1024)]
    max_connections: usize,
    /// Seconds a connection may take to send a request's head, and may idle between
    /// requests, before it is closed.
    #[arg(long, default_value_t = 30.0)]
    header_timeout: f64,
    /// Serve https with this certificate chain (PEM), for a farm without an ingress in
    /// front; clients trust it through KILN_TLS_CA.
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// The certificate's private key (PEM).
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// The job store: a postgres://user:password@host:port/database URL of a server that
    /// several coordinators may share, one leading and the others standing by. Default:
    /// SQLite in the data directory.
    #[arg(long, env = "KILN_STORE")]
    store: Option<String>,
    /// Keep scene bundles, pre-passes and merged frames also in this S3 bucket
    /// (s3://bucket/prefix), where every coordinator of the farm finds them; the endpoint
    /// and credentials come from AWS_ENDPOINT, AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY,
    /// AWS_REGION (and AWS_ALLOW_HTTP=true for an http endpoint).
    #[arg(long, env = "KILN_OBJECTS")]
    objects: Option<String>,
    /// The URL other coordinators report as this one's while it leads (default: the
    /// listening address).
    #[arg(long)]
    advertise: Option<String>,
    /// Seconds the lead lasts unrenewed before a standby takes it (a shared store only).
    #[arg(long, env = "KILN_LEADER_TTL", default_value_t = 5.0)]
    leader_ttl: f64,
}

pub fn coordinator(args: CoordinatorArgs) -> Result<()> {
    let rt = runtime()?;
    rt.block_on(async {
        let mut config = Config::new(args.data_dir.clone());
        config.token = args.token;
        config.lease_ttl = Duration::from_secs_f64(args.lease_ttl.max(0.05));
        config.max_frame_pixels = args.max_frame_pixels;
        config.max_denoised_pixels = args.max_denoised_pixels;
        config.max_connections = args.max_connections.max(1);
        anyhow::ensure!(
            args.header_timeout.is_finite() && args.header_timeout > 0.0,
            "--header-timeout must be a positive number of seconds, not {}",
            args.header_timeout
        );
        config.header_timeout = Duration::from_secs_f64(args.header_timeout.clamp(0.1, 86_400.0));
        if let (Some(cert), Some(key)) = (args.tls_cert.clone(), args.tls_key.clone()) {
            let files = coordinator::TlsFiles { cert, key };
            coordinator::check_tls(&files)
                .map_err(|e| anyhow::anyhow!("--tls-cert and --tls-key: {e}"))?;
            config.tls = Some(files);
        }
        let scheme = if config.tls.is_some() {
            "https"
        } else {
            "http"
        };
        if let Some(store) = args.store.clone().filter(|s| !s.is_empty()) {
            anyhow::ensure!(
                args.leader_ttl.is_finite() && args.leader_ttl > 0.0,
                "--leader-ttl must be a positive number of seconds, not {}",
                args.leader_ttl
            );
            let address = args
                .advertise
                .clone()
                .unwrap_or_else(|| format!("{scheme}://{}", args.listen));
            let ttl = Duration::from_secs_f64(args.leader_ttl.clamp(0.2, 3600.0));
            config.candidate = Some(coordinator::Candidate::new(address, ttl));
            config.store = Some(store);
        }
        config.objects = args.objects.clone().filter(|o| !o.is_empty());
        let bind = || async {
            tokio::net::TcpListener::bind(&args.listen)
                .await
                .with_context(|| format!("cannot listen on {}", args.listen))
        };
        // On a shared store, a standby answers on its address with the leader's while it
        // waits (over plain http only: with TLS it does not listen until it leads).
        let standing_by = match &config.candidate {
            Some(me) if config.tls.is_none() => {
                let listener = bind().await?.into_std()?;
                let answering = tokio::net::TcpListener::from_std(listener.try_clone()?)?;
                println!(
                    "kiln coordinator: standing by on http://{} until it leads",
                    listener.local_addr()?
                );
                let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
                let task = tokio::spawn(coordinator::stand_by(answering, me.clone(), async {
                    let _ = stopped.await;
                }));
                Some((listener, stop, task))
            }
            _ => None,
        };
        // A standby waits here, on a blocking thread, until it leads.
        let c = tokio::task::spawn_blocking(move || Coordinator::open(config)).await??;
        let listener = match standing_by {
            Some((listener, stop, task)) => {
                let _ = stop.send(());
                let _ = task.await;
                tokio::net::TcpListener::from_std(listener)?
            }
            None => bind().await?,
        };
        let addr = listener.local_addr()?;
        println!(
            "kiln coordinator: listening on {scheme}://{addr} (data in {})",
            args.data_dir.display()
        );
        use std::io::Write;
        std::io::stdout().flush().ok();
        coordinator::serve(listener, c, shutdown_signal()).await?;
        Ok(())
    })
}

#[derive(clap::Args)]
pub struct WorkerArgs {
    /// The coordinator's URL, e.g. http://127.0.0.1:7878; for a farm with standby
    /// coordinators, all of theirs, comma separated (requests go to the one that leads).
    #[arg(long)]
    coordinator: String,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    #[arg(long, env = "KILN_TOKEN")]
    token: Option<String>,
    /// A name for this worker in the coordinator's records (default: host-pid).
    #[arg(long)]
    name: Option<String>,
    /// Where scene bundles are cached (default: the system temp dir).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Exit after the coordinator has been unreachable for this many seconds.
    #[arg(long, default_value_t = 600.0)]
    give_up_after: f64,
    /// For tests only: upload wrong pixels on purpose ("flip-low-bit" flips the lowest bit
    /// of some pixels), as a bad host would; or abort on a scene marked
    /// "# kiln-test: abort-worker" ("abort-on-marked-scene"), as a scene that crashes its
    /// renderer would.
    #[arg(long, value_parser = parse_fault)]
    inject_fault: Option<worker::Fault>,
    /// What this worker offers, comma separated (e.g. big-mem,avx512): it is lent only
    /// the tiles of jobs whose requirements (kiln submit --requires) it has, every one.
    #[arg(long, value_delimiter = ',')]
    tags: Vec<String>,
    /// The memory this worker offers (e.g. 16G, 512M; a plain number is MiB): it is lent
    /// only jobs whose scenes are estimated to need no more. Default: the machine's.
    #[arg(long, value_parser = parse_memory)]
    memory: Option<u64>,
}

/// A memory size in MiB from `16G`, `512M` or `512`.
fn parse_memory(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let (number, unit) = match t.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => t.split_at(i),
        None => (t, ""),
    };
    let scale = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "M" | "MB" | "MIB" => 1,
        "G" | "GB" | "GIB" => 1024,
        "T" | "TB" | "TIB" => 1024 * 1024,
        _ => return Err(format!("memory '{s}' is not a size such as 16G or 512M")),
    };
    number
        .parse::<u64>()
        .ok()
        .and_then(|n| n.checked_mul(scale))
        .filter(|&n| n > 0)
        .ok_or_else(|| format!("memory '{s}' is not a size such as 16G or 512M"))
}

/// The machine's memory in MiB, as Linux reports it (None elsewhere).
fn machine_memory_mib() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024)
}

fn parse_fault(s: &str) -> std::result::Result<worker::Fault, String> {
    match s {
        "flip-low-bit" => Ok(worker::Fault::FlipLowBit),
        "abort-on-marked-scene" => Ok(worker::Fault::AbortOnMarkedScene),
        other => Err(format!(
            "unknown fault '{other}' (known: flip-low-bit, abort-on-marked-scene)"
        )),
    }
}

pub fn worker(args: WorkerArgs) -> Result<()> {
    let rt = runtime()?;
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let name = args.name.unwrap_or_else(|| {
        let host = std::fs::read_to_string("/etc/hostname").unwrap_or_else(|_| "worker".into());
        // Only what a worker name may hold (a host name may hold more, in principle).
        let host: String = host
            .trim()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
            .take(100)
            .collect();
        format!("{host}-{}", std::process::id())
    });
    kiln_farm::api::check_worker_name(&name).map_err(anyhow::Error::msg)?;
    kiln_farm::api::check_tags(&args.tags).map_err(anyhow::Error::msg)?;
    let cache_dir = args
        .cache_dir
        .unwrap_or_else(|| std::env::temp_dir().join("kiln-bundles"));
    std::fs::create_dir_all(&cache_dir)
        .with_context(|| format!("cannot create {}", cache_dir.display()))?;
    let config = WorkerConfig {
        coordinator: args.coordinator,
        token: args.token,
        threads,
        name: name.clone(),
        cache_dir,
        poll: Duration::from_millis(100),
        give_up_after: Duration::from_secs_f64(args.give_up_after.max(0.0)),
        fault: args.inject_fault,
        tags: args.tags,
        memory_mib: args.memory.or_else(machine_memory_mib),
    };
    rt.block_on(async move {
        let stop = Arc::new(worker::Stop::default());
        let flag = stop.clone();
        let who = name.clone();
        let mut signals = Signals::new();
        tokio::spawn(async move {
            signals.next().await;
            // Finish the tile in hand, then leave; a second signal leaves at once, giving
            // the tile back.
            flag.after_tile.store(true, Ordering::SeqCst);
            eprintln!("kiln worker {who}: stopping after this tile (signal again to stop now)");
            signals.next().await;
            flag.now.store(true, Ordering::SeqCst);
        });
        eprintln!("kiln worker {name}: {threads} threads");
        let n = worker::run(config, stop).await?;
        eprintln!("kiln worker {name}: stopped after {n} tiles");
        Ok(())
    })
}

#[derive(clap::Args, Clone)]
pub struct JobArgs {
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    spp: Option<u32>,
    /// Resolution as WIDTHxHEIGHT (default: the scene's).
    #[arg(long, value_parser = crate::render::parse_resolution)]
    resolution: Option<(u32, u32)>,
    /// Tile size in pixels.
    #[arg(long, default_value_t = 32)]
    tile: u32,
    /// Sampler seed (default: the scene's).
    #[arg(long)]
    seed: Option<u32>,
    /// Progressive passes: cumulative samples per pixel at the end of each, comma
    /// separated (e.g. 16,64,256); the whole frame is merged after each, and the last is
    /// the job's samples per pixel.
    #[arg(long, value_delimiter = ',')]
    passes: Option<Vec<u32>>,
    /// Render this fraction (0 to 1) of tile passes twice, on different workers, and
    /// compare them bit for bit: a worker whose render two others contradict is set aside.
    #[arg(long)]
    verify: Option<f64>,
    /// Higher runs first; jobs of equal priority share the workers.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    priority: i32,
    /// A URL the coordinator POSTs the job's status to when it ends (retried until it
    /// answers 2xx).
    #[arg(long)]
    webhook: Option<String>,
    /// Render spectrally, as pbrt-v4 does (the default unless the scene says
    /// Option "kiln.spectral" false).
    #[arg(long, conflicts_with = "rgb")]
    spectral: bool,
    /// Render in RGB.
    #[arg(long)]
    rgb: bool,
    /// Tags a worker must offer, every one, to render this job (kiln worker --tags),
    /// comma separated.
    #[arg(long, value_delimiter = ',')]
    requires: Vec<String>,
    /// At most this many workers render the job at once.
    #[arg(long)]
    max_workers: Option<u32>,
    /// Start after these jobs (ids, comma separated) are done.
    #[arg(long, value_delimiter = ',')]
    after: Vec<u64>,
    /// With --after: start once they have ended, done, failed or cancelled.
    #[arg(long, requires = "after")]
    after_ended: bool,
    /// With --after: if one of them fails or is cancelled, hold (stay waiting, for someone
    /// to cancel this job) rather than fail.
    #[arg(long, requires = "after", conflicts_with = "after_ended")]
    hold_on_failure: bool,
}

impl JobArgs {
    /// The job's colour mode: given, or the scene's.
    fn spectral(&self) -> Option<bool> {
        match (self.spectral, self.rgb) {
            (true, _) => Some(true),
            (_, true) => Some(false),
            _ => None,
        }
    }
}

#[derive(clap::Args)]
pub struct SubmitArgs {
    /// The pbrt-v4 scene file; it and every file it refers to are uploaded. Several files
    /// (or a quoted glob, 'shot/f*.pbrt') make one job of many frames, a shot: every file
    /// lies beside or below the first's folder.
    #[arg(required = true, num_args = 1..)]
    scenes: Vec<PathBuf>,
    /// The coordinator's URL; for a farm with standby coordinators, all of theirs, comma
    /// separated (requests go to the one that leads).
    #[arg(long)]
    coordinator: String,
    #[command(flatten)]
    job: JobArgs,
    #[arg(long, env = "KILN_TOKEN")]
    token: Option<String>,
    /// Wait for the render, showing progress, and download the result.
    #[arg(long)]
    wait: bool,
    /// Where --wait writes the merged EXR; for a shot, the folder that receives one EXR per
    /// frame, named after its scene file (default: job-ID).
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[arg(long, short)]
    quiet: bool,
}

/// Packs, uploads and creates the job of `frames` (one, or a shot's); returns its id.
async fn submit_job(client: &Client, frames: &[PathBuf], job: &JobArgs) -> Result<u64> {
    let (bundle, names) = match frames {
        [scene] => (kiln_farm::bundle::pack(scene)?, Vec::new()),
        _ => kiln_farm::bundle::pack_frames(frames)?,
    };
    let spec = JobSpec {
        spp: job.spp,
        resolution: job.resolution,
        tile: job.tile,
        seed: job.seed,
        passes: job.passes.clone(),
        verify: job.verify,
        priority: job.priority,
        webhook: job.webhook.clone(),
        spectral: job.spectral(),
        requires: job.requires.clone(),
        max_workers: job.max_workers,
        after: job.after.clone(),
        after_ended: job.after_ended,
        hold_on_failure: job.hold_on_failure,
        frames: names,
        ..JobSpec::new(&bundle.digest)
    };
    // The same scene and settings submitted twice (a retry) make one job.
    let key = format!("{}-{}", bundle.digest, serde_json::to_string(&spec)?);
    let digest = client.upload_scene(bundle.bytes).await?;
    if digest != spec.scene {
        bail!(
            "the coordinator computed digest {digest} for the bundle, not {}",
            spec.scene
        );
    }
    Ok(client
        .create_job(&spec, Some(&kiln_farm::bundle::digest_of(key.as_bytes())))
        .await?)
}

/// Follows a job to its end with a progress bar; writes the result to `output`.
async fn wait_for(client: &Client, id: u64, output: &std::path::Path, quiet: bool) -> Result<()> {
    let bar = crate::output::progress_bar(quiet);
    let mut written = 0;
    loop {
        let s = client.status(id).await?;
        bar.set_position((s.progress * 1000.0) as u64);
        let eta = s
            .eta_seconds
            .map(|e| format!(", {e:.0} s left"))
            .unwrap_or_default();
        let passes = if s.passes.len() > 1 {
            format!(
                ", pass {}/{} merged ({} spp)",
                s.passes_done,
                s.passes.len(),
                s.samples_per_pixel_done
            )
        } else {
            String::new()
        };
        bar.set_message(format!(
            "{}/{} tiles, {:.2} M samples/s{passes}{eta}",
            s.tiles_done,
            s.tiles_total,
            s.samples_per_second / 1e6
        ));
        // Each merged pass is written as it lands, so the file is always a whole frame.
        if s.state == JobState::Running && s.passes_done > written {
            written = s.passes_done;
            let bytes = client.result(id).await?;
            crate::output::write_replacing(output, &bytes)?;
        }
        if crate::output::ended(id, &s)? {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    bar.finish_and_clear();
    let bytes = client.result(id).await?;
    crate::output::write_replacing(output, &bytes)
}

/// What `kiln job` does to a job.
#[derive(clap::Subcommand)]
pub enum JobAction {
    /// Print the job's status as JSON.
    Status,
    /// End the job after the pass in progress: its result is that pass's whole frame.
    Stop,
    /// Add passes after the job's last (a done job renders on from the samples it has).
    Extend {
        /// Cumulative samples per pixel at the end of each new pass, comma separated.
        #[arg(long, value_delimiter = ',', required = true)]
        passes: Vec<u32>,
    },
    /// Cancel the job.
    Cancel,
}

#[derive(clap::Args)]
pub struct JobCommandArgs {
    /// The job's id.
    id: u64,
    #[command(subcommand)]
    action: JobAction,
    #[arg(long, default_value = "http://127.0.0.1:7878")]
    coordinator: String,
    #[arg(long, env = "KILN_TOKEN")]
    token: Option<String>,
}

pub fn job(args: JobCommandArgs) -> Result<()> {
    let rt = runtime()?;
    rt.block_on(async {
        let client = Client::new(&args.coordinator, args.token.clone());
        let status = match &args.action {
            JobAction::Status => client.status(args.id).await?,
            JobAction::Stop => client.stop_after_pass(args.id).await?,
            JobAction::Extend { passes } => client.extend(args.id, passes).await?,
            JobAction::Cancel => client.cancel(args.id).await?,
        };
        println!("{}", serde_json::to_string_pretty(&status)?);
        Ok(())
    })
}

pub fn submit(args: SubmitArgs) -> Result<()> {
    let rt = runtime()?;
    rt.block_on(async {
        let client = Client::new(&args.coordinator, args.token.clone());
        let frames = crate::shot::expand(&args.scenes)?;
        let id = submit_job(&client, &frames, &args.job).await?;
        println!("kiln submit: job {id}");
        if !args.wait {
            return Ok(());
        }
        let out = args.output.clone();
        if frames.len() > 1 {
            let dir = out.unwrap_or_else(|| PathBuf::from(format!("job-{id}")));
            let outputs = crate::shot::outputs(&frames, &dir)?;
            crate::shot::wait_for_shot(&client, id, &outputs, args.quiet).await?;
            eprintln!(
                "kiln submit: wrote {} frames into {}",
                outputs.len(),
                dir.display()
            );
        } else {
            let out = out.unwrap_or_else(|| PathBuf::from(format!("job-{id}.exr")));
            wait_for(&client, id, &out, args.quiet).await?;
            eprintln!("kiln submit: wrote {}", out.display());
        }
        Ok(())
    })
}

#[derive(clap::Args)]
pub struct HealthArgs {
    /// The coordinator's base URL.
    #[arg(long, default_value = "http://127.0.0.1:7878")]
    coordinator: String,
    /// How long to wait for the answer, in seconds.
    #[arg(long, default_value_t = 5)]
    timeout: u64,
}

/// `kiln health`: GET /healthz within the timeout; an error (exit status 1) says why not.
pub fn health(args: HealthArgs) -> Result<()> {
    let rt = runtime()?;
    rt.block_on(async {
        let client = Client::new(&args.coordinator, None);
        match tokio::time::timeout(
            std::time::Duration::from_secs(args.timeout),
            client.healthz(),
        )
        .await
        {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => Err(anyhow::anyhow!("{} is not healthy: {e}", args.coordinator)),
            Err(_) => Err(anyhow::anyhow!(
                "{} did not answer within {} s",
                args.coordinator,
                args.timeout
            )),
        }
    })
}

#[derive(clap::Args)]
pub struct FarmArgs {
    /// The pbrt-v4 scene file; several (or a quoted glob) render a shot of many frames.
    #[arg(required = true, num_args = 1..)]
    scenes: Vec<PathBuf>,
    /// Local worker processes.
    #[arg(long, default_value_t = 2)]
    workers: usize,
    /// Render threads per worker (default: the cores divided among the workers).
    #[arg(long)]
    threads_per_worker: Option<usize>,
    #[command(flatten)]
    job: JobArgs,
    /// Output EXR (default: the Film's filename); for a shot, the folder that receives one
    /// EXR per frame, named after its scene file (default: the current folder).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also write an sRGB PNG preview (of one frame; a shot's are on the dashboard).
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Denoise the merged frame with its feature buffers (as `kiln render --denoise`): the
    /// denoised beauty as R, G and B and in the preview, the raw beauty as raw.R, raw.G
    /// and raw.B.
    #[arg(long)]
    denoise: bool,
    /// Which denoiser --denoise uses.
    #[arg(long, value_enum, default_value_t = crate::denoise::Choice::Kiln, requires = "denoise")]
    denoiser: crate::denoise::Choice,
    #[arg(long, short)]
    quiet: bool,
}

pub fn farm(args: FarmArgs) -> Result<()> {
    if args.workers == 0 {
        bail!("--workers must be at least 1");
    }
    if args.denoise {
        args.denoiser.check_available()?;
    }
    if !args.job.requires.is_empty() {
        // Its workers declare no tags, so the job would wait for ever.
        bail!(
            "--requires is for `kiln submit` to a coordinator whose workers offer tags; \
             this farm's workers are this machine's own"
        );
    }
    let frames = crate::shot::expand(&args.scenes)?;
    let shot = frames.len() > 1;
    if shot && (args.preview.is_some() || args.denoise) {
        bail!(
            "--preview and --denoise take one frame's; a shot's frames are each an EXR in the -o folder (`kiln denoise` takes each)"
        );
    }
    let output = match &args.output {
        Some(o) => o.clone(),
        None if shot => PathBuf::from("."),
        None => {
            let desc = kiln_scene::load_file(&frames[0])?;
            let mut p = PathBuf::from(&desc.film.filename);
            p.set_extension("exr");
            p
        }
    };
    let outputs = if shot {
        crate::shot::outputs(&frames, &output)?
    } else {
        vec![output.clone()]
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = args
        .threads_per_worker
        .unwrap_or((cores / args.workers).max(1));
    let data = std::env::temp_dir().join(format!("kiln-farm-{}", std::process::id()));
    let rt = runtime()?;
    let start = std::time::Instant::now();
    let result = rt.block_on(async {
        let c = Coordinator::open(Config::new(data.clone()))?;
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
        let url = format!("http://{}", listener.local_addr()?);
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let server = tokio::spawn(coordinator::serve(listener, c, async {
            let _ = stop_rx.await;
        }));
        let exe = std::env::current_exe()?;
        let mut children = Vec::new();
        for i in 0..args.workers {
            let child = std::process::Command::new(&exe)
                .args([
                    "worker",
                    "--coordinator",
                    &url,
                    "--threads",
                    &threads.to_string(),
                    "--name",
                    &format!("local-{i}"),
                ])
                // Local workers outlive a killed `kiln farm` by seconds, not minutes.
                .args(["--give-up-after", "5"])
                .arg("--cache-dir")
                .arg(data.join("worker-cache"))
                .stdin(std::process::Stdio::null())
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .context("cannot start a worker process")?;
            children.push(child);
        }
        if !args.quiet {
            eprintln!(
                "kiln farm: coordinator at {url}, {} workers x {threads} threads",
                args.workers
            );
        }
        let client = Client::new(&url, None);
        let outcome = async {
            let id = submit_job(&client, &frames, &args.job).await?;
            if shot {
                crate::shot::wait_for_shot(&client, id, &outputs, args.quiet).await
            } else {
                wait_for(&client, id, &output, args.quiet).await
            }
        }
        .await;
        for child in &mut children {
            terminate(child);
        }
        for mut child in children {
            let _ = child.wait();
        }
        let _ = stop_tx.send(());
        let _ = server.await;
        outcome
    });
    let _ = std::fs::remove_dir_all(&data);
    result?;
    finish_frame(&args, &output)?;
    let wrote = if shot {
        format!("{} frames into {}", outputs.len(), output.display())
    } else {
        output.display().to_string()
    };
    eprintln!(
        "kiln farm: wrote {wrote} in {:.2} s",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The merged frame at `output` denoised (with --denoise) and its preview written (with
/// --preview). The raw frame is on disk already: a failure here loses nothing.
fn finish_frame(args: &FarmArgs, output: &std::path::Path) -> Result<()> {
    if !args.denoise && args.preview.is_none() {
        return Ok(());
    }
    let mut frame = kiln_image::decode_exr(&std::fs::read(output)?)?;
    if args.denoise {
        frame = crate::denoise::denoise_frame(&frame, args.denoiser, args.quiet)
            .with_context(|| format!("the raw frame is in {}, not denoised", output.display()))?;
        kiln_image::write_exr(output, &frame)
            .with_context(|| format!("cannot write {}", output.display()))?;
    }
    if let Some(preview) = &args.preview {
        kiln_image::write_png(preview, &frame, 0.0)?;
    }
    Ok(())
}

/// Asks a worker process to finish its tile and stop: SIGTERM through `kill` where there
/// is one, else a plain kill.
fn terminate(child: &mut std::process::Child) {
    let asked = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .is_ok_and(|s| s.success());
    if !asked {
        let _ = child.kill();
    }
}
