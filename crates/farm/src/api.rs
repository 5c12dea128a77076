//! The JSON types of the HTTP API (under /v1), shared by the coordinator and its clients.

use serde::{Deserialize, Serialize};

/// What to render: a scene bundle and the settings that override the scene's own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobSpec {
    /// Digest of an uploaded scene bundle.
    pub scene: String,
    #[serde(default)]
    pub spp: Option<u32>,
    #[serde(default)]
    pub resolution: Option<(u32, u32)>,
    #[serde(default = "default_tile")]
    pub tile: u32,
    #[serde(default)]
    pub seed: Option<u32>,
    /// Progressive passes: cumulative samples per pixel at the end of each pass, ascending
    /// (for example 16, 64, 256, 1024, 2048). After each pass the whole frame is merged and
    /// can be downloaded; the job can be stopped after any pass and extended later. The
    /// last is the job's samples per pixel (`spp`, if given, must equal it). Absent: one
    /// pass of `spp` (or the scene's count).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub passes: Option<Vec<u32>>,
    /// Verified workers: the fraction (0 to 1) of tile passes rendered twice, on different
    /// workers, and compared bit for bit. Renders are deterministic, so a difference proves
    /// a worker wrong: a third render decides which, that worker is set aside with the
    /// reason, and what it rendered unchecked is rendered again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verify: Option<f64>,
    /// Higher runs first; jobs of equal priority share the workers.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub priority: i32,
    /// Called (POST, the job's status as JSON) when the job ends: done, failed or
    /// cancelled. Retried with backoff until it answers 2xx.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub webhook: Option<String>,
    /// Spectral (true) or RGB (false) rendering; absent: the scene's choice (spectral
    /// unless it says `Option "kiln.spectral" false`). The coordinator records the mode it
    /// planned the job with, so the job's every tile renders in it, across restarts and
    /// upgrades.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectral: Option<bool>,
    /// Tags a worker must have declared, every one of them, to be lent this job's tiles
    /// (`kiln worker --tags big-mem,avx512`); empty: any worker.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub requires: Vec<String>,
    /// At most this many workers hold the job's leases at once (at least 1); absent: no
    /// limit beyond sharing with jobs of equal priority.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_workers: Option<u32>,
    /// Jobs (at most [`MAX_AFTER`], each created before this one) this one starts after:
    /// until then it is lent nothing, and its status says what it waits for.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub after: Vec<u64>,
    /// Start once every job in `after` has ended, done or not; otherwise (the default)
    /// once every one is done.
    #[serde(default, skip_serializing_if = "is_false")]
    pub after_ended: bool,
    /// When a job this one waits on to be done fails or is cancelled: hold (stay waiting,
    /// its status naming that job, until this one is cancelled: a failed or cancelled job
    /// does not run again) rather than fail too (the default).
    #[serde(default, skip_serializing_if = "is_false")]
    pub hold_on_failure: bool,
    /// A shot: the frames' scene files, paths relative to the bundle (at most
    /// [`MAX_FRAMES`]), in the shot's order. Each frame is rendered as `kiln render` renders
    /// its file, and every frame must have the same film size. Empty: one frame, the
    /// bundle's scene file.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<String>,
    /// The submitter whose token created the job (set by the coordinator, whatever a
    /// client sends): a submitter sees and changes only its own jobs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub owner: Option<String>,
}

/// The most jobs a job starts after.
pub const MAX_AFTER: usize = 64;

/// The most frames a job (a shot) has.
pub const MAX_FRAMES: usize = 10_000;

fn is_false(v: &bool) -> bool {
    !*v
}

fn is_zero(v: &i32) -> bool {
    *v == 0
}

fn default_tile() -> u32 {
    32
}

impl JobSpec {
    /// A job of the bundle with digest `scene`, rendered with the scene's own settings in
    /// tiles of 32 pixels, one frame, no requirements.
    pub fn new(scene: &str) -> JobSpec {
        JobSpec {
            scene: scene.into(),
            spp: None,
            resolution: None,
            tile: default_tile(),
            seed: None,
            passes: None,
            verify: None,
            priority: 0,
            webhook: None,
            spectral: None,
            requires: Vec::new(),
            max_workers: None,
            after: Vec::new(),
            after_ended: false,
            hold_on_failure: false,
            frames: Vec::new(),
            owner: None,
        }
    }

