//! The frames a job's finished tiles are pasted into: the last pass every tile has done,
//! the frames of the passes some tiles have finished, the black frame the first pass starts
//! from, and how many passes the result file holds.

use kiln_image::RgbBuffer;
use std::collections::BTreeMap;
use std::sync::Arc;

pub(super) struct Frames {
    /// The last pass whose every tile is done, and its frame.
    complete: Option<(u32, Arc<RgbBuffer>)>,
    /// Frames of passes some tiles have finished, by pass, with how many tiles each holds.
    /// Each starts as a copy of the newest frame there was, so it is always a whole
    /// picture. Shared, so a merge or a preview reads it after the lock is released.
    building: BTreeMap<u32, (Arc<RgbBuffer>, usize)>,
    /// A black frame with the job's channels: the first pass's starting picture.
    black: Arc<RgbBuffer>,
    /// Passes merged into the result file.
    pub written: u32,
    /// Its last pass is merged and its pictures are let go: its result file is the frame.
    pub released: bool,
}

impl Frames {
    pub fn new(black: Arc<RgbBuffer>) -> Frames {
        Frames {
            complete: None,
            building: BTreeMap::new(),
            black,
            written: 0,
            released: false,
        }
    }

    /// The frame's width and height.
    pub fn size(&self) -> (u32, u32) {
        (self.black.frame_width, self.black.frame_height)
    }

    /// The frame as far as it has come: the newest pass some tiles have finished, over the
    /// last complete one (black before any tile is back).
    pub fn so_far(&self) -> Arc<RgbBuffer> {
        if let Some((_, (frame, _))) = self.building.last_key_value() {
            return frame.clone();
        }
        self.complete
            .as_ref()
            .map_or_else(|| self.black.clone(), |(_, f)| f.clone())
    }

    /// Whether pass `pass`'s frame is being pasted together.
    pub fn is_building(&self, pass: u32) -> bool {
        self.building.contains_key(&pass)
    }

    /// Pastes `tile` into pass `pass`'s frame (started from the frame so far); returns
    /// whether that frame now holds all `tiles` tiles.
    pub fn paste(
        &mut self,
        pass: u32,
        tile: &RgbBuffer,
        tiles: usize,
    ) -> Result<bool, kiln_image::ImageError> {
        // A released frame extended by more passes starts its next from black.
        self.released = false;
        let start = self.so_far();
        let entry = self.building.entry(pass).or_insert_with(|| (start, 0));
        Arc::make_mut(&mut entry.0).paste(tile)?;
        entry.1 += 1;
        Ok(entry.1 == tiles)
    }

    /// Pass `pass`'s frame holds every tile: it is the complete one. Returns it.
    pub fn finish(&mut self, pass: u32) -> Arc<RgbBuffer> {
        let (frame, _) = self.building.remove(&pass).expect("just filled");
        self.complete = Some((pass, frame.clone()));
        frame
    }

    /// Forgets every frame (a restore pastes them again).
    pub fn clear(&mut self) {
        self.complete = None;
        self.building.clear();
        self.released = false;
    }

    /// Lets the pictures go once the last pass is in the result file (a shot of many
    /// frames would otherwise hold every finished frame in memory); what the frame looks
    /// like is read from that file from then on.
    pub fn release(&mut self) {
        self.building.clear();
        if let Some((pass, _)) = self.complete {
            self.complete = Some((pass, self.black.clone()));
        }
        self.released = true;
    }

    /// The black frame a restore starts pasting from.
    pub fn black(&self) -> Arc<RgbBuffer> {
        self.black.clone()
    }

    /// Restored: pass `pass`'s frame, complete or holding `count` tiles.
    pub fn restored(&mut self, pass: u32, frame: Arc<RgbBuffer>, count: Option<usize>) {
        match count {
            None => self.complete = Some((pass, frame)),
            Some(count) => {
                self.building.insert(pass, (frame, count));
            }
        }
    }

    /// Forgets the frames of passes after `last` (the job stops after it).
    pub fn stop_after(&mut self, last: u32) {
        self.building.retain(|&p, _| p <= last);
    }

    /// Records that pass `pass` is merged into the result file.
    pub fn merged(&mut self, pass: u32) {
        self.written = self.written.max(pass + 1);
    }

    /// Whether every tile has done pass `pass` (or a later one).
    pub fn has_complete(&self, pass: u32) -> bool {
        self.complete.as_ref().is_some_and(|(p, _)| *p >= pass)
    }

    /// The last complete pass and its frame.
    pub fn complete(&self) -> Option<(u32, Arc<RgbBuffer>)> {
        self.complete.clone()
    }

    /// Takes the result file to hold the last complete pass (a job that ended had it
    /// merged before it ended).
    pub fn written_as_complete(&mut self) {
        self.written = self.complete.as_ref().map_or(0, |(p, _)| p + 1);
    }
}
