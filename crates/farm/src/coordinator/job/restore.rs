//! Restoring a job from the tile passes the store kept: on resume, and after a worker whose
//! unchecked renders some tiles held was set aside (those tiles' rows were dropped).

use super::super::store::KeptTile;
use super::Job;
use crate::api::JobState;
use kiln_image::RgbBuffer;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

/// Per tile, its readable rows by pass: the tile and whose unchecked renders its sums hold.
type Rows = Vec<BTreeMap<u32, (RgbBuffer, BTreeSet<String>)>>;

impl Job {
    /// Restores the tiles kept in the store (on resume, or after a worker was set aside and
    /// its tiles' rows were dropped). Each tile resumes after the last pass it has a
    /// readable row for (one that cannot be read, or is not this job's, does not count),
    /// and the frames are pasted together again from the rows of the passes in progress.
    pub fn restore(&mut self, rows: Vec<KeptTile>) {
        for frames in &mut self.frames {
            frames.clear();
        }
        let mut kept = self.readable(rows);
        // Each tile resumes after its last row; rows below a gap are of no use (nothing
        // continues from them), and a tile whose last row cannot be pasted starts again.
        for (idx, rows) in kept.iter_mut().enumerate() {
            let Some(last) = rows.keys().next_back().copied() else {
                self.lending.done[idx] = 0;
                continue;
            };
            let mut first = last;
            while first > 0 && rows.contains_key(&(first - 1)) {
                first -= 1;
            }
            rows.retain(|&p, _| p >= first);
            self.lending.done[idx] = last + 1;
        }
        for k in 0..self.frames.len() {
            self.paste_restored(&kept, k);
        }
        for (idx, rows) in kept.iter_mut().enumerate() {
            let last = self.lending.done[idx].checked_sub(1);
            let by = last
                .and_then(|p| rows.remove(&p))
                .map(|(_, by)| by)
                .unwrap_or_default();
            self.verification.set_unchecked_by(idx, by);
        }
        self.lending.reset(self.schedule.len());
        // A job that ended had its last complete pass merged before it ended; a running
        // one is merged again on resume, which records it.
        if self.state != JobState::Running {
            for frames in &mut self.frames {
                frames.written_as_complete();
            }
        }
    }

    /// The rows that are this job's and can be read and pasted, by tile and pass. A tile
    /// kept before passes existed marks the job as such.
    fn readable(&mut self, rows: Vec<KeptTile>) -> Rows {
        let n = self.tile_count();
        let mut kept: Rows = vec![BTreeMap::new(); n];
        for row in rows {
            let idx = row.idx;
            if idx >= n {
                continue;
            }
            let Some(pass) = self.schedule.passes.iter().position(|&p| p == row.samples) else {
                continue;
            };
            let Ok(tile) = kiln_image::decode_exr(&row.exr) else {
                continue;
            };
            let mut range = self.schedule.range(pass as u32);
            range.to = row.samples;
            let mut spot = self.spot(idx, range);
            if row.legacy {
                // Its pixels are the tile's; it has no sums to continue, so the job
                // cannot be extended (check_extend says so).
                spot.sums = None;
                self.schedule.legacy = true;
            }
            if spot.check(&tile).is_ok() {
                kept[idx].insert(pass as u32, (tile, row.unchecked_by));
            }
        }
        kept
    }

    /// Frame `frame`'s pictures of the passes from its slowest tile's on, pasted from the
    /// rows. A pass some tile is past without a row for it (the store forgot it once a
    /// later pass was merged, and the tiles that start again after a worker was set aside
    /// are behind it) is never whole, and never merged: the next merged pass is the first
    /// that every tile of the frame reaches with its row.
    fn paste_restored(&mut self, kept: &Rows, frame: usize) {
        let tiles = self.tiles_of(frame);
        let n = tiles.len();
        let done = &self.lending.done[tiles.clone()];
        let kept = &kept[tiles];
        let frontier = done.iter().copied().min().unwrap_or(0);
        let newest = done.iter().copied().max().unwrap_or(0);
        let frames = &mut self.frames[frame];
        let mut picture = frames.black();
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
            let past = (0..n).filter(|&i| done[i] > pass).count();
            if count == n {
                frames.restored(pass, picture.clone(), None);
            } else if count == past {
                frames.restored(pass, picture.clone(), Some(count));
            }
        }
    }

    /// Restores the job from `rows` after some of its tiles' rows were dropped (a worker
    /// whose renders were in them was set aside). The result file may hold those renders:
    /// it no longer counts until the next pass is merged.
    pub fn rebuild(&mut self, rows: Vec<KeptTile>, tiles: &[usize]) {
        for &t in tiles {
            self.verification.forget_tile(t);
        }
        self.restore(rows);
        for frames in &mut self.frames {
            frames.written = 0;
        }
    }
}