    /// What the job changes in its scene: the samples per pixel are the last pass's when
    /// passes are given.
    pub fn overrides(&self) -> kiln_scene::Overrides {
        kiln_scene::Overrides {
            resolution: self.resolution,
            spp: self
                .spp
                .or_else(|| self.passes.as_ref().and_then(|p| p.last().copied())),
            seed: self.seed,
            noise_threshold: None,
            spectral: self.spectral,
        }
    }

    /// How many frames the job renders.
    pub fn frame_count(&self) -> usize {
        self.frames.len().max(1)
    }

    /// Frame `frame`'s scene file, relative to the bundle; `None` for the bundle's own
    /// scene file (a job of one frame).
    pub fn frame_scene(&self, frame: usize) -> Option<&str> {
        self.frames.get(frame).map(String::as_str)
    }

    /// The prefix of frame `frame`'s shared pre-pass names (see [`prepass_prefix`]): a
    /// shot's frames each have their own photon maps.
    pub fn prepass_prefix(&self, frame: usize) -> String {
        let o = self.overrides();
        match self.frame_scene(frame) {
            None => prepass_prefix(&o),
            Some(scene) => {
                let inputs = format!(
                    "photons-v1 {:?} {:?} {:?} frame {scene}",
                    o.resolution, o.spp, o.seed
                );
                crate::bundle::digest_of(inputs.as_bytes())[..16].to_string()
            }
        }
    }
}

/// One frame of a job, as GET /v1/jobs/{id}/frames lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameStatus {
    /// Its place in the shot, from 0.
    pub index: u32,
    /// Its scene file in the bundle (empty for a job of one frame: the bundle's own).
    pub scene: String,
    pub tiles_total: u32,
    pub tiles_done: u32,
    /// Fraction of its samples done, 0 to 1.
    pub progress: f64,
    /// Passes merged into its result (`/v1/jobs/{id}/frames/{index}/result.exr`).
    pub passes_done: u32,
    pub samples_per_pixel_done: u32,
}

/// The samples a lease renders: each pixel of its tile from `from` samples (the running
/// sums the tile holds after its previous pass, downloaded from
/// `/v1/leases/{id}/sums`; none when 0) on to `to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PassRange {
    /// The pass's index in the job's schedule.
    pub index: u32,
    pub from: u32,
    pub to: u32,
}

/// A job's passes extended to more samples (POST /v1/jobs/{id}/extend).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Extend {
    /// Further cumulative sample counts, ascending, each above the job's last.
    pub passes: Vec<u32>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    Running,
    Done,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 4] = [
        JobState::Running,
        JobState::Done,
        JobState::Failed,
        JobState::Cancelled,
    ];

    /// The state's name, as its JSON spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Running => "running",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    /// The state named `name` (as [`JobState::as_str`] spells it).
    pub fn from_name(name: &str) -> Option<JobState> {
        JobState::ALL.into_iter().find(|s| s.as_str() == name)
    }
}

