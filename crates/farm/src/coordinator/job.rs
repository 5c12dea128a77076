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
//! Bookkeeping only: it reads the scene once to plan the tiles, and otherwise must never do
//! I/O, touch the store or the leases, or read a clock (callers pass `now`).

use super::MAX_TILE_ATTEMPTS;
use super::error::{PlanError, TileRejected};
use super::store::KeptTile;
use super::verify::{Candidate, Checks, Verdict, is_checked};
use super::webhooks::Delivery;
use crate::api::{JobSpec, JobState, JobStatus, PassRange, Rect};
use crate::bundle;
use kiln_image::{RgbBuffer, Windows};
use kiln_render::{SumsLayout, TileRect, TileSums, split_into_tiles};
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::Path;
use std::sync::Arc;
use tokio::time::Instant;

/// The most passes a job may have.
pub const MAX_PASSES: usize = 64;

pub(super) struct Job {
    pub id: u64,
    pub spec: JobSpec,
    pub state: JobState,
    pub error: Option<String>,
    pub tiles: Vec<TileRect>,
    /// Cumulative samples per pixel at the end of each pass, ascending.
    passes: Vec<u32>,
    /// Whether tiles carry running sums (every integrator but SPPM), and what those hold
    /// (G-buffer sums, adaptive sampling's): None for SPPM.
    sums: Option<SumsLayout>,
    /// Per tile: how many passes it has done.
    done: Vec<u32>,
    /// Per tile: the lease rendering its next pass.
    lent: Vec<Option<u64>>,
    /// Tiles whose next pass may be lent, in order; a tile may sit here after it stopped
    /// being lendable (lending checks), so lending never scans the whole job.
    queue: VecDeque<usize>,
    /// Tiles two passes ahead of the slowest, waiting for it.
    parked: Vec<usize>,
    /// Failed attempts at each tile's current pass.
    attempts: Vec<u32>,
    failures: u32,
    /// The last pass whose every tile is done, and its frame.
    complete: Option<(u32, Arc<RgbBuffer>)>,
    /// Frames of passes some tiles have finished, by pass, with how many tiles each holds.
    /// Each starts as a copy of the newest frame there was, so it is always a whole
    /// picture. Shared, so a merge or a preview reads it after the lock is released.
    building: BTreeMap<u32, (Arc<RgbBuffer>, usize)>,
    /// A black frame with the job's channels: the first pass's starting picture.
    black: Arc<RgbBuffer>,
    /// Passes merged into the result file.
    written: u32,
    /// The fraction of tile passes rendered twice and compared, and those renders waiting
    /// for a second.
    verify: f64,
    checks: Checks,
    /// Per tile: the workers whose renders, not compared with another's, its sums hold.
    unchecked_by: Vec<BTreeSet<String>>,
    /// Tile passes kept after two workers agreed on them.
    pub verified: u64,
    /// The id of the last lease this job granted (0 for none): jobs of equal priority
    /// take turns by it.
    pub last_lent: u64,
    /// Where the job's webhook call stands.
    pub webhook: Delivery,
    /// How often the job was made to run again after it ended (extended, or reopened):
    /// a call announcing an earlier end must not count for the next.
    pub webhook_round: u64,
    /// Whether tiles kept before passes existed (without running sums) are in its frame.
    legacy: bool,
    /// When the rate is counted from: the first lease after the job was created, resumed
    /// or extended (time spent queued behind other jobs is not rendering), and the samples
    /// done by then.
    started: Option<Instant>,
    samples_at_start: u64,
    /// Why a job renders tiles again (a worker whose unchecked renders its sums held was
    /// set aside), for the status.
    pub notice: Option<String>,
    pub merge_seconds: Option<f64>,
}

