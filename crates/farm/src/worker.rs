//! A worker: leases tiles, renders them with `kiln_render::render_tile`, returns EXRs.

use crate::api::{GeometryCounts, JobSpec, Lease, PrepassClaim};
use crate::bundle;
use crate::client::{Client, ClientError};
use kiln_render::shared::{Shared, SharedPrepass};
use kiln_render::{
    Integrator, Renderer, SumsLayout, TileRect, TileSums, render_tile_pass, render_tile_until,
};
use reqwest::StatusCode;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Why a worker stopped.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    #[error("cannot start {threads} threads: {message}")]
    Threads { threads: usize, message: String },
    #[error("the coordinator at {url} has been unreachable for {after:?}")]
    Unreachable { url: String, after: Duration },
    /// The coordinator refused this worker (a wrong token, or set aside after failures).
    #[error("{0}")]
    Refused(ClientError),
}

/// Why a lease's scene could not be made ready; sent to the coordinator as the reason the
/// attempt failed.
#[derive(Debug, thiserror::Error)]
enum LoadError {
    #[error("{0}")]
    Download(ClientError),
    #[error("the scene bundle's digest is {actual}, not {expected}")]
    Digest { actual: String, expected: String },
    #[error("{0}")]
    Bundle(bundle::BundleError),
    /// The parser's message, file names relative to the bundle.
    #[error("{0}")]
    Scene(String),
    #[error("{0}")]
    Overrides(String),
    #[error("{0}")]
    Build(kiln_render::BuildError),
    #[error("{0}")]
    Task(tokio::task::JoinError),
}

#[derive(Debug, Clone)]
pub struct WorkerConfig {
    pub coordinator: String,
    pub token: Option<String>,
    pub threads: usize,
    pub name: String,
    /// Where bundles are unpacked (one folder per digest).
    pub cache_dir: PathBuf,
    pub poll: Duration,
    /// Stop after the coordinator has been unreachable this long (a farm that is gone).
    pub give_up_after: Duration,
    /// A fault to inject, to test that verification catches it.
    pub fault: Option<Fault>,
    /// What the worker offers: it is lent only tiles of jobs that require none else.
    pub tags: Vec<String>,
    /// The memory it offers, in MiB: it is lent only tiles of jobs estimated to need no
    /// more (None: not said).
    pub memory_mib: Option<u64>,
}

/// A fault a worker can be told to inject, for tests: how a verified job is tested against
/// a bad host (a flaky memory bit, a miscompiled math library), and the farm against a
/// scene that crashes its renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Flips the lowest bit of the red channel of every seventh pixel of each tile.
    FlipLowBit,
    /// Aborts the process on loading a scene whose file holds [`ABORT_MARKER`]: a scene
    /// that crashes every renderer that takes it.
    AbortOnMarkedScene,
}

/// The comment that makes a worker with [`Fault::AbortOnMarkedScene`] abort.
pub const ABORT_MARKER: &str = "# kiln-test: abort-worker";

impl Fault {
    fn apply(self, tile: &mut kiln_image::RgbBuffer) {
        match self {
            Fault::FlipLowBit => {
                for p in tile.pixels.iter_mut().step_by(7) {
                    p[0] = f32::from_bits(p[0].to_bits() ^ 1);
                }
            }
            Fault::AbortOnMarkedScene => {}
        }
    }
}

/// A loaded scene, ready to render tiles of one job spec.
struct Loaded {
    renderer: Renderer,
    frame: (u32, u32),
}

/// When a worker stops.
#[derive(Debug, Default)]
pub struct Stop {
    /// Finish the tile in hand, then leave (a first SIGTERM).
    pub after_tile: AtomicBool,
    /// Leave now: the tile in hand is given back to the coordinator (a second SIGTERM).
    pub now: AtomicBool,
}