/// A job's progress, as GET /v1/jobs/{id} and its events report it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobStatus {
    pub id: u64,
    pub state: JobState,
    pub width: u32,
    pub height: u32,
    pub tiles_total: u32,
    pub tiles_done: u32,
    pub samples_total: u64,
    pub samples_done: u64,
    /// Fraction done, 0 to 1.
    pub progress: f64,
    /// Samples per second since the job's first lease (after it was created, resumed or
    /// extended): time queued behind other jobs does not count.
    pub samples_per_second: f64,
    pub eta_seconds: Option<f64>,
    /// Tile attempts that failed (worker errors, corrupt uploads).
    pub failures: u32,
    pub error: Option<String>,
    /// Seconds spent writing the merged EXR when the last tile arrived.
    #[serde(default)]
    pub merge_seconds: Option<f64>,
    /// The job's passes (cumulative samples per pixel) and how many are merged: the
    /// result holds `samples_per_pixel_done` samples of every pixel (0 before the first
    /// pass is merged).
    #[serde(default)]
    pub passes: Vec<u32>,
    #[serde(default)]
    pub passes_done: u32,
    #[serde(default)]
    pub samples_per_pixel_done: u32,
    /// Tile passes two workers rendered with the same bits before one was kept.
    #[serde(default)]
    pub tile_passes_verified: u64,
    /// Checked tile passes rendered once and waiting for a second worker's render to
    /// compare with (with one worker, they wait until another joins).
    #[serde(default)]
    pub tile_passes_held: u32,
    /// Why a job renders tiles again or ran again after it was done: a worker whose
    /// unchecked renders its frame held was set aside.
    #[serde(default)]
    pub notice: Option<String>,
    #[serde(default)]
    pub priority: i32,
    /// What became of the job's webhook call, once it has ended.
    #[serde(default)]
    pub webhook: Option<String>,
    /// Why no worker takes the running job's tiles, when none of the workers heard from
    /// can: the tags it requires that none of them has.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waiting: Option<String>,
    /// The tags its workers must offer (its spec's).
    #[serde(default)]
    pub requires: Vec<String>,
    /// The most workers it is lent to at once (its spec's).
    #[serde(default)]
    pub max_workers: Option<u32>,
    /// The jobs it starts after (its spec's).
    #[serde(default)]
    pub after: Vec<u64>,
    /// The memory a worker is estimated to need for it, in MiB, from its scene when it
    /// was planned: it is lent only to workers that offer at least this much.
    #[serde(default)]
    pub memory_mib: u64,
    /// The frames it renders (1 unless it is a shot: see `/v1/jobs/{id}/frames`).
    #[serde(default = "one")]
    pub frame_count: u32,
    /// The submitter that created it (none: the admin).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub owner: Option<String>,
}

fn one() -> u32 {
    1
}

/// A worker as the coordinator knows it (GET /v1/workers).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkerStatus {
    pub name: String,
    /// Tile passes it rendered and uploaded.
    pub tiles_done: u64,
    pub failures: u64,
    /// Seconds since it last asked for work, renewed a lease or uploaded.
    pub last_seen_seconds: Option<f64>,
    /// Why it gets no more leases, if it does not.
    pub set_aside: Option<String>,
    /// What it is rendering now.
    pub leases: Vec<WorkerLease>,
    /// The tags it declared with its last request for work.
    #[serde(default)]
    pub tags: Vec<String>,
    /// The memory it offered then, in MiB (None: not said).
    #[serde(default)]
    pub memory_mib: Option<u64>,
    /// What its geometry cache has done, as it last said.
    #[serde(default)]
    pub geometry: Option<GeometryCounts>,
}

/// A worker's geometry cache: mesh files read and parsed, and meshes taken from the cache
/// instead (a shot's frames that include the same geometry), since it started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct GeometryCounts {
    pub loads: u64,
    pub reused: u64,
}

/// A lease a worker holds, as [`WorkerStatus`] lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkerLease {
    pub job: u64,
    pub tile_index: u32,
    pub pass: PassRange,
    /// The frame of a shot the tile is of.
    #[serde(default)]
    pub frame: u32,
}

/// A tile's pixels in frame coordinates: the wire form of [`kiln_render::TileRect`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rect {
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

impl From<kiln_render::TileRect> for Rect {
    fn from(t: kiln_render::TileRect) -> Rect {
        let kiln_render::TileRect {
            x0,
            y0,
            width,
            height,
        } = t;
        Rect {
            x0,
            y0,
            width,
            height,
        }
    }
}

impl From<Rect> for kiln_render::TileRect {
    fn from(r: Rect) -> kiln_render::TileRect {
        let Rect {
            x0,
            y0,
            width,
            height,
        } = r;
        kiln_render::TileRect {
            x0,
            y0,
            width,
            height,
        }
    }
}

