//! One job in memory: its tiles and passes, what became of each tile (how many passes it
//! has done, which lease renders its next), the queue of tiles to lend next, attempts and
//! failures, the frames the finished tiles are pasted into, and the progress it reports.
//!
//! A job renders its frame in passes (cumulative samples per pixel, one pass by default).
//! A tile's pass continues the running sums its previous pass left (carried in the tile's
//! EXR as integer channels), so each pixel after N samples is the same bytes as
//! `kiln render --spp N`. Tiles run at most one pass ahead of the slowest: every tile's
//! pass p is lent before any tile's pass p + 2. When the last tile of a pass comes back
//! the whole frame at that pass is complete and is merged.
//!
//! A job may be a shot of many frames (`shot.rs`): each frame has the same tiles, a tile's
//! index in the job is its frame's times the tiles a frame has plus its own, and each
//! frame is pasted and merged into a result file of its own.
//!
//! The state is split by concern, each part with its own file: the schedule of passes
//! (`schedule.rs`), lending the tiles (`lending.rs`), the frames (`frames.rs`), the shot's
//! frames and their order (`shot.rs`), restoring them from the store (`restore.rs`); verification's state is `verify.rs`'s
//! [`Verification`], the webhook's `webhooks.rs`'s [`WebhookState`].
//!
//! Bookkeeping only: it reads the scene once to plan the tiles, and otherwise must never do
//! I/O, touch the store or the leases, or read a clock (callers pass `now`).

mod frames;
mod lending;
mod restore;
mod schedule;
mod shot;

use super::error::{PlanError, TileRejected};
use super::verify::{Candidate, Verdict, Verification};
use super::webhooks::WebhookState;
use super::{MAX_TILE_ATTEMPTS, MAX_TILE_EXPIRIES};
use crate::api::{FrameStatus, JobSpec, JobState, JobStatus, PassRange, Rect};
use crate::bundle;
use frames::Frames;
use kiln_image::{RgbBuffer, Windows};
use kiln_render::{SumsLayout, TileRect, TileSums, split_into_tiles};
use lending::Lending;
use schedule::{Schedule, check_passes};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::Instant;

/// The most tiles a job may have. A tile's bookkeeping is some 100 bytes, so this bounds
/// a job's to about 100 MB, and a 16384x16384 frame can still be cut into tiles of 16.
pub const MAX_TILES: u64 = 1 << 20;

pub(super) struct Job {
    pub id: u64,
    pub spec: JobSpec,
    pub state: JobState,
    pub error: Option<String>,
    /// Why a job renders tiles again (a worker whose unchecked renders its sums held was
    /// set aside), for the status.
    pub notice: Option<String>,
    /// What holds the job's work back now (a store that cannot keep its tiles, a frame
    /// that cannot be written): its notice while it lasts.
    pub held_back: BTreeMap<Hold, String>,
    /// When a merged frame that could not be written is written again.
    merge_retry: Option<Instant>,
    /// Writes of a merged frame that failed in a row.
    merge_failures: u32,
    pub merge_seconds: Option<f64>,
    /// One frame's tiles (every frame of a shot has these).
    tiles: Vec<TileRect>,
    schedule: Schedule,
    lending: Lending,
    /// Per frame of the shot, its pictures.
    frames: Vec<Frames>,
    pub verification: Verification,
    pub webhook: WebhookState,
    /// The id of the last lease this job granted (0 for none): jobs of equal priority
    /// take turns by it.
    pub last_lent: u64,
    rate: Rate,
    /// The memory a worker is estimated to need for the job's scene, in MiB (0 where it
    /// could not be planned).
    pub memory_mib: u64,
}

/// What can hold a job's work back for a while.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Hold {
    /// The job store cannot keep its tiles.
    Store,
    /// A complete pass's frame cannot be written.
    Merge,
}

/// When the rate is counted from: the first lease after the job was created, resumed or
/// extended (time spent queued behind other jobs is not rendering), and the samples done
/// by then.
#[derive(Debug, Clone, Copy, Default)]
struct Rate {
    started: Option<Instant>,
    samples_at_start: u64,
}