/// Runs until `stop` says so or the coordinator sets this worker aside. Returns the number
/// of tiles rendered.
pub async fn run(config: WorkerConfig, stop: Arc<Stop>) -> Result<u64, WorkerError> {
    let client = Client::new(&config.coordinator, config.token.clone());
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(config.threads)
            .build()
            .map_err(|e| WorkerError::Threads {
                threads: config.threads,
                message: e.to_string(),
            })?,
    );
    let mut scenes = Scenes::new(mesh_budget(config.memory_mib));
    let mut rendered = 0u64;
    let mut unreachable = Unreachable::default();
    while !stop.after_tile.load(Ordering::SeqCst) && !stop.now.load(Ordering::SeqCst) {
        let counts = scenes.geometry();
        let Some(lease) = next_lease(&client, &config, counts, &mut unreachable).await? else {
            continue;
        };
        // Loading may take a while (a big scene, photon maps built or waited for): the
        // lease is kept alive meanwhile, and one lost on the way is not rendered.
        let (beat, lost) = keep_alive(&client, &lease);
        let loaded = scenes.get(&client, &config, &lease).await;
        beat.abort();
        let loaded = match loaded {
            Ok(_) if lost.load(Ordering::SeqCst) => continue,
            Ok(l) => l,
            Err(e) => {
                let _ = client.fail(lease.lease, &e.to_string()).await;
                continue;
            }
        };
        let (name, job, tile) = (&config.name, lease.job, lease.tile_index);
        match render_and_upload(&client, &pool, &loaded, &lease, &stop, config.fault).await {
            Ok(Outcome::Uploaded) => {
                rendered += 1;
                eprintln!("kiln worker {name}: rendered job {job} tile {tile}");
            }
            Ok(Outcome::Failed(why)) => {
                eprintln!("kiln worker {name}: job {job} tile {tile} failed: {why}");
            }
            Ok(Outcome::Abandoned) => {
                eprintln!("kiln worker {name}: job {job} tile {tile} abandoned part way");
            }
            Err(e) => tracing::warn!("job {} tile {}: {e}", lease.job, lease.tile_index),
        }
    }
    Ok(rendered)
}

/// Since when, and how many times in a row, the coordinator has not answered.
#[derive(Default)]
struct Unreachable {
    since: Option<std::time::Instant>,
    attempts: u32,
}

impl Unreachable {
    /// The pause before asking again: exponential from 250 ms up to 8 s, each drawn at
    /// random between half and all of it, so that a farm's workers do not all come back to
    /// a restarted coordinator at once.
    fn backoff(&self, name: &str) -> Duration {
        let full = 0.25 * 2f64.powi(self.attempts.min(5) as i32);
        // Jitter from the clock and the worker's name: nothing rendered depends on it.
        let mut h = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos() as u64);
        for b in name.bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
        let u = (h >> 11) as f64 / (1u64 << 53) as f64;
        Duration::from_secs_f64(full * (0.5 + 0.5 * u))
    }
}

/// Asks the coordinator for a tile. `None` (after a pause) when there is no work now or
/// the coordinator did not answer (it may be restarting: the pause backs off, with
/// jitter); an error when it refuses this worker, or has been unreachable for longer than
/// allowed.
async fn next_lease(
    client: &Client,
    config: &WorkerConfig,
    geometry: GeometryCounts,
    unreachable: &mut Unreachable,
) -> Result<Option<Lease>, WorkerError> {
    let answer = client
        .lease_for(&crate::api::LeaseRequest {
            worker: config.name.clone(),
            tags: config.tags.clone(),
            memory_mib: config.memory_mib,
            geometry: Some(geometry),
        })
        .await;
    if matches!(answer, Err(ClientError::Http(_))) {
        let since = *unreachable
            .since
            .get_or_insert_with(std::time::Instant::now);
        if since.elapsed() > config.give_up_after {
            return Err(WorkerError::Unreachable {
                url: config.coordinator.clone(),
                after: config.give_up_after,
            });
        }
        let pause = unreachable.backoff(&config.name);
        unreachable.attempts += 1;
        tracing::warn!(
            "the coordinator at {} did not answer; asking again in {pause:?}",
            config.coordinator
        );
        tokio::time::sleep(pause).await;
        return Ok(None);
    }
    *unreachable = Unreachable::default();
    match answer {
        Ok(Some(lease)) => Ok(Some(lease)),
        Ok(None) => {
            tokio::time::sleep(config.poll).await;
            Ok(None)
        }
        Err(e)
            if e.status() == Some(StatusCode::FORBIDDEN)
                || e.status() == Some(StatusCode::UNAUTHORIZED)
                || matches!(e, ClientError::Setup(_)) =>
        {
            Err(WorkerError::Refused(e))
        }
        Err(e) => {
            tracing::warn!("{e}");
            tokio::time::sleep(Duration::from_millis(500)).await;
            Ok(None)
        }
    }
}