/// What a tile's upload did to its job.
#[derive(Debug)]
pub(super) enum Landed {
    /// It was a pass the job already had (a repeated upload): nothing changed.
    Nothing,
    /// The tile moved on by a pass.
    Tile,
    /// It was the last tile of pass `pass`: the frame at that pass is complete.
    Pass { pass: u32, frame: Arc<RgbBuffer> },
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
        let scene = bundle::cached_scene(scenes, &spec.scene)
            .ok_or_else(|| PlanError::NoScene(spec.scene.clone()))?;
        let root = scenes.join(&spec.scene);
        let mut desc = kiln_scene::load_file_within(&scene, &root)
            .map_err(|e| PlanError::Scene(bundle::relative_message(&e, &root)))?;
        desc.apply_overrides(&spec.overrides())
            .map_err(PlanError::Overrides)?;
        desc.check_frame_size(max_frame_pixels)
            .map_err(PlanError::Overrides)?;
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
        let frame = RgbBuffer::new(f.xresolution, f.yresolution, x0, y0, x1 - x0, y1 - y0)
            .with_aovs(kiln_render::aov_names(f.gbuffer));
        let tiles = split_into_tiles(f.pixel_bounds, spec.tile);
        let n = tiles.len();
        let verify = spec.verify.unwrap_or(0.0);
        if !(0.0..=1.0).contains(&verify) {
            return Err(PlanError::Verify(verify));
        }
        Ok(Job {
            id,
            spec,
            state,
            error: None,
            tiles,
            passes,
            sums: (!sppm)
                .then(|| kiln_render::RenderSettings::from_description(&desc).sums_layout()),
            done: vec![0; n],
            lent: vec![None; n],
            queue: (0..n).collect(),
            parked: Vec::new(),
            attempts: vec![0; n],
            failures: 0,
            complete: None,
            building: BTreeMap::new(),
            black: Arc::new(frame),
            written: 0,
            verify,
            checks: Checks::default(),
            unchecked_by: vec![BTreeSet::new(); n],
            verified: 0,
            last_lent: 0,
            webhook: Delivery::Waiting,
            webhook_round: 0,
            legacy: false,
            started: None,
            samples_at_start: 0,
            notice: None,
            merge_seconds: None,
        })
    }

    /// A job that cannot be planned again at a restart (its record or its scene bundle is
    /// damaged or gone): kept in the list with the reason, with no tiles. One that was
    /// still running has failed; a finished one keeps its state (its frame is a file).
    pub fn damaged(id: u64, spec: Option<JobSpec>, state: JobState, reason: String) -> Job {
        let spec = spec.unwrap_or(JobSpec {
            scene: String::new(),
            spp: None,
            resolution: None,
            tile: 1,
            seed: None,
            passes: None,
            verify: None,
            priority: 0,
            webhook: None,
        });
        let state = if state == JobState::Running {
            JobState::Failed
        } else {
            state
        };
        Job {
            id,
            spec,
            state,
            error: Some(reason),
            tiles: Vec::new(),
            passes: Vec::new(),
            sums: None,
            done: Vec::new(),
            lent: Vec::new(),
            queue: VecDeque::new(),
            parked: Vec::new(),
            attempts: Vec::new(),
            failures: 0,
            complete: None,
            building: BTreeMap::new(),
            black: Arc::new(RgbBuffer::new(0, 0, 0, 0, 0, 0)),
            written: 0,
            verify: 0.0,
            checks: Checks::default(),
            unchecked_by: Vec::new(),
            verified: 0,
            last_lent: 0,
            webhook: Delivery::Waiting,
            webhook_round: 0,
            legacy: false,
            started: None,
            samples_at_start: 0,
            notice: None,
            merge_seconds: None,
        }
    }

    /// The pass the slowest tile is on: every tile has done this many passes.
    fn frontier(&self) -> u32 {
        self.done.iter().copied().min().unwrap_or(0)
    }

    /// Samples per pixel after `done` passes.
    fn samples_after(&self, done: u32) -> u32 {
        match done {
            0 => 0,
            d => self.passes[(d as usize - 1).min(self.passes.len() - 1)],
        }
    }

    fn samples_done(&self) -> u64 {
        (0..self.tiles.len())
            .map(|i| self.tiles[i].pixel_count() * u64::from(self.samples_after(self.done[i])))
            .sum()
    }

    /// Progress as the API reports it; the rate counts samples since the job's first lease
    /// after it was created, the coordinator resumed it, or it was extended.
    pub fn status(&self, now: Instant) -> JobStatus {
        let last = self.passes.last().copied().unwrap_or(0);
        let samples_total: u64 =
            self.tiles.iter().map(|t| t.pixel_count()).sum::<u64>() * u64::from(last);
        let samples_done = self.samples_done().min(samples_total);
        let rate = self.started.map_or(0.0, |started| {
            let secs = now.saturating_duration_since(started).as_secs_f64();
            let samples = samples_done.saturating_sub(self.samples_at_start) as f64;
            // Until a second has passed the figure says little; none is better.
            if secs < 1.0 { 0.0 } else { samples / secs }
        });
        let progress = if samples_total == 0 {
            1.0
        } else {
            samples_done as f64 / samples_total as f64
        };
        let finished = self
            .done
            .iter()
            .filter(|&&d| d as usize >= self.passes.len())
            .count();
        JobStatus {
            id: self.id,
            state: self.state,
            width: self.black.frame_width,
            height: self.black.frame_height,
            tiles_total: self.tiles.len() as u32,
            tiles_done: finished as u32,
            samples_total,
            samples_done,
            progress,
            samples_per_second: rate,
            eta_seconds: (rate > 0.0 && self.state == JobState::Running)
                .then(|| (samples_total - samples_done) as f64 / rate),
            failures: self.failures,
            error: self.error.clone(),
            merge_seconds: self.merge_seconds,
            passes: self.passes.clone(),
            passes_done: self.written,
            samples_per_pixel_done: self.samples_after(self.written),
            tile_passes_verified: self.verified,
            tile_passes_held: self.checks.held() as u32,
            notice: self.notice.clone(),
            priority: self.spec.priority,
            webhook: self.webhook.describe(),
        }
    }

    /// The frame as far as it has come: the newest pass some tiles have finished, over the
    /// last complete one (black before any tile is back).
    pub fn frame_so_far(&self) -> Arc<RgbBuffer> {
        if let Some((_, (frame, _))) = self.building.last_key_value() {
            return frame.clone();
        }
        self.complete
            .as_ref()
            .map_or_else(|| self.black.clone(), |(_, f)| f.clone())
    }

    /// Whether passes are merged into the result file: a result can be downloaded.
    pub fn has_result(&self) -> bool {
        self.written > 0
    }

    /// The next tile to lend `worker` and the pass it is to render, taken off the queue.
    /// A checked pass `worker` has rendered already waits for another worker.
    pub fn next_pending(&mut self, worker: &str) -> Option<(usize, PassRange)> {
        let frontier = self.frontier();
        let mut not_for_this_one = Vec::new();
        let found = loop {
            let Some(t) = self.queue.pop_front() else {
                break None;
            };
            let d = self.done[t];
            if self.lent[t].is_some() || d as usize >= self.passes.len() {
                continue;
            }
            if d > frontier + 1 {
                self.parked.push(t);
                continue;
            }
            if self.checks.has_rendered(t, d, worker) {
                not_for_this_one.push(t);
                continue;
            }
            break Some(t);
        };
        for t in not_for_this_one.into_iter().rev() {
            self.queue.push_front(t);
        }
        let t = found?;
        let d = self.done[t];
        Some((
            t,
            PassRange {
                index: d,
                from: self.samples_after(d),
                to: self.passes[d as usize],
            },
        ))
    }

    /// Whether an upload of `tile`'s pass `pass` would move the tile on (it is the pass the
    /// tile is on, and the job still has it).
    pub fn expects(&self, tile: usize, pass: u32) -> bool {
        self.done[tile] == pass && (pass as usize) < self.passes.len()
    }

    /// Whether `tile`'s pass `pass` is rendered twice and compared before it is kept.
    pub fn is_checked(&self, tile: usize, pass: u32) -> bool {
        is_checked(self.verify, tile, pass)
    }

    /// The workers whose unchecked renders `tile`'s sums hold once `worker`'s unchecked
    /// render of its next pass is kept.
    pub fn unchecked_after(&self, tile: usize, worker: &str) -> BTreeSet<String> {
        let mut chain = self.unchecked_by[tile].clone();
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
        let chain = self.unchecked_by[tile].clone();
        let verdict = self.checks.judge(tile, pass, render);
        match &verdict {
            Verdict::Keep { .. } => self.verified += 1,
            Verdict::Held => {
                self.lent[tile] = None;
                self.queue.push_front(tile);
            }
            Verdict::Chaos => {}
        }
        (verdict, chain)
    }

    /// The tiles whose sums hold `worker`'s unchecked renders.
    pub fn tiles_unchecked_by(&self, worker: &str) -> Vec<usize> {
        (0..self.tiles.len())
            .filter(|&t| self.unchecked_by[t].contains(worker))
            .collect()
    }

    /// Forgets the renders of checked passes `worker` gave (it was set aside).
    pub fn forget_worker(&mut self, worker: &str) {
        self.checks.forget_worker(worker);
    }

    /// Marks `tile` as lent under `lease` at `now`.
    pub fn lend(&mut self, tile: usize, lease: u64, now: Instant) {
        self.lent[tile] = Some(lease);
        if self.started.is_none() {
            self.started = Some(now);
            self.samples_at_start = self.samples_done();
        }
    }

    /// Whether `tile` has every pass done.
    pub fn is_finished(&self, tile: usize) -> bool {
        self.done[tile] as usize >= self.passes.len()
    }

    /// `lease` ended without a result (it expired): if it still holds `tile`, the tile goes
    /// back to the front of the queue, since a job finishes sooner without stragglers.
    pub fn lease_lost(&mut self, tile: usize, lease: u64) {
        if self.lent[tile] == Some(lease) {
            self.lent[tile] = None;
            self.queue.push_front(tile);
        }
    }

    /// An attempt at `tile` failed: the tile goes back to the front of the queue, or, after
    /// [`MAX_TILE_ATTEMPTS`], fails the job. Returns whether the job failed now.
    pub fn attempt_failed(&mut self, tile: usize, reason: &str) -> bool {
        self.failures += 1;
        self.attempts[tile] += 1;
        self.lent[tile] = None;
        self.queue.push_front(tile);
        if self.attempts[tile] >= MAX_TILE_ATTEMPTS && self.state == JobState::Running {
            self.state = JobState::Failed;
            let t = self.tiles[tile];
            self.error = Some(format!(
                "tile {tile} ({}x{} at {},{}) failed {MAX_TILE_ATTEMPTS} times; last: {reason}",
                t.width, t.height, t.x0, t.y0
            ));
            return true;
        }
        false
    }

    /// Where tile `idx` lies and what its pass `pass` must hold: what an upload must match.
    pub fn spot(&self, idx: usize, pass: PassRange) -> TileSpot {
        TileSpot {
            frame: (self.black.frame_width, self.black.frame_height),
            window: self.tiles[idx].into(),
            sums: self.sums.map(|g| (g, pass.to)),
        }
    }

    /// Which of this job's tiles has the windows `tile`.
    pub fn find_tile(&self, tile: &Windows) -> Option<usize> {
        if (tile.frame_width, tile.frame_height)
            != (self.black.frame_width, self.black.frame_height)
        {
            return None;
        }
        let window = data_window(tile);
        self.tiles.iter().position(|&r| Rect::from(r) == window)
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
        if self.done[idx] != pass || pass as usize >= self.passes.len() {
            if self.done[idx] == pass {
                self.lent[idx] = None;
            }
            return Ok(Landed::Nothing);
        }
        // A pass other tiles are past with no frame building for it (their rows of it were
        // forgotten; this tile starts again behind them) is never whole: nothing to paste.
        let whole_possible = self.building.contains_key(&pass)
            || !self
                .done
                .iter()
                .enumerate()
                .any(|(i, &d)| i != idx && d > pass);
        let full = if whole_possible {
            let start = self.frame_so_far();
            let entry = self.building.entry(pass).or_insert_with(|| (start, 0));
            Arc::make_mut(&mut entry.0).paste(tile)?;
            entry.1 += 1;
            entry.1 == self.tiles.len()
        } else {
            false
        };
        self.unchecked_by[idx] = unchecked_by;
        self.done[idx] += 1;
        self.attempts[idx] = 0;
        self.lent[idx] = None;
        if !self.is_finished(idx) {
            self.queue.push_back(idx);
        }
        if !full {
            return Ok(Landed::Tile);
        }
        let (frame, _) = self.building.remove(&pass).expect("just filled");
        self.complete = Some((pass, frame.clone()));
        // The frontier moved: the tiles waiting for it may go on.
        self.queue.extend(self.parked.drain(..));
        Ok(Landed::Pass { pass, frame })
    }

    /// Records that pass `pass` is merged into the result file; returns whether it was the
    /// last pass (the job is done).
    pub fn merged(&mut self, pass: u32) -> bool {
        self.written = self.written.max(pass + 1);
        self.written as usize >= self.passes.len()
    }

    /// Samples per pixel at the end of the last pass.
    pub fn last_samples(&self) -> u32 {
        self.passes.last().copied().unwrap_or(0)
    }

    /// Samples per pixel at the end of pass `pass`.
    pub fn samples_of_pass(&self, pass: u32) -> u32 {
        self.passes[(pass as usize).min(self.passes.len() - 1)]
    }

    /// Whether every tile has done pass `pass` (or a later one).
    pub fn has_complete(&self, pass: u32) -> bool {
        self.complete.as_ref().is_some_and(|(p, _)| *p >= pass)
    }

    /// Whether the result file already holds pass `pass` or a later one.
    pub fn is_written(&self, pass: u32) -> bool {
        self.written > pass
    }

    /// Restores the tiles kept in the store (on resume, or after a worker was set aside and
    /// its tiles' rows were dropped). Each tile resumes after the last pass it has a
    /// readable row for (one that cannot be read, or is not this job's, does not count),
    /// and the frames are pasted together again from the rows of the passes in progress.
    pub fn restore(&mut self, rows: Vec<KeptTile>) {
        let n = self.tiles.len();
        self.complete = None;
        self.building.clear();
        let mut kept: Vec<BTreeMap<u32, (RgbBuffer, BTreeSet<String>)>> = vec![BTreeMap::new(); n];
        for row in rows {
            let idx = row.idx;
            if idx >= n {
                continue;
            }
            let Some(pass) = self.passes.iter().position(|&p| p == row.samples) else {
                continue;
            };
            let Ok(tile) = kiln_image::decode_exr(&row.exr) else {
                continue;
            };
            let range = PassRange {
                index: pass as u32,
                from: self.samples_after(pass as u32),
                to: row.samples,
            };
            let mut spot = self.spot(idx, range);
            if row.legacy {
                // Its pixels are the tile's; it has no sums to continue, so the job
                // cannot be extended (check_extend says so).
                spot.sums = None;
                self.legacy = true;
            }
            if spot.check(&tile).is_ok() {
                kept[idx].insert(pass as u32, (tile, row.unchecked_by));
            }
        }
        // Each tile resumes after its last row; rows below a gap are of no use (nothing
        // continues from them), and a tile whose last row cannot be pasted starts again.
        for (idx, rows) in kept.iter_mut().enumerate() {
            let Some(last) = rows.keys().next_back().copied() else {
                self.done[idx] = 0;
                continue;
            };
            let mut first = last;
            while first > 0 && rows.contains_key(&(first - 1)) {
                first -= 1;
            }
            rows.retain(|&p, _| p >= first);
            self.done[idx] = last + 1;
        }
        // The frames of the passes from the slowest tile's on are pasted from the rows. A
        // pass some tile is past without a row for it (the store forgot it once a later pass
        // was merged, and the tiles that start again after a worker was set aside are
        // behind it) is never whole, and never merged: the next merged pass is the first
        // that every tile reaches with its row.
        let frontier = self.frontier();
        let newest = self.done.iter().copied().max().unwrap_or(0);
        let mut picture = self.black.clone();
        for pass in frontier.saturating_sub(1)..newest {
            let with_row: Vec<usize> = (0..n).filter(|&i| kept[i].contains_key(&pass)).collect();
            if with_row.is_empty() {
                continue;
            }
            let mut frame = (*picture).clone();
            let mut count = 0;
            for idx in with_row {
                if let Some((tile, _)) = kept[idx].get(&pass)
                    && frame.paste(tile).is_ok()
                {
                    count += 1;
                }
            }
            picture = Arc::new(frame);
            let past = (0..n).filter(|&i| self.done[i] > pass).count();
            if count == n {
                self.complete = Some((pass, picture.clone()));
            } else if count == past {
                self.building.insert(pass, (picture.clone(), count));
            }
        }
        for (idx, rows) in kept.iter_mut().enumerate() {
            let last = self.done[idx].checked_sub(1);
            self.unchecked_by[idx] = last
                .and_then(|p| rows.remove(&p))
                .map(|(_, by)| by)
                .unwrap_or_default();
        }
        self.queue = (0..n).filter(|&i| !self.is_finished(i)).collect();
        self.parked.clear();
        self.lent = vec![None; n];
        // A job that ended had its last complete pass merged before it ended; a running
        // one is merged again on resume, which records it.
        if self.state != JobState::Running {
            self.written = self.complete.as_ref().map_or(0, |(p, _)| p + 1);
        }
    }

    /// Restores the job from `rows` after some of its tiles' rows were dropped (a worker
    /// whose renders were in them was set aside). The result file may hold those renders:
    /// it no longer counts until the next pass is merged.
    pub fn rebuild(&mut self, rows: Vec<KeptTile>, tiles: &[usize]) {
        for &t in tiles {
            self.checks.forget_tile(t);
        }
        self.restore(rows);
        self.written = 0;
    }

    /// The complete pass to merge after a restore, if the result file may lack it.
    pub fn to_merge(&self) -> Option<(u32, Arc<RgbBuffer>)> {
        self.complete.clone()
    }

    /// Counts the rate afresh from the next lease (the samples done so far were done
    /// before).
    pub fn restart_rate(&mut self) {
        self.started = None;
    }

    /// Ends the job after the pass its slowest tile is on. Returns whether the schedule
    /// changed (the spec is updated to say so).
    pub fn stop_after_pass(&mut self) -> bool {
        // The pass in progress ends the job; the renderer keeps the footprint of the
        // samples it was created for (see set_spec_passes), so the pass's tiles still to
        // come are rendered as those already back were.
        let f = self.frontier() as usize;
        if self.state != JobState::Running || f + 1 >= self.passes.len() {
            return false;
        }
        self.passes.truncate(f + 1);
        self.building.retain(|&p, _| (p as usize) <= f);
        self.set_spec_passes();
        true
    }

    /// The spec this job would have with `more` passes after its last, or why it cannot
    /// have them.
    pub fn check_extend(&self, more: &[u32]) -> Result<JobSpec, PlanError> {
        let Some(last) = self.passes.last().copied() else {
            return Err(PlanError::Passes("this job has no tiles to extend".into()));
        };
        if self.legacy {
            return Err(PlanError::Passes(
                "this job was rendered before passes existed: its tiles keep no running sums to continue; submit a new job".into(),
            ));
        }
        if self.sums.is_none() {
            return Err(PlanError::Passes(
                "an SPPM job cannot be extended: its photon radius shrinks over all its iterations together".into(),
            ));
        }
        if !matches!(self.state, JobState::Running | JobState::Done) {
            return Err(PlanError::Passes(format!(
                "a {} job cannot be extended",
                self.state.as_str()
            )));
        }
        check_passes(more, last)?;
        let new_last = *more.last().expect("checked: not empty");
        // The renderer's footprint is the one the job was created with (its pinned spp).
        let planned = self.spec.spp.unwrap_or(last);
        if kiln_render::texture_footprint(planned) != kiln_render::texture_footprint(new_last) {
            return Err(PlanError::Passes(format!(
                "a job created for {planned} samples per pixel cannot be extended to {new_last}: textures are filtered over a footprint that shrinks with the total up to 64 samples (as pbrt-v4 does), so its samples would not be those of a {new_last}-sample render; submit a new job"
            )));
        }
        if self.passes.len() + more.len() > MAX_PASSES {
            return Err(PlanError::Passes(format!(
                "a job has at most {MAX_PASSES} passes"
            )));
        }
        let mut spec = self.spec.clone();
        spec.passes = Some(self.passes.iter().chain(more).copied().collect());
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
        self.webhook = Delivery::Waiting;
        self.webhook_round += 1;
    }

    /// Adds passes beyond the last ([`Job::check_extend`] says whether it may): a done job
    /// runs again from where it ended.
    pub fn extend(&mut self, more: &[u32]) -> Result<(), PlanError> {
        self.check_extend(more)?;
        self.passes.extend_from_slice(more);
        self.set_spec_passes();
        if self.state == JobState::Done {
            self.state = JobState::Running;
        }
        self.queue = (0..self.tiles.len())
            .filter(|&i| !self.is_finished(i) && self.lent[i].is_none())
            .collect();
        // It will end again: its webhook is called again then.
        self.run_again();
        Ok(())
    }

    /// Records the schedule in the spec. Its `spp` stays what the job was created with:
    /// it sets the renderer's texture footprint, which every pass of the job must share.
    fn set_spec_passes(&mut self) {
        self.spec.passes = Some(self.passes.clone());
    }
}