/// What a tile's upload did to its job.
#[derive(Debug)]
pub(super) enum Landed {
    /// It was a pass the job already had (a repeated upload): nothing changed.
    Nothing,
    /// The tile moved on by a pass.
    Tile,
    /// It was the last tile of frame `index`'s pass `pass`: the frame at that pass is
    /// complete.
    Pass {
        index: u32,
        pass: u32,
        frame: Arc<RgbBuffer>,
    },
}

impl Job {
    /// Loads the job's scene (unpacked under `scenes`) to learn its frame, tiles and passes.
    /// Parser errors name files relative to the bundle, not the data directory.
    pub fn plan(
        scenes: &Path,
        id: u64,
        spec: JobSpec,
        state: JobState,
        max_frame_pixels: u64,
    ) -> Result<Job, PlanError> {
        if spec.tile == 0 {
            return Err(PlanError::ZeroTile);
        }
        shot::check_frames(&spec)?;
        let scene = bundle::cached_scene(scenes, &spec.scene)
            .ok_or_else(|| PlanError::NoScene(spec.scene.clone()))?;
        let root = scenes.join(&spec.scene);
        // A shot's frames are loaded one after the other, sharing their meshes, and each
        // checked against the first; the estimate is the largest frame's.
        let meshes = Arc::new(kiln_scene::MeshCache::new(shot::PLAN_MESH_BUDGET));
        let load = |k: usize| {
            let path = shot::frame_path(&scene, &root, &spec, k)?;
            shot::load(&path, &root, &spec, k, max_frame_pixels, &meshes)
        };
        let desc = load(0)?;
        let mut memory = desc.memory_estimate();
        for k in 1..spec.frame_count() {
            let other = load(k)?;
            shot::check_alike(&desc, &other, &spec, k)?;
            memory = memory.max(other.memory_estimate());
        }
        // The colour mode is pinned as planned, so that a job stored now renders its last
        // tile as its first even if a later Kiln changes the default. (Jobs stored before
        // modes were pinned take the scene's choice as this Kiln makes it.)
        let mut spec = spec;
        spec.spectral = Some(desc.spectral);
        let spp = desc.sampler.pixel_samples;
        let passes = spec.passes.clone().unwrap_or_else(|| vec![spp]);
        check_passes(&passes, 0)?;
        let sppm = desc.integrator.kind == kiln_scene::IntegratorKind::Sppm;
        if sppm && passes.len() > 1 {
            return Err(PlanError::Passes(
                "SPPM renders in one pass (its photon radius shrinks over all its iterations together): give no passes"
                    .into(),
            ));
        }
        let f = &desc.film;
        let [x0, x1, y0, y1] = f.pixel_bounds;
        check_tile_count(x1 - x0, y1 - y0, spec.tile)?;
        let frame = RgbBuffer::new(f.xresolution, f.yresolution, x0, y0, x1 - x0, y1 - y0)
            .with_aovs(kiln_render::aov_names(f.gbuffer));
        let tiles = split_into_tiles(f.pixel_bounds, spec.tile);
        let verify = spec.verify.unwrap_or(0.0);
        if !(0.0..=1.0).contains(&verify) {
            return Err(PlanError::Verify(verify));
        }
        let sums =
            (!sppm).then(|| kiln_render::RenderSettings::from_description(&desc).sums_layout());
        let schedule = Schedule {
            passes,
            sums,
            legacy: false,
        };
        let mut job = Job::with(id, spec, state, tiles, schedule, frame, verify);
        job.memory_mib = memory.div_ceil(1 << 20);
        Ok(job)
    }

    /// A job that cannot be planned again at a restart (its record or its scene bundle is
    /// damaged or gone): kept in the list with the reason, with no tiles. One that was
    /// still running has failed; a finished one keeps its state (its frame is a file).
    pub fn damaged(id: u64, spec: Option<JobSpec>, state: JobState, reason: String) -> Job {
        let spec = spec.unwrap_or(JobSpec {
            tile: 1,
            ..JobSpec::new("")
        });
        let state = if state == JobState::Running {
            JobState::Failed
        } else {
            state
        };
        let frame = RgbBuffer::new(0, 0, 0, 0, 0, 0);
        let schedule = Schedule {
            passes: Vec::new(),
            sums: None,
            legacy: false,
        };
        let mut job = Job::with(id, spec, state, Vec::new(), schedule, frame, 0.0);
        job.error = Some(reason);
        job
    }