/// The bytes of meshes a worker keeps for the next frame of a shot: a quarter of the memory
/// it offers, or 2 GiB if it says none.
fn mesh_budget(memory_mib: Option<u64>) -> u64 {
    memory_mib.map_or(2 << 30, |m| (m << 20) / 4)
}

/// Scenes loaded for the last few job specs and frames, and the meshes the frames of a shot
/// share (loaded once while its frames follow each other).
struct Scenes {
    loaded: HashMap<String, Arc<Loaded>>,
    meshes: Arc<kiln_scene::MeshCache>,
}

impl Scenes {
    fn new(mesh_budget: u64) -> Scenes {
        Scenes {
            loaded: HashMap::new(),
            meshes: Arc::new(kiln_scene::MeshCache::new(mesh_budget)),
        }
    }

    /// What the geometry cache has done so far.
    fn geometry(&self) -> GeometryCounts {
        GeometryCounts {
            loads: self.meshes.loads(),
            reused: self.meshes.reused(),
        }
    }

    async fn get(
        &mut self,
        client: &Client,
        config: &WorkerConfig,
        lease: &Lease,
    ) -> Result<Arc<Loaded>, LoadError> {
        // What the renderer is built from: a job's passes (stopped early, extended) do not
        // change it.
        let spec = &lease.spec;
        let frame = lease.frame as usize;
        let key = format!(
            "{} {:?} {:?} {:?}",
            spec.scene,
            spec.frame_scene(frame),
            spec.overrides(),
            spec.tile
        );
        let loaded = match self.loaded.get(&key) {
            Some(l) => l.clone(),
            None => Arc::new(load(client, config, spec, frame, &self.meshes).await?),
        };
        if self.loaded.len() >= 4 {
            self.loaded.clear();
        }
        self.loaded.insert(key, loaded.clone());
        Ok(loaded)
    }
}

/// Loads frame `frame` of `spec` (downloading and unpacking its bundle if this worker has
/// not yet), taking the meshes it reads from `meshes` where they are kept.
async fn load(
    client: &Client,
    config: &WorkerConfig,
    spec: &JobSpec,
    frame: usize,
    meshes: &Arc<kiln_scene::MeshCache>,
) -> Result<Loaded, LoadError> {
    let scene_path = match bundle::cached_scene(&config.cache_dir, &spec.scene) {
        Some(path) => path,
        None => {
            let bytes = client
                .download_scene(&spec.scene)
                .await
                .map_err(LoadError::Download)?;
            let digest = bundle::digest_of(&bytes);
            if digest != spec.scene {
                return Err(LoadError::Digest {
                    actual: digest,
                    expected: spec.scene.clone(),
                });
            }
            let cache = config.cache_dir.clone();
            tokio::task::spawn_blocking(move || {
                bundle::unpack_into_cache(bundle::Source::Bytes(&bytes), &digest, &cache, false)
            })
            .await
            .map_err(LoadError::Task)?
            .map_err(LoadError::Bundle)?
        }
    };
    let root = config.cache_dir.join(&spec.scene);
    let scene_path = match spec.frame_scene(frame) {
        Some(name) => root.join(name),
        None => scene_path,
    };
    if config.fault == Some(Fault::AbortOnMarkedScene)
        && std::fs::read_to_string(&scene_path).is_ok_and(|t| t.contains(ABORT_MARKER))
    {
        eprintln!("kiln worker {}: aborting on a marked scene", config.name);
        std::process::abort();
    }
    let overrides = spec.overrides();
    let share: Arc<dyn SharedPrepass> = Arc::new(CoordinatorShare {
        client: client.clone(),
        runtime: tokio::runtime::Handle::current(),
        scene: spec.scene.clone(),
        prefix: spec.prepass_prefix(frame),
    });
    let meshes = meshes.clone();
    tokio::task::spawn_blocking(move || {
        let mut desc = kiln_scene::load_file_within_sharing(&scene_path, &root, Some(meshes))
            .map_err(|e| LoadError::Scene(bundle::relative_message(&e, &root)))?;
        desc.apply_overrides(&overrides)
            .map_err(LoadError::Overrides)?;
        let renderer = Renderer::build_sharing(&desc, Some(share)).map_err(LoadError::Build)?;
        Ok(Loaded {
            renderer,
            frame: (desc.film.xresolution, desc.film.yresolution),
        })
    })
    .await
    .map_err(LoadError::Task)?
}

