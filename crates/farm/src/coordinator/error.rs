//! What the coordinator's operations fail with: the client's mistakes (each with the
//! message the client is shown) and internal failures (the store, the disk, a task).
//!
//! This file only names failures. Which HTTP status each one gets, and which are shown or
//! only logged, is `http.rs`'s business; nothing here logs or knows about HTTP.
//!
//! Messages carry their cause's text (`"job store: {0}"`) and causes are not chained as
//! `source()`, so a `{:#}` print (the CLI's) says each thing once.

use super::store::StoreError;
use crate::api::{JobState, Rect};
use crate::bundle::BundleError;
use kiln_image::ImageError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    // The client's mistakes: shown to it.
    #[error("missing or wrong bearer token")]
    Unauthorized,
    #[error("no such route")]
    NoRoute,
    #[error("'{0}' is not an id")]
    BadId(String),
    #[error("bad request body: {0}")]
    BadBody(serde_json::Error),
    #[error("bad job: {0}")]
    BadJob(serde_json::Error),
    /// A scene bundle that does not unpack.
    #[error("{0}")]
    BadBundle(BundleError),
    #[error("a digest is hexadecimal")]
    BadDigest,
    #[error("exposure is a number of stops from -20 to 20")]
    BadExposure,
    #[error("denoise is 1 (or true) or 0 (or false)")]
    BadDenoise,
    #[error("no scene with digest '{0}'")]
    UnknownScene(String),
    #[error("no job {0}")]
    UnknownJob(u64),
    /// A token's role does not allow the request, or a worker's credential is another's.
    #[error("{0}")]
    Forbidden(String),
    #[error("no token {0}")]
    UnknownToken(u64),
    /// A token asked for with a name that is not one.
    #[error("{0}")]
    BadToken(String),
    #[error("job {id} has no frame {frame} (frames count from 0)")]
    UnknownFrame { id: u64, frame: u32 },
    #[error("no worker '{0}' is set aside")]
    NotSetAside(String),
    #[error("{0}")]
    BadWorkerName(String),
    /// A worker's tags that are not tags.
    #[error("{0}")]
    BadTags(String),
    /// A job whose scene cannot be planned into tiles.
    #[error("{0}")]
    Unplannable(PlanError),
    #[error("job {id} is {}, not done", state.as_str())]
    NotDone { id: u64, state: JobState },
    #[error("worker '{worker}' is set aside: {reason}")]
    SetAside { worker: String, reason: String },
    #[error("lease {0} has expired or is unknown")]
    UnknownLease(u64),
    /// An upload under an expired lease that is not the tile already kept.
    #[error("lease {0} has expired or is unknown, and the tile differs from the one kept")]
    StaleTile(u64),
    /// An upload under an expired lease whose tile has been lent again and is not back yet:
    /// the newer lease's upload is the one kept.
    #[error(
        "lease {0} has expired and its tile is lent to another worker; this upload is not kept"
    )]
    Relent(u64),
    #[error("job {0} is no longer running")]
    JobEnded(u64),
    /// A job that cannot be stopped or extended as asked.
    #[error("job {id}: {why}")]
    Passes { id: u64, why: PlanError },
    #[error("lease {0}'s pass starts from nothing: there are no running sums to download")]
    NoSums(u64),
    #[error("job {0} has no merged pass yet")]
    NoResult(u64),
    #[error("the upload is larger than the {limit} bytes this coordinator accepts")]
    TooLarge { limit: usize },
    #[error("the upload broke off: {0}")]
    BrokenUpload(String),
    #[error("a tile upload must give the SHA-256 of its bytes in the X-Kiln-Tile-SHA256 header")]
    NoTileDigest,
    #[error("rejected tile: {0}")]
    RejectedTile(TileRejected),
    #[error("a pre-pass name is 1 to 128 of a-z, 0-9 and '-'")]
    BadPrepassName,
    #[error("no pre-pass '{0}' is stored for this scene")]
    UnknownPrepass(String),
    #[error(
        "no job of this scene shares a pre-pass named '{0}' (a job's are PREFIX-photon-maps and PREFIX-sppm-pass-N, PREFIX from its inputs)"
    )]
    UnwantedPrepass(String),
    #[error(
        "a pre-pass upload must give the SHA-256 of its bytes in the X-Kiln-Prepass-SHA256 header, and its bytes must have it"
    )]
    PrepassDigest,

    // Internal failures: logged, never shown.
    #[error("job store: {0}")]
    Store(StoreError),
    /// The object store could not be set up, written or read.
    #[error("{0}")]
    Objects(String),
    #[error("{}: {message}", path.display())]
    Io { path: PathBuf, message: String },
    #[error("cannot store a scene: {0}")]
    Unpack(BundleError),
    #[error("{0}")]
    Image(ImageError),
    /// A frame larger than the coordinator denoises.
    #[error(
        "the frame of {pixels} pixels is larger than the {limit} this coordinator denoises: download result.exr and run `kiln denoise` on it"
    )]
    DenoiseTooLarge { pixels: u64, limit: u64 },
    /// A frame that cannot be denoised (it holds no features, or no variance).
    #[error("the frame cannot be denoised: {0}")]
    Denoise(kiln_denoise::Error),
    #[error("a blocking task failed: {0}")]
    Task(tokio::task::JoinError),
    /// The data directory holds what its store has lost: starting would hide those jobs.
    #[error("{0}")]
    LostJobs(String),
}