    /// A job of `tiles` on `schedule` in a frame like `black`, none started, checking the
    /// fraction `verify` of its tile passes.
    fn with(
        id: u64,
        spec: JobSpec,
        state: JobState,
        tiles: Vec<TileRect>,
        schedule: Schedule,
        black: RgbBuffer,
        verify: f64,
    ) -> Job {
        let (n, count) = (tiles.len(), spec.frame_count());
        let black = Arc::new(black);
        Job {
            id,
            spec,
            state,
            error: None,
            notice: None,
            held_back: BTreeMap::new(),
            merge_retry: None,
            merge_failures: 0,
            merge_seconds: None,
            tiles,
            schedule,
            lending: Lending::new(shot::lending_order(n, count)),
            frames: (0..count).map(|_| Frames::new(black.clone())).collect(),
            verification: Verification::new(verify, n * count),
            webhook: WebhookState::default(),
            last_lent: 0,
            rate: Rate::default(),
            memory_mib: 0,
        }
    }

    fn samples_done(&self) -> u64 {
        self.samples_done_in(0..self.lending.done.len())
    }

    /// Samples done by the tiles `tiles` (job-wide indices).
    fn samples_done_in(&self, tiles: std::ops::Range<usize>) -> u64 {
        tiles
            .map(|i| {
                self.rect(i).pixel_count()
                    * u64::from(self.schedule.samples_after(self.lending.done[i]))
            })
            .sum()
    }

    /// Where tile `idx` (of any frame) lies in its frame.
    pub fn rect(&self, idx: usize) -> TileRect {
        self.tiles[idx % self.tiles.len()]
    }

    /// The frame tile `idx` is of.
    pub fn frame_of(&self, idx: usize) -> usize {
        idx / self.tiles.len().max(1)
    }

    /// How many tiles the job has, every frame's together.
    pub fn tile_count(&self) -> usize {
        self.lending.done.len()
    }

    /// The job-wide indices of frame `frame`'s tiles.
    fn tiles_of(&self, frame: usize) -> std::ops::Range<usize> {
        let n = self.tiles.len();
        frame * n..(frame + 1) * n
    }

    /// Passes every frame has merged into its result.
    fn passes_written(&self) -> u32 {
        self.frames.iter().map(|f| f.written).min().unwrap_or(0)
    }

    /// Progress as the API reports it; the rate counts samples since the job's first lease
    /// after it was created, the coordinator resumed it, or it was extended.
    pub fn status(&self, now: Instant) -> JobStatus {
        let last = self.schedule.last_samples();
        let samples_total: u64 = self.tiles.iter().map(|t| t.pixel_count()).sum::<u64>()
            * self.frames.len() as u64
            * u64::from(last);
        let samples_done = self.samples_done().min(samples_total);
        let rate = self.rate.started.map_or(0.0, |started| {
            let secs = now.saturating_duration_since(started).as_secs_f64();
            let samples = samples_done.saturating_sub(self.rate.samples_at_start) as f64;
            // Until a second has passed the figure says little; none is better.
            if secs < 1.0 { 0.0 } else { samples / secs }
        });
        let progress = if samples_total == 0 {
            1.0
        } else {
            samples_done as f64 / samples_total as f64
        };
        let finished = (0..self.tile_count())
            .filter(|&t| self.is_finished(t))
            .count();
        let (width, height) = self.frames[0].size();
        let written = self.passes_written();
        JobStatus {
            id: self.id,
            state: self.state,
            width,
            height,
            tiles_total: self.tile_count() as u32,
            tiles_done: finished as u32,
            samples_total,
            samples_done,
            progress,
            samples_per_second: rate,
            eta_seconds: (rate > 0.0 && self.state == JobState::Running)
                .then(|| (samples_total - samples_done) as f64 / rate),
            failures: self.lending.failures,
            error: self.error.clone(),
            merge_seconds: self.merge_seconds,
            passes: self.schedule.passes.clone(),
            passes_done: written,
            samples_per_pixel_done: self.schedule.samples_after(written),
            tile_passes_verified: self.verification.verified,
            tile_passes_held: self.verification.held() as u32,
            notice: if self.held_back.is_empty() {
                self.notice.clone()
            } else {
                Some(
                    self.held_back
                        .values()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join("; "),
                )
            },
            priority: self.spec.priority,
            webhook: self.webhook.delivery.describe(),
            waiting: None,
            requires: self.spec.requires.clone(),
            max_workers: self.spec.max_workers,
            after: self.spec.after.clone(),
            memory_mib: self.memory_mib,
            frame_count: self.frames.len() as u32,
            owner: self.spec.owner.clone(),
        }
    }