/// A tile lent to a worker until `deadline_ms` (renewed by heartbeats).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Lease {
    pub lease: u64,
    pub job: u64,
    pub spec: JobSpec,
    pub tile_index: u32,
    pub tile: Rect,
    pub pass: PassRange,
    /// Milliseconds the lease lasts without a heartbeat.
    pub ttl_ms: u64,
    /// The frame the tile is of: its scene is `spec.frames[frame]` in a shot (a job of one
    /// frame has only frame 0, the bundle's scene file).
    #[serde(default)]
    pub frame: u32,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LeaseRequest {
    pub worker: String,
    /// What the worker offers (see [`check_tags`]): it is lent only tiles of jobs whose
    /// `requires` it has, every one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tags: Vec<String>,
    /// The memory it offers, in MiB: it is lent only tiles of jobs estimated to need no
    /// more. Absent: not said (any job).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_mib: Option<u64>,
    /// What its geometry cache has done so far (shown in its status).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geometry: Option<GeometryCounts>,
}

impl LeaseRequest {
    /// A request from `worker` that offers no tags and says nothing of its memory.
    pub fn plain(worker: &str) -> LeaseRequest {
        LeaseRequest {
            worker: worker.into(),
            tags: Vec::new(),
            memory_mib: None,
            geometry: None,
        }
    }
}

/// The longest tag, in bytes.
pub const MAX_TAG: usize = 64;

/// The most tags a worker declares or a job requires.
pub const MAX_TAGS: usize = 32;

/// Checks tags (a worker's, or those a job requires): at most [`MAX_TAGS`], each 1 to
/// [`MAX_TAG`] bytes of lower-case letters, digits and `-`, `_`, `.`. The message names
/// the first that is not one.
pub fn check_tags(tags: &[String]) -> Result<(), String> {
    if tags.len() > MAX_TAGS {
        return Err(format!("{} tags; at most {MAX_TAGS}", tags.len()));
    }
    let allowed = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || "-_.".contains(c);
    for tag in tags {
        if tag.is_empty() || tag.len() > MAX_TAG || !tag.chars().all(allowed) {
            return Err(format!(
                "tag {} is not 1 to {MAX_TAG} of a-z, 0-9 and - _ .",
                quoted(tag)
            ));
        }
    }
    Ok(())
}

/// The longest worker name, in bytes.
pub const MAX_WORKER_NAME: usize = 128;

/// Checks a worker's name: 1 to [`MAX_WORKER_NAME`] bytes of letters, digits and `.`, `_`,
/// `-`, `:`, `@` (a host name, a pod's, `host-pid`). The coordinator keeps a record per
/// name, so a name is bounded; `kiln worker` checks its own before it starts.
pub fn check_worker_name(name: &str) -> Result<(), String> {
    let allowed = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-' | ':' | '@');
    if name.is_empty() || name.len() > MAX_WORKER_NAME || !name.chars().all(allowed) {
        return Err(format!(
            "worker name {} is not 1 to {MAX_WORKER_NAME} of letters, digits and . _ - : @",
            quoted(name)
        ));
    }
    Ok(())
}

/// A name a client gave, quoted for a message: at most 40 characters of it, escaped.
fn quoted(name: &str) -> String {
    let shown: String = name.chars().take(40).collect();
    let more = if name.chars().count() > 40 { "..." } else { "" };
    format!("'{}{more}'", shown.escape_debug())
}

/// What a token may do. The coordinator's own token (`--token`) is the admin's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Everything: every job and worker, and issuing and revoking tokens.
    Admin,
    /// Uploads scenes, creates jobs, and sees, follows, stops, extends and cancels its own.
    Submitter,
    /// One worker: leases, heartbeats, uploads and failures of its own leases, under the
    /// name the credential was issued for, and the scenes and pre-passes they need.
    Worker,
}

impl Role {
    /// The role's name, as its JSON spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Admin => "admin",
            Role::Submitter => "submitter",
            Role::Worker => "worker",
        }
    }
}

/// A token to issue (POST /v1/tokens, admin only): its role and whose it is (a submitter's
/// or a worker's name, checked as worker names are).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TokenRequest {
    pub role: Role,
    pub name: String,
}

