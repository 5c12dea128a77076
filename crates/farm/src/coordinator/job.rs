//! One job in memory: its tiles and what became of each (pending, lent, done), the queue of
//! tiles to lend next, attempts and failures, the frame the finished tiles are pasted into,
//! and the progress it reports.
//!
//! Bookkeeping only: it reads the scene once to plan the tiles, and otherwise must never do
//! I/O, touch the store or the leases, or read a clock (callers pass `now`).

use super::MAX_TILE_ATTEMPTS;
use super::error::{PlanError, TileRejected};
use crate::api::{JobSpec, JobState, JobStatus, Rect};
use crate::bundle;
use kiln_image::{RgbBuffer, Windows};
use kiln_render::{TileRect, split_into_tiles};
use std::collections::VecDeque;
use std::path::Path;
use std::sync::Arc;
use tokio::time::Instant;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TileState {
    Pending,
    Leased(u64),
    Done,
}

pub(super) struct Job {
    pub id: u64,
    pub spec: JobSpec,
    pub state: JobState,
    pub error: Option<String>,
    pub tiles: Vec<TileRect>,
    tile_state: Vec<TileState>,
    /// Tiles to lend next, in order; a tile may appear here after it stopped being
    /// pending (lending checks), so lending never scans the whole job.
    queue: VecDeque<usize>,
    attempts: Vec<u32>,
    failures: u32,
    done: u32,
    /// The finished tiles pasted together. Shared, so a merge or a preview can read it
    /// after the lock is released (a paste during a preview copies it first).
    pub frame: Arc<RgbBuffer>,
    spp: u32,
    started: Instant,
    samples_at_start: u64,
    pub merge_seconds: Option<f64>,
}

impl Job {
    /// Loads the job's scene (unpacked under `scenes`) to learn its frame and tiles. Parser
    /// errors name files relative to the bundle, not the data directory.
    pub fn plan(
        scenes: &Path,
        id: u64,
        spec: JobSpec,
        state: JobState,
        now: Instant,
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
        let f = &desc.film;
        let [x0, x1, y0, y1] = f.pixel_bounds;
        let frame = RgbBuffer::new(f.xresolution, f.yresolution, x0, y0, x1 - x0, y1 - y0)
            .with_aovs(kiln_render::aov_names(f.gbuffer));
        let tiles = split_into_tiles(f.pixel_bounds, spec.tile);
        let n = tiles.len();
        Ok(Job {
            id,
            spec,
            state,
            error: None,
            tiles,
            tile_state: vec![TileState::Pending; n],
            queue: (0..n).collect(),
            attempts: vec![0; n],
            failures: 0,
            done: 0,
            frame: Arc::new(frame),
            spp: desc.sampler.pixel_samples,
            started: now,
            samples_at_start: 0,
            merge_seconds: None,
        })
    }