    /// Each frame's progress, in the shot's order.
    pub fn frame_statuses(&self) -> Vec<FrameStatus> {
        let per_frame = self.tiles.iter().map(|t| t.pixel_count()).sum::<u64>()
            * u64::from(self.schedule.last_samples());
        (0..self.frames.len())
            .map(|k| {
                let tiles = self.tiles_of(k);
                let done = self.samples_done_in(tiles.clone()).min(per_frame);
                let written = self.frames[k].written;
                FrameStatus {
                    index: k as u32,
                    scene: self.spec.frame_scene(k).unwrap_or_default().to_string(),
                    tiles_total: self.tiles.len() as u32,
                    tiles_done: tiles.filter(|&t| self.is_finished(t)).count() as u32,
                    progress: if per_frame == 0 {
                        1.0
                    } else {
                        done as f64 / per_frame as f64
                    },
                    passes_done: written,
                    samples_per_pixel_done: self.schedule.samples_after(written),
                }
            })
            .collect()
    }

    /// How many frames the job has.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Frame `frame` as far as it has come: the newest pass some tiles have finished, over
    /// the last complete one (black before any tile is back); `None` once its last pass is
    /// merged (its result file is the picture) or if there is no such frame.
    pub fn frame_so_far(&self, frame: usize) -> Option<Arc<RgbBuffer>> {
        let f = self.frames.get(frame)?;
        (!f.released).then(|| f.so_far())
    }

    /// How many passes of frame `frame` its result file holds.
    pub fn frame_passes_written(&self, frame: usize) -> u32 {
        self.frames.get(frame).map_or(0, |f| f.written)
    }

    /// Whether passes of frame `frame` are merged into its result file: it can be
    /// downloaded.
    pub fn has_result(&self, frame: usize) -> bool {
        self.frames.get(frame).is_some_and(|f| f.written > 0)
    }

    /// The next tile to lend `worker` and the pass it is to render, taken off the queue.
    /// A checked pass `worker` has rendered already waits for another worker.
    pub fn next_pending(&mut self, worker: &str) -> Option<(usize, PassRange)> {
        let verification = &self.verification;
        let t = self.lending.next(self.schedule.len(), |t, d| {
            verification.has_rendered(t, d, worker)
        })?;
        Some((t, self.schedule.range(self.lending.done[t])))
    }

    /// Whether an upload of `tile`'s pass `pass` would move the tile on (it is the pass the
    /// tile is on, and the job still has it).
    pub fn expects(&self, tile: usize, pass: u32) -> bool {
        self.lending.done[tile] == pass && (pass as usize) < self.schedule.len()
    }

    /// Whether `tile`'s pass `pass` is rendered twice and compared before it is kept.
    pub fn is_checked(&self, tile: usize, pass: u32) -> bool {
        self.verification.is_checked(tile, pass)
    }

    /// The workers whose unchecked renders `tile`'s sums hold once `worker`'s unchecked
    /// render of its next pass is kept.
    pub fn unchecked_after(&self, tile: usize, worker: &str) -> BTreeSet<String> {
        let mut chain = self.verification.unchecked_by(tile).clone();
        chain.insert(worker.to_string());
        chain
    }