impl Error {
    pub(super) fn io(path: impl Into<PathBuf>, e: std::io::Error) -> Error {
        Error::Io {
            path: path.into(),
            message: e.to_string(),
        }
    }
}

impl From<StoreError> for Error {
    fn from(e: StoreError) -> Error {
        Error::Store(e)
    }
}

impl From<tokio::task::JoinError> for Error {
    fn from(e: tokio::task::JoinError) -> Error {
        Error::Task(e)
    }
}

/// Why a job's scene cannot be turned into a frame and tiles.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("tile must be at least 1")]
    ZeroTile,
    /// Tiles of `tile` pixels would cut the frame into more than [`super::job::MAX_TILES`].
    #[error(
        "tiles of {tile} pixels cut this {width}x{height} render into {count} tiles; a job has at most {max}: use tiles of at least {least} pixels"
    )]
    TooManyTiles {
        tile: u32,
        width: u32,
        height: u32,
        count: u64,
        max: u64,
        least: u32,
    },
    #[error("no scene with digest '{0}' was uploaded")]
    NoScene(String),
    /// The parser's message, with the data directory's prefix taken off file names.
    #[error("{0}")]
    Scene(String),
    /// Overrides the scene cannot take (a resolution out of range, ...).
    #[error("{0}")]
    Overrides(String),
    #[error("{0}")]
    Webhook(String),
    #[error("verify is the fraction of tile passes rendered twice, 0 to 1, not {0}")]
    Verify(f64),
    /// A pass schedule that cannot be rendered, or extended as asked.
    #[error("passes: {0}")]
    Passes(String),
    /// Requirements that are not tags, or a worker cap of none.
    #[error("{0}")]
    Requirements(String),
    /// Jobs to start after that do not exist (yet), or too many.
    #[error("after: {0}")]
    After(String),
    /// A shot's frame list that names no scene of the bundle, or frames that differ where
    /// they must agree.
    #[error("frames: {0}")]
    Frames(String),
}

/// Why an uploaded tile was refused (the attempt counts as failed).
#[derive(Debug, thiserror::Error)]
pub enum TileRejected {
    #[error("{0}")]
    Decode(ImageError),
    #[error(
        "the EXR's windows ({}x{} frame, {}x{} at {},{}) are not the leased tile's",
        frame.0, frame.1, window.width, window.height, window.x0, window.y0
    )]
    Windows { frame: (u32, u32), window: Rect },
    #[error(
        "the tile's further channels are {found:?}, not the {expected:?} its frame keeps (a worker of another Kiln version?)"
    )]
    Channels {
        found: Vec<String>,
        expected: Vec<String>,
    },
    #[error("the tile has NaN or infinite pixels")]
    NonFinite,
    #[error("the tile's bytes do not have the SHA-256 its upload gives (damaged on the way)")]
    Digest,
    #[error("{0}")]
    Sums(kiln_render::SumsError),
}