    /// A job that cannot be planned again at a restart (its record or its scene bundle is
    /// damaged or gone): kept in the list with the reason, with no tiles. One that was
    /// still running has failed; a finished one keeps its state (its frame is a file).
    pub fn damaged(
        id: u64,
        spec: Option<JobSpec>,
        state: JobState,
        reason: String,
        now: Instant,
    ) -> Job {
        let spec = spec.unwrap_or(JobSpec {
            scene: String::new(),
            spp: None,
            resolution: None,
            tile: 1,
            seed: None,
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
            tile_state: Vec::new(),
            queue: VecDeque::new(),
            attempts: Vec::new(),
            failures: 0,
            done: 0,
            frame: Arc::new(RgbBuffer::new(0, 0, 0, 0, 0, 0)),
            spp: 0,
            started: now,
            samples_at_start: 0,
            merge_seconds: None,
        }
    }

    fn samples_of(&self, i: usize) -> u64 {
        self.tiles[i].pixel_count() * self.spp as u64
    }

    fn samples_done(&self) -> u64 {
        (0..self.tiles.len())
            .filter(|&i| self.tile_state[i] == TileState::Done)
            .map(|i| self.samples_of(i))
            .sum()
    }

    /// Progress as the API reports it; the rate counts samples since the job started or
    /// the coordinator resumed it.
    pub fn status(&self, now: Instant) -> JobStatus {
        let samples_total: u64 = (0..self.tiles.len()).map(|i| self.samples_of(i)).sum();
        let samples_done = self.samples_done();
        let secs = now
            .saturating_duration_since(self.started)
            .as_secs_f64()
            .max(1e-3);
        let rate = samples_done.saturating_sub(self.samples_at_start) as f64 / secs;
        let progress = if samples_total == 0 {
            1.0
        } else {
            samples_done as f64 / samples_total as f64
        };
        JobStatus {
            id: self.id,
            state: self.state,
            width: self.frame.frame_width,
            height: self.frame.frame_height,
            tiles_total: self.tiles.len() as u32,
            tiles_done: self.done,
            samples_total,
            samples_done,
            progress,
            samples_per_second: rate,
            eta_seconds: (rate > 0.0 && self.state == JobState::Running)
                .then(|| (samples_total - samples_done) as f64 / rate),
            failures: self.failures,
            error: self.error.clone(),
            merge_seconds: self.merge_seconds,
        }
    }

    /// Whether every tile is done.
    pub fn is_complete(&self) -> bool {
        self.done as usize == self.tiles.len()
    }

    /// Whether the job is running with every tile done: its frame is ready to be written.
    pub fn is_ready_to_merge(&self) -> bool {
        self.state == JobState::Running && self.is_complete()
    }

    /// The next pending tile to lend, taken off the queue.
    pub fn next_pending(&mut self) -> Option<usize> {
        while let Some(t) = self.queue.pop_front() {
            if self.tile_state[t] == TileState::Pending {
                return Some(t);
            }
        }
        None
    }

    /// Marks `tile` as lent under `lease`.
    pub fn lend(&mut self, tile: usize, lease: u64) {
        self.tile_state[tile] = TileState::Leased(lease);
    }

    /// Whether `tile` is done.
    pub fn is_done(&self, tile: usize) -> bool {
        self.tile_state[tile] == TileState::Done
    }

    /// `lease` ended without a result (it expired): if it still holds `tile`, the tile goes
    /// back to the front of the queue, since a job finishes sooner without stragglers.
    pub fn lease_lost(&mut self, tile: usize, lease: u64) {
        if self.tile_state[tile] == TileState::Leased(lease) {
            self.tile_state[tile] = TileState::Pending;
            self.queue.push_front(tile);
        }
    }

    /// An attempt at `tile` failed: the tile goes back to the front of the queue, or, after
    /// [`MAX_TILE_ATTEMPTS`], fails the job. Returns whether the job failed now.
    pub fn attempt_failed(&mut self, tile: usize, reason: &str) -> bool {
        self.failures += 1;
        self.attempts[tile] += 1;
        self.tile_state[tile] = TileState::Pending;
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

    /// Where tile `idx` lies: what an upload of it must match.
    pub fn spot(&self, idx: usize) -> TileSpot {
        TileSpot {
            frame: (self.frame.frame_width, self.frame.frame_height),
            window: self.tiles[idx].into(),
        }
    }

    /// Which of this job's tiles has the windows `tile`.
    pub fn find_tile(&self, tile: &Windows) -> Option<usize> {
        if (tile.frame_width, tile.frame_height)
            != (self.frame.frame_width, self.frame.frame_height)
        {
            return None;
        }
        let window = data_window(tile);
        self.tiles.iter().position(|&r| Rect::from(r) == window)
    }

    /// Pastes a checked tile into the frame and marks it done. Returns whether it was
    /// newly done (a tile already done keeps the pixels it has).
    pub fn complete_tile(
        &mut self,
        idx: usize,
        tile: &RgbBuffer,
    ) -> Result<bool, kiln_image::ImageError> {
        if self.tile_state[idx] == TileState::Done {
            return Ok(false);
        }
        Arc::make_mut(&mut self.frame).paste(tile)?;
        self.tile_state[idx] = TileState::Done;
        self.done += 1;
        Ok(true)
    }

    /// Restores a tile kept in the store (on resume). A tile that cannot be read back, or
    /// is not this job's, stays pending and is rendered again.
    pub fn restore_tile(&mut self, idx: usize, exr: &[u8]) {
        if idx >= self.tiles.len() {
            return;
        }
        let Ok(tile) = kiln_image::decode_exr(exr) else {
            return;
        };
        if self.spot(idx).check(&tile).is_ok() {
            let _ = self.complete_tile(idx, &tile);
        }
    }

    /// Starts counting the rate from here (the tiles done so far were done before).
    pub fn restart_rate(&mut self, now: Instant) {
        self.samples_at_start = self.samples_done();
        self.started = now;
    }
}

/// A tile's place: its frame's size and its window in it.
#[derive(Debug, Clone, Copy)]
pub(super) struct TileSpot {
    frame: (u32, u32),
    window: Rect,
}

impl TileSpot {
    /// The number of pixels the tile holds.
    pub fn pixels(&self) -> u64 {
        u64::from(self.window.width) * u64::from(self.window.height)
    }

    /// Checks that an uploaded tile has this place's windows and finite pixels.
    pub fn check(&self, tile: &RgbBuffer) -> Result<(), TileRejected> {
        let frame = (tile.frame_width, tile.frame_height);
        let window = data_window(&tile.windows());
        if (frame, window) != (self.frame, self.window) {
            return Err(TileRejected::Windows { frame, window });
        }
        if tile.pixels.iter().any(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(TileRejected::NonFinite);
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