    /// Judges a render of `tile`'s checked pass `pass`: held until another worker's render
    /// agrees with it (the tile goes back to the front of the queue for that). Returns the
    /// verdict, and the workers whose unchecked renders the sums hold (a checked pass adds
    /// none).
    pub fn judge(
        &mut self,
        tile: usize,
        pass: u32,
        render: Candidate,
    ) -> (Verdict, BTreeSet<String>) {
        let chain = self.verification.unchecked_by(tile).clone();
        let verdict = self.verification.judge(tile, pass, render);
        if let Verdict::Held = verdict {
            self.lending.give_back(tile);
        }
        (verdict, chain)
    }

    /// The tiles whose sums hold `worker`'s unchecked renders.
    pub fn tiles_unchecked_by(&self, worker: &str) -> Vec<usize> {
        self.verification.tiles_unchecked_by(worker)
    }

    /// Forgets the renders of checked passes `worker` gave (it was set aside).
    pub fn forget_worker(&mut self, worker: &str) {
        self.verification.forget_worker(worker);
    }

    /// Marks `tile` as lent under `lease` at `now`.
    pub fn lend(&mut self, tile: usize, lease: u64, now: Instant) {
        self.lending.lent[tile] = Some(lease);
        if self.rate.started.is_none() {
            self.rate = Rate {
                started: Some(now),
                samples_at_start: self.samples_done(),
            };
        }
    }

    /// Whether `tile` has every pass done.
    pub fn is_finished(&self, tile: usize) -> bool {
        self.lending.done[tile] as usize >= self.schedule.len()
    }

    /// `lease` ended without a result (it expired): if it still holds `tile`, the tile goes
    /// back to the front of the queue, since a job finishes sooner without stragglers.
    pub fn lease_lost(&mut self, tile: usize, lease: u64) {
        self.lending.lease_lost(tile, lease);
    }

    /// `worker`'s `lease` on `tile` expired: the tile goes back to the front of the queue.
    /// A scene that kills every renderer that takes it must fail its job with the reason
    /// instead of killing workers for ever, while workers that die of their own (a machine
    /// lost, an operator's kill) must cost no job: the two look alike one expiry at a time.
    /// So the job fails after [`MAX_TILE_ATTEMPTS`] expiries of the tile in a row while the
    /// rest of the job did nothing, or after [`MAX_TILE_EXPIRIES`] of them whatever it did
    /// (a scene that kills only on this tile). The worker is not blamed (a machine can die
    /// under any scene). A tile that holds the job up, every other tile finished or a pass
    /// ahead of it (waiting for it), once passes were done, has no rest of the job to
    /// compare with (nothing else could be done, and renderers did finish this scene's
    /// tiles): only the second limit applies to it. Returns whether the job failed.
    pub fn lease_expired(&mut self, tile: usize, lease: u64, worker: &str) -> bool {
        let Some(n) = self.lending.lease_expired(tile, lease, worker) else {
            return false;
        };
        let died = self.lending.expired_on(tile).join(", ");
        let t = self.rect(tile);
        let at = self.frame_named(tile);
        let done = &self.lending.done;
        let holds_up = self.lending.finished() > 0
            && (0..self.tile_count())
                .all(|o| o == tile || self.is_finished(o) || done[o] > done[tile]);
        let reason = if n.stalled >= MAX_TILE_ATTEMPTS && !holds_up {
            format!(
                "{} renderers in a row died, hung or lost their link rendering tile {tile} ({}x{} at {},{}{at}) while no tile of the job was done; leases of {died} expired on this pass, the last {worker}'s: a scene that crashes or hangs its renderer does this",
                n.stalled, t.width, t.height, t.x0, t.y0
            )
        } else if n.total >= MAX_TILE_EXPIRIES {
            format!(
                "{} renderers died, hung or lost their link rendering tile {tile} ({}x{} at {},{}{at}) while the rest of the job went on; leases of {died} expired on this pass, the last {worker}'s: a scene that crashes or hangs its renderer on this tile does this",
                n.total, t.width, t.height, t.x0, t.y0
            )
        } else {
            return false;
        };
        self.fail(reason)
    }

    /// An attempt at `tile` failed: the tile goes back to the front of the queue, or, after
    /// [`MAX_TILE_ATTEMPTS`], fails the job. Returns whether the job failed now.
    pub fn attempt_failed(&mut self, tile: usize, reason: &str) -> bool {
        let attempts = self.lending.attempt_failed(tile);
        self.fail_after(tile, attempts, reason)
    }