/// A token as the coordinator lists it: never its secret, which only the answer to its
/// issue holds.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TokenInfo {
    pub id: u64,
    pub role: Role,
    pub name: String,
    pub revoked: bool,
}

/// A token just issued: its secret, shown this once (the coordinator keeps only its hash).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TokenIssued {
    #[serde(flatten)]
    pub info: TokenInfo,
    pub token: String,
}

/// Who a token is (POST /v1/token/check): whether it is valid, and its role and name.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TokenCheck {
    pub valid: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub role: Option<Role>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Failure {
    pub reason: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneUploaded {
    pub digest: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JobCreated {
    pub id: u64,
}

/// Every 4xx and 5xx response body.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ApiError {
    pub error: String,
}

/// The header a tile upload carries: the SHA-256 of its EXR bytes, in hexadecimal, computed
/// by the worker that rendered it. The coordinator accepts the tile only if the bytes it
/// received have that digest, so a tile damaged on the way is rendered again rather than
/// merged.
pub const TILE_DIGEST_HEADER: &str = "x-kiln-tile-sha256";

/// The header a standby coordinator's 503 names the leading coordinator's address in.
pub const LEADER_HEADER: &str = "x-kiln-leader";

/// The header carrying the SHA-256 (hex) of a shared pre-pass's bytes, on upload and
/// download.
pub const PREPASS_DIGEST_HEADER: &str = "x-kiln-prepass-sha256";

/// The part of a shared pre-pass's name that its job's inputs decide beyond the scene
/// bundle (resolution, samples, seed), and the layout's version: a digest's first 16 hex
/// digits. Workers name what they share `PREFIX-photon-maps` and `PREFIX-sppm-pass-N`.
pub fn prepass_prefix(o: &kiln_scene::Overrides) -> String {
    let inputs = format!("photons-v1 {:?} {:?} {:?}", o.resolution, o.spp, o.seed);
    crate::bundle::digest_of(inputs.as_bytes())[..16].to_string()
}

/// The most SPPM passes a job shares (its iterations; pbrt-v4's default is 64).
pub const MAX_SHARED_PASSES: u32 = 1 << 20;

/// Whether `name` is one a job whose pre-pass names start with `prefix` can have: its
/// photon maps, or one of its SPPM passes.
pub fn is_prepass_of(name: &str, prefix: &str) -> bool {
    let Some(rest) = name.strip_prefix(prefix).and_then(|r| r.strip_prefix('-')) else {
        return false;
    };
    rest == "photon-maps"
        || rest.strip_prefix("sppm-pass-").is_some_and(|n| {
            !n.is_empty()
                && n.len() <= 7
                && n.bytes().all(|b| b.is_ascii_digit())
                && (n == "0" || !n.starts_with('0'))
                && n.parse::<u32>().is_ok_and(|i| i < MAX_SHARED_PASSES)
        })
}

/// Who computes a job's shared pre-pass (photon maps, an SPPM pass) that is not stored yet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PrepassClaim {
    /// It is stored: download it.
    Ready,
    /// The asking worker holds the claim: compute it and upload it.
    Yours,
    /// Another worker holds the claim (for at most the claim's time to live).
    Theirs,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PrepassClaimAnswer {
    pub claim: PrepassClaim,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_state_names_are_their_json() {
        for s in JobState::ALL {
            assert_eq!(
                serde_json::to_value(s).unwrap(),
                serde_json::Value::from(s.as_str())
            );
            assert_eq!(JobState::from_name(s.as_str()), Some(s));
        }
        assert_eq!(JobState::from_name("paused"), None);
    }

    #[test]
    fn rects_convert_to_tile_rects_and_back() {
        let t = kiln_render::TileRect {
            x0: 1,
            y0: 2,
            width: 3,
            height: 4,
        };
        let r = Rect::from(t);
        assert_eq!(
            (r.x0, r.y0, r.width, r.height),
            (1, 2, 3, 4),
            "each field lands in its namesake"
        );
        assert_eq!(kiln_render::TileRect::from(r), t);
    }
}