/// A job's shared pre-passes (photon maps, SPPM's passes) through the coordinator. The
/// renderer calls it from its own threads, outside the runtime, so each call blocks on the
/// runtime's handle. A coordinator that cannot be reached makes this worker compute what it
/// needs itself (the bytes are the same).
struct CoordinatorShare {
    client: Client,
    runtime: tokio::runtime::Handle,
    scene: String,
    prefix: String,
}

impl SharedPrepass for CoordinatorShare {
    fn fetch(&self, name: &str) -> Shared {
        let name = format!("{}-{name}", self.prefix);
        let (client, scene) = (&self.client, &self.scene);
        self.runtime.block_on(async {
            match client.prepass(scene, &name).await {
                Ok(Some(bytes)) => return Shared::Ready(bytes),
                Ok(None) => {}
                Err(e) => {
                    tracing::warn!("pre-pass {name}: {e}; computing it here");
                    return Shared::Yours;
                }
            }
            match client.claim_prepass(scene, &name).await {
                Ok(PrepassClaim::Theirs) => Shared::Theirs,
                Ok(PrepassClaim::Ready) => match client.prepass(scene, &name).await {
                    Ok(Some(bytes)) => Shared::Ready(bytes),
                    _ => Shared::Yours,
                },
                Ok(PrepassClaim::Yours) => Shared::Yours,
                Err(e) => {
                    tracing::warn!("pre-pass {name}: {e}; computing it here");
                    Shared::Yours
                }
            }
        })
    }

    fn publish(&self, name: &str, bytes: &[u8]) {
        let name = format!("{}-{name}", self.prefix);
        let upload = self
            .client
            .upload_prepass(&self.scene, &name, bytes.to_vec());
        if let Err(e) = self.runtime.block_on(upload) {
            // The others would wait for the claim to lapse: give it up, so the next to ask
            // computes it.
            tracing::warn!("pre-pass {name}: cannot upload it: {e}");
            let release = self.client.release_prepass(&self.scene, &name);
            let _ = self.runtime.block_on(release);
        }
    }
}

/// Heartbeats for `lease` until the task is aborted; the flag turns true when the
/// coordinator refuses one (the job was cancelled or has ended, the lease expired).
fn keep_alive(client: &Client, lease: &Lease) -> (tokio::task::JoinHandle<()>, Arc<AtomicBool>) {
    let lost = Arc::new(AtomicBool::new(false));
    let client = client.clone();
    let id = lease.lease;
    let flag = lost.clone();
    let every = Duration::from_millis((lease.ttl_ms / 3).max(10));
    let beat = tokio::spawn(async move {
        loop {
            tokio::time::sleep(every).await;
            match client.heartbeat(id).await {
                Ok(()) => {}
                Err(e) if e.status().is_some_and(|s| s.is_client_error()) => {
                    flag.store(true, Ordering::SeqCst);
                    break;
                }
                // The coordinator may be restarting: the lease may still be good.
                Err(_) => {}
            }
        }
    });
    (beat, lost)
}

/// What became of a leased tile.
enum Outcome {
    Uploaded,
    /// The render failed, and the lease with it (the coordinator was told why).
    Failed(String),
    /// The render stopped part way: the lease was lost, or the worker was told to leave now.
    Abandoned,
}