    /// Fails the job if `tile` has failed [`MAX_TILE_ATTEMPTS`] times, the last for
    /// `reason`. Returns whether it failed now.
    fn fail_after(&mut self, tile: usize, attempts: u32, reason: &str) -> bool {
        if attempts < MAX_TILE_ATTEMPTS {
            return false;
        }
        let t = self.rect(tile);
        let at = self.frame_named(tile);
        self.fail(format!(
            "tile {tile} ({}x{} at {},{}{at}) failed {MAX_TILE_ATTEMPTS} times; last: {reason}",
            t.width, t.height, t.x0, t.y0
        ))
    }

    /// `, frame K (its scene)` for a tile of a shot's frame; nothing for a job of one frame.
    fn frame_named(&self, tile: usize) -> String {
        let k = self.frame_of(tile);
        self.spec
            .frame_scene(k)
            .map(|s| format!(", frame {} ({s})", k + 1))
            .unwrap_or_default()
    }

    /// Fails the job, if it is running, for `error`. Returns whether it failed now.
    pub fn fail(&mut self, error: String) -> bool {
        if self.state != JobState::Running {
            return false;
        }
        self.state = JobState::Failed;
        self.error = Some(error);
        true
    }

    /// Where tile `idx` lies and what its pass `pass` must hold: what an upload must match.
    pub fn spot(&self, idx: usize, pass: PassRange) -> TileSpot {
        TileSpot {
            frame: self.frames[0].size(),
            window: self.rect(idx).into(),
            channels: self.frames[0].black().aovs.names.clone(),
            sums: self.schedule.sums.map(|g| (g, pass.to)),
        }
    }

    /// Which of this job's tiles have the windows `tile`: one per frame of the shot.
    pub fn find_tiles(&self, tile: &Windows) -> Vec<usize> {
        if (tile.frame_width, tile.frame_height) != self.frames[0].size() {
            return Vec::new();
        }
        let window = data_window(tile);
        let Some(t) = self.tiles.iter().position(|&r| Rect::from(r) == window) else {
            return Vec::new();
        };
        (0..self.frames.len())
            .map(|k| k * self.tiles.len() + t)
            .collect()
    }

    /// A checked tile of pass `pass` came back: pasted into that pass's frame, and the tile
    /// moves on. A pass the tile has already done (a repeated upload), or one past the
    /// job's last (it was stopped meanwhile), changes nothing.
    pub fn complete_tile(
        &mut self,
        idx: usize,
        pass: u32,
        tile: &RgbBuffer,
        unchecked_by: BTreeSet<String>,
    ) -> Result<Landed, kiln_image::ImageError> {
        let done = &self.lending.done;
        if done[idx] != pass || pass as usize >= self.schedule.len() {
            if done[idx] == pass {
                self.lending.lent[idx] = None;
            }
            return Ok(Landed::Nothing);
        }
        // A pass other tiles of the frame are past with no frame building for it (their
        // rows of it were forgotten; this tile starts again behind them) is never whole:
        // nothing to paste.
        let k = self.frame_of(idx);
        let whole_possible = self.frames[k].is_building(pass)
            || !self.tiles_of(k).any(|i| i != idx && done[i] > pass);
        let n = self.tiles.len();
        let full = whole_possible && self.frames[k].paste(pass, tile, n)?;
        self.verification.set_unchecked_by(idx, unchecked_by);
        self.lending.advance(idx, self.schedule.len());
        if !full {
            return Ok(Landed::Tile);
        }
        let frame = self.frames[k].finish(pass);
        // The frontier may have moved: the tiles waiting for it may go on.
        self.lending.release_parked();
        Ok(Landed::Pass {
            index: k as u32,
            pass,
            frame,
        })
    }