/// Checks a schedule of cumulative sample counts: 1 to [`MAX_PASSES`] of them, ascending,
/// the first above `after`.
fn check_passes(passes: &[u32], after: u32) -> Result<(), PlanError> {
    if passes.is_empty() || passes.len() > MAX_PASSES {
        return Err(PlanError::Passes(format!(
            "give 1 to {MAX_PASSES} passes, not {}",
            passes.len()
        )));
    }
    let mut prev = after;
    for &p in passes {
        if p <= prev {
            return Err(PlanError::Passes(format!(
                "passes are cumulative samples per pixel, each above the one before (and above {after}): {passes:?}"
            )));
        }
        prev = p;
    }
    Ok(())
}

/// A tile's place: its frame's size, its window in it, and the running sums it must carry
/// (with a G-buffer's or not, and after how many samples).
#[derive(Debug, Clone, Copy)]
pub(super) struct TileSpot {
    frame: (u32, u32),
    window: Rect,
    sums: Option<(SumsLayout, u32)>,
}

impl TileSpot {
    /// The number of pixels the tile holds.
    pub fn pixels(&self) -> u64 {
        u64::from(self.window.width) * u64::from(self.window.height)
    }

    /// Checks that an uploaded tile has this place's windows, finite pixels, and running
    /// sums of its pass.
    pub fn check(&self, tile: &RgbBuffer) -> Result<(), TileRejected> {
        let frame = (tile.frame_width, tile.frame_height);
        let window = data_window(&tile.windows());
        if (frame, window) != (self.frame, self.window) {
            return Err(TileRejected::Windows { frame, window });
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