async fn render_and_upload(
    client: &Client,
    pool: &Arc<rayon::ThreadPool>,
    loaded: &Arc<Loaded>,
    lease: &Lease,
    stop: &Arc<Stop>,
    fault: Option<Fault>,
) -> Result<Outcome, ClientError> {
    // Heartbeats keep the lease while the tile renders; one the coordinator refuses (the
    // job was cancelled or has ended, the lease expired) stops the render between rounds.
    let (beat, lost) = keep_alive(client, lease);
    let rect = TileRect::from(lease.tile);
    let from = match previous_sums(client, loaded, lease).await {
        Ok(sums) => sums,
        Err(why) => {
            beat.abort();
            let _ = client.fail(lease.lease, &why).await;
            return Ok(Outcome::Failed(why));
        }
    };
    let to = lease.pass.to;
    let (pool, loaded2, lost2, stop2) = (pool.clone(), loaded.clone(), lost.clone(), stop.clone());
    let exr = tokio::task::spawn_blocking(move || {
        let halt = || lost2.load(Ordering::Relaxed) || stop2.now.load(Ordering::Relaxed);
        let renderer = &loaded2.renderer;
        let rendered = match &from {
            Some(from) => pool
                .install(|| render_tile_pass(renderer, from, to, &halt))
                .map_err(|e| e.to_string())?,
            // SPPM: one pass, no sums.
            None => pool
                .install(|| render_tile_until(renderer, rect, &halt))
                .map(|r| (r, TileSums::empty(rect, SumsLayout::default()))),
        };
        let Some((result, sums)) = rendered else {
            return Ok(None);
        };
        if let Some(why) = result.stats.cut_off_error() {
            return Err(why);
        }
        let (t, (frame_width, frame_height)) = (result.rect, loaded2.frame);
        let aovs = kiln_image::Aovs {
            names: kiln_render::aov_names(renderer.settings().gbuffer),
            values: result.aovs,
        };
        let mut buffer =
            kiln_image::RgbBuffer::new(frame_width, frame_height, t.x0, t.y0, t.width, t.height)
                .holding(result.pixels, aovs);
        if let Some(fault) = fault {
            fault.apply(&mut buffer);
        }
        if from.is_some() {
            buffer.words = kiln_image::Words {
                names: TileSums::word_names(sums.layout),
                values: sums.to_words(),
            };
        }
        kiln_image::encode_exr(&buffer)
            .map(Some)
            .map_err(|e| e.to_string())
    })
    .await;
    beat.abort();
    let exr = match exr {
        Ok(Ok(Some(bytes))) => bytes,
        Ok(Ok(None)) => {
            if !lost.load(Ordering::SeqCst) {
                // Told to leave now: the tile goes back to be lent again at once.
                let _ = client.fail(lease.lease, "the worker was stopped").await;
            }
            return Ok(Outcome::Abandoned);
        }
        Ok(Err(e)) => {
            let _ = client.fail(lease.lease, &e.to_string()).await;
            return Ok(Outcome::Failed(e));
        }
        Err(e) => {
            let why = format!("the render panicked: {e}");
            let _ = client.fail(lease.lease, &why).await;
            return Ok(Outcome::Failed(why));
        }
    };
    client.upload_tile(lease.lease, exr).await?;
    Ok(Outcome::Uploaded)
}

/// The running sums a lease's pass continues: none for SPPM (one pass, no sums), empty for
/// a first pass, else the tile's EXR after its previous pass, downloaded and checked.
async fn previous_sums(
    client: &Client,
    loaded: &Loaded,
    lease: &Lease,
) -> Result<Option<TileSums>, String> {
    let settings = loaded.renderer.settings();
    let rect = TileRect::from(lease.tile);
    if let Integrator::Sppm(_) = settings.integrator {
        return Ok(None);
    }
    let layout = settings.sums_layout();
    let from = lease.pass.from;
    if from == 0 {
        return Ok(Some(TileSums::empty(rect, layout)));
    }
    let bytes = client
        .lease_sums(lease.lease)
        .await
        .map_err(|e| format!("cannot download the tile's running sums: {e}"))?
        .ok_or("the tile's running sums were damaged on the way")?;
    let tile = kiln_image::decode_exr_limited(&bytes, rect.pixel_count())
        .map_err(|e| format!("the tile's running sums do not decode: {e}"))?;
    let place = (tile.x0, tile.y0, tile.width, tile.height);
    if place != (rect.x0, rect.y0, rect.width, rect.height) {
        return Err("the running sums downloaded are of another tile".into());
    }
    let sums = TileSums::from_words(rect, layout, &tile.words.names, &tile.words.values)
        .map_err(|e| e.to_string())?;
    if sums.samples != from {
        return Err(format!(
            "the tile's running sums hold {} samples, not the {from} its pass starts from",
            sums.samples
        ));
    }
    Ok(Some(sums))
}

#[cfg(test)]
mod backoff_tests {
    use super::Unreachable;
    use std::time::Duration;

    /// The pause doubles from 250 ms to at most 8 s, each drawn between half and all of it.
    #[test]
    fn backoff_grows_to_its_cap_with_jitter() {
        for attempts in 0..12u32 {
            let u = Unreachable {
                since: None,
                attempts,
            };
            let full = Duration::from_millis(250 * (1 << attempts.min(5)));
            for _ in 0..50 {
                let pause = u.backoff("worker-7");
                assert!(pause >= full / 2 && pause <= full, "{attempts}: {pause:?}");
            }
        }
    }
}