    /// A merged frame of pass `pass` could not be written (`why`, without server paths):
    /// the job waits and writes it again after `base`, doubling with each failure in a row
    /// to at most a minute. Returns the wait.
    pub fn merge_failed(&mut self, pass: u32, why: &str, now: Instant, base: Duration) -> Duration {
        self.merge_failures += 1;
        let doubling = 2u32.saturating_pow((self.merge_failures - 1).min(16));
        let wait = (base * doubling).min(Duration::from_secs(60));
        self.merge_retry = Some(now + wait);
        self.held_back.insert(
            Hold::Merge,
            format!(
                "pass {} is complete, but its merged frame could not be written ({why}): written again in {} s",
                pass + 1,
                wait.as_secs_f64()
            ),
        );
        wait
    }

    /// Whether a merged frame that could not be written is due to be written again.
    pub fn merge_due(&self, now: Instant) -> bool {
        self.state == JobState::Running && self.merge_retry.is_some_and(|at| at <= now)
    }

    /// Takes the retry: the complete passes to write again.
    pub fn take_merge_retry(&mut self) -> Vec<ToMerge> {
        self.merge_retry = None;
        self.to_merge()
    }

    /// Records that frame `frame`'s pass `pass` is merged into its result file; returns
    /// whether every frame's last pass is (the job is done). A shot's frame whose last pass
    /// is merged lets its pictures go (its result file is what it shows from then on), so a
    /// long shot does not hold every finished frame; a job of one frame keeps its picture,
    /// which an extension's next pass starts from.
    pub fn merged(&mut self, frame: usize, pass: u32) -> bool {
        if self.merge_failures > 0 {
            self.merge_failures = 0;
            self.merge_retry = None;
            self.held_back.remove(&Hold::Merge);
        }
        let passes = self.schedule.len();
        let shot = self.frames.len() > 1;
        let f = &mut self.frames[frame];
        f.merged(pass);
        if shot && f.written as usize >= passes {
            f.release();
        }
        self.passes_written() as usize >= passes
    }

    /// Whether every frame has merged pass `pass` (nothing continues from the passes
    /// before it any more).
    pub fn merged_everywhere(&self, pass: u32) -> bool {
        self.passes_written() > pass
    }

    /// Samples per pixel at the end of the last pass.
    pub fn last_samples(&self) -> u32 {
        self.schedule.last_samples()
    }

    /// Samples per pixel at the end of pass `pass`.
    pub fn samples_of_pass(&self, pass: u32) -> u32 {
        self.schedule.samples_of_pass(pass)
    }

    /// Whether every tile of frame `frame` has done pass `pass` (or a later one).
    pub fn has_complete(&self, frame: usize, pass: u32) -> bool {
        self.frames[frame].has_complete(pass)
    }

    /// Whether frame `frame`'s result file already holds pass `pass` or a later one.
    pub fn is_written(&self, frame: usize, pass: u32) -> bool {
        self.frames[frame].written > pass
    }

    /// The complete passes to merge (after a restore, or a failed write), of the frames
    /// whose result files may lack them.
    pub fn to_merge(&self) -> Vec<ToMerge> {
        self.frames
            .iter()
            .enumerate()
            .filter_map(|(k, f)| {
                let (pass, frame) = f.complete()?;
                (f.written <= pass).then_some(ToMerge {
                    index: k as u32,
                    pass,
                    frame,
                })
            })
            .collect()
    }

    /// Counts the rate afresh from the next lease (the samples done so far were done
    /// before).
    pub fn restart_rate(&mut self) {
        self.rate.started = None;
    }

    /// Ends the job after the pass its slowest tile is on. Returns whether the schedule
    /// changed (the spec is updated to say so).
    pub fn stop_after_pass(&mut self) -> bool {
        // The pass in progress ends the job; the renderer keeps the footprint of the
        // samples it was created for (see set_spec_passes), so the pass's tiles still to
        // come are rendered as those already back were.
        let f = self.lending.frontier() as usize;
        if self.state != JobState::Running || f + 1 >= self.schedule.len() {
            return false;
        }
        self.schedule.passes.truncate(f + 1);
        for frames in &mut self.frames {
            frames.stop_after(f as u32);
        }
        self.set_spec_passes();
        true
    }

    /// The spec this job would have with `more` passes after its last, or why it cannot
    /// have them.
    pub fn check_extend(&self, more: &[u32]) -> Result<JobSpec, PlanError> {
        let passes = self.schedule.extended(more, self.state, self.spec.spp)?;
        let mut spec = self.spec.clone();
        spec.passes = Some(passes);
        Ok(spec)
    }

    /// Runs a done job again (tiles of it are to be rendered again): its result no longer
    /// counts until its last pass is merged again, and its webhook is called again then.
    pub fn reopen(&mut self) {
        self.state = JobState::Running;
        self.error = None;
        self.run_again();
    }

    /// What running again after an end (a reopening or an extension) resets: the rate
    /// counts afresh, and the job's next end is announced by a webhook round of its own.
    fn run_again(&mut self) {
        self.restart_rate();
        self.webhook.run_again();
    }

    /// Adds passes beyond the last ([`Job::check_extend`] says whether it may): a done job
    /// runs again from where it ended.
    pub fn extend(&mut self, more: &[u32]) -> Result<(), PlanError> {
        self.check_extend(more)?;
        self.schedule.passes.extend_from_slice(more);
        self.set_spec_passes();
        if self.state == JobState::Done {
            self.state = JobState::Running;
        }
        self.lending.requeue(self.schedule.len());
        // It will end again: its webhook is called again then.
        self.run_again();
        Ok(())
    }

    /// Records the schedule in the spec. Its `spp` stays what the job was created with:
    /// it sets the renderer's texture footprint, which every pass of the job must share.
    fn set_spec_passes(&mut self) {
        self.spec.passes = Some(self.schedule.passes.clone());
    }
}

/// Refuses tiles of `tile` pixels that would cut a `width` x `height` render into more than
/// [`MAX_TILES`], before any is planned, saying the smallest tile that would do.
fn check_tile_count(width: u32, height: u32, tile: u32) -> Result<(), PlanError> {
    let count = |t: u32| u64::from(width.div_ceil(t)) * u64::from(height.div_ceil(t));
    let n = count(tile);
    if n <= MAX_TILES {
        return Ok(());
    }
    let least = (tile..=width.max(height).max(1))
        .find(|&t| count(t) <= MAX_TILES)
        .unwrap_or(tile);
    Err(PlanError::TooManyTiles {
        tile,
        width,
        height,
        count: n,
        max: MAX_TILES,
        least,
    })
}

/// A complete pass of one frame to merge into its result file.
pub(super) struct ToMerge {
    /// The frame's index in the shot.
    pub index: u32,
    pub pass: u32,
    pub frame: Arc<RgbBuffer>,
}

/// A tile's place: its frame's size, its window in it, the further channels it must hold
/// (the features, a G-buffer's), and the running sums it must carry (with a G-buffer's or
/// not, and after how many samples).
#[derive(Debug, Clone)]
pub(super) struct TileSpot {
    frame: (u32, u32),
    window: Rect,
    channels: Vec<String>,
    sums: Option<(SumsLayout, u32)>,
}

impl TileSpot {
    /// The number of pixels the tile holds.
    pub fn pixels(&self) -> u64 {
        u64::from(self.window.width) * u64::from(self.window.height)
    }

    /// Checks that an uploaded tile has this place's windows, further channels, finite
    /// pixels, and running sums of its pass.
    pub fn check(&self, tile: &RgbBuffer) -> Result<(), TileRejected> {
        let frame = (tile.frame_width, tile.frame_height);
        let window = data_window(&tile.windows());
        if (frame, window) != (self.frame, self.window) {
            return Err(TileRejected::Windows { frame, window });
        }
        if tile.aovs.names != self.channels {
            return Err(TileRejected::Channels {
                found: tile.aovs.names.clone(),
                expected: self.channels.clone(),
            });
        }
        if tile.pixels.iter().any(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(TileRejected::NonFinite);
        }
        if let Some((layout, samples)) = self.sums {
            let rect = kiln_render::TileRect::from(self.window);
            let words = &tile.words;
            TileSums::check_words(rect, layout, &words.names, &words.values, samples)
                .map_err(TileRejected::Sums)?;
        }
        Ok(())
    }
}

/// An image's data window.
fn data_window(b: &Windows) -> Rect {
    Rect {
        x0: b.x0,
        y0: b.y0,
        width: b.width,
        height: b.height,
    }
}
