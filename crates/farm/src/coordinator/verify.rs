//! Verified workers: a job may have a fraction of its tile passes rendered twice, on two
//! different workers, and compared bit for bit before either is kept.
//!
//! A tile pass is a pure function of (scene, settings, tile, pass), so two honest workers
//! give the same bits and any difference proves one of them wrong. Which one, a third
//! worker's render decides: the render two workers agree on is kept, and the workers whose
//! renders differ from it are set aside with the reason (the coordinator then renders again
//! what they rendered unchecked). Which passes are checked is a function of the tile and
//! the pass alone, so it is the same at every restart.
//!
//! Plain state, like `job/`: no I/O, no clock, no lock.

use kiln_image::RgbBuffer;
use std::collections::{BTreeSet, HashMap};

/// The most renders of one tile pass kept while no two agree; past it, the attempt fails.
pub const MAX_CANDIDATES: usize = 4;

/// Whether tile `tile`'s pass `pass` is rendered twice, for a job verifying `fraction` of
/// its tile passes.
pub fn is_checked(fraction: f64, tile: usize, pass: u32) -> bool {
    if fraction <= 0.0 {
        return false;
    }
    // SplitMix64 of (tile, pass): uniform in [0, 1), the same on every machine.
    let mut z = ((tile as u64) << 32 | u64::from(pass)).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    ((z >> 11) as f64 / (1u64 << 53) as f64) < fraction
}

/// Whether two renders of a tile are the same bits: pixels, further channels and running
/// sums (float comparison would take 0 and -0 as equal, and a NaN as unequal to itself).
pub fn same_bits(a: &RgbBuffer, b: &RgbBuffer) -> bool {
    a.windows() == b.windows()
        && a.pixels.len() == b.pixels.len()
        && a.pixels
            .iter()
            .zip(&b.pixels)
            .all(|(p, q)| p.map(f32::to_bits) == q.map(f32::to_bits))
        && a.aovs.names == b.aovs.names
        && a.aovs.values.len() == b.aovs.values.len()
        && a.aovs
            .values
            .iter()
            .zip(&b.aovs.values)
            .all(|(p, q)| p.to_bits() == q.to_bits())
        && a.words == b.words
}

/// One worker's render of a tile pass, held until another agrees with it.
#[derive(Debug, Clone)]
pub(super) struct Candidate {
    pub worker: String,
    pub exr: Vec<u8>,
    pub tile: RgbBuffer,
}

/// What to do with a render of a checked tile pass.
#[derive(Debug)]
pub(super) enum Verdict {
    /// Keep this render, which `agreeing` workers gave; set `wrong` aside.
    Keep {
        render: Box<Candidate>,
        agreeing: Vec<String>,
        wrong: Vec<String>,
    },
    /// Held until another worker renders the same pass.
    Held,
    /// No two of [`MAX_CANDIDATES`] renders agree: the attempt fails, and those renders are
    /// dropped.
    Chaos,
}

/// The renders of checked tile passes not confirmed yet, by tile.
#[derive(Debug, Default)]
pub(super) struct Checks {
    pending: HashMap<usize, (u32, Vec<Candidate>)>,
}

impl Checks {
    /// Whether `worker` has rendered tile `tile`'s pass `pass` already (it must not be lent
    /// the same pass again: its second render would agree with its first).
    pub fn has_rendered(&self, tile: usize, pass: u32, worker: &str) -> bool {
        self.pending
            .get(&tile)
            .is_some_and(|(p, c)| *p == pass && c.iter().any(|c| c.worker == worker))
    }

    /// Judges a render of tile `tile`'s pass `pass`.
    pub fn judge(&mut self, tile: usize, pass: u32, render: Candidate) -> Verdict {
        let entry = self.pending.entry(tile).or_insert((pass, Vec::new()));
        if entry.0 != pass {
            *entry = (pass, Vec::new());
        }
        let candidates = &mut entry.1;
        if candidates.iter().any(|c| c.worker == render.worker) {
            return Verdict::Held;
        }
        if let Some(i) = candidates
            .iter()
            .position(|c| same_bits(&c.tile, &render.tile))
        {
            let (_, mut all) = self.pending.remove(&tile).expect("found above");
            let first = all.remove(i);
            let wrong = all.into_iter().map(|c| c.worker).collect();
            return Verdict::Keep {
                agreeing: vec![first.worker, render.worker.clone()],
                render: Box::new(render),
                wrong,
            };
        }
        candidates.push(render);
        if candidates.len() >= MAX_CANDIDATES {
            self.pending.remove(&tile);
            return Verdict::Chaos;
        }
        Verdict::Held
    }

    /// How many tile passes have renders waiting for a second worker's.
    pub fn held(&self) -> usize {
        self.pending.len()
    }

    /// Forgets every render `worker` gave (it was set aside).
    pub fn forget_worker(&mut self, worker: &str) {
        for (_, c) in self.pending.values_mut() {
            c.retain(|c| c.worker != worker);
        }
        self.pending.retain(|_, (_, c)| !c.is_empty());
    }

    /// Forgets the renders of `tile` (it starts again).
    pub fn forget_tile(&mut self, tile: usize) {
        self.pending.remove(&tile);
    }
}

/// A job's verification: the fraction of its tile passes rendered twice, the renders held
/// until a second agrees, whose unchecked renders each tile's sums hold, and how many tile
/// passes were kept after two workers agreed.
#[derive(Debug, Default)]
pub(super) struct Verification {
    fraction: f64,
    checks: Checks,
    /// Per tile: the workers whose renders, not compared with another's, its sums hold.
    unchecked_by: Vec<BTreeSet<String>>,
    /// Tile passes kept after two workers agreed on them.
    pub verified: u64,
}

impl Verification {
    /// Checks `fraction` of the tile passes of a job of `tiles` tiles.
    pub fn new(fraction: f64, tiles: usize) -> Verification {
        Verification {
            fraction,
            checks: Checks::default(),
            unchecked_by: vec![BTreeSet::new(); tiles],
            verified: 0,
        }
    }

    /// Whether `tile`'s pass `pass` is rendered twice and compared before it is kept.
    pub fn is_checked(&self, tile: usize, pass: u32) -> bool {
        is_checked(self.fraction, tile, pass)
    }

    /// Whether `worker` rendered `tile`'s checked pass `pass` already.
    pub fn has_rendered(&self, tile: usize, pass: u32, worker: &str) -> bool {
        self.checks.has_rendered(tile, pass, worker)
    }

    /// The workers whose unchecked renders `tile`'s sums hold.
    pub fn unchecked_by(&self, tile: usize) -> &BTreeSet<String> {
        &self.unchecked_by[tile]
    }

    /// Records whose unchecked renders `tile`'s sums now hold.
    pub fn set_unchecked_by(&mut self, tile: usize, workers: BTreeSet<String>) {
        self.unchecked_by[tile] = workers;
    }

    /// Judges a render of `tile`'s checked pass `pass` (counting a pass kept).
    pub fn judge(&mut self, tile: usize, pass: u32, render: Candidate) -> Verdict {
        let verdict = self.checks.judge(tile, pass, render);
        if let Verdict::Keep { .. } = verdict {
            self.verified += 1;
        }
        verdict
    }

    /// The tiles whose sums hold `worker`'s unchecked renders.
    pub fn tiles_unchecked_by(&self, worker: &str) -> Vec<usize> {
        (0..self.unchecked_by.len())
            .filter(|&t| self.unchecked_by[t].contains(worker))
            .collect()
    }

    /// Forgets the renders of checked passes `worker` gave (it was set aside).
    pub fn forget_worker(&mut self, worker: &str) {
        self.checks.forget_worker(worker);
    }

    /// Forgets the renders held for `tile` (it starts again).
    pub fn forget_tile(&mut self, tile: usize) {
        self.checks.forget_tile(tile);
    }

    /// How many tile passes have renders waiting for a second worker's.
    pub fn held(&self) -> usize {
        self.checks.held()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn render(worker: &str, v: f32) -> Candidate {
        let mut tile = RgbBuffer::new(4, 4, 0, 0, 2, 2);
        tile.pixels.iter_mut().for_each(|p| *p = [v; 3]);
        Candidate {
            worker: worker.into(),
            exr: Vec::new(),
            tile,
        }
    }

    #[test]
    fn the_checked_fraction_is_what_was_asked() {
        for fraction in [0.0, 0.1, 0.5, 1.0] {
            let n = (0..20_000)
                .filter(|&t| is_checked(fraction, t, (t % 7) as u32))
                .count();
            assert!(
                (n as f64 / 20_000.0 - fraction).abs() < 0.01,
                "{fraction}: {n}"
            );
        }
    }

    #[test]
    fn two_agreeing_workers_decide_and_the_odd_one_is_wrong() {
        let mut checks = Checks::default();
        assert!(matches!(
            checks.judge(0, 1, render("a", 1.0)),
            Verdict::Held
        ));
        assert!(checks.has_rendered(0, 1, "a") && !checks.has_rendered(0, 1, "b"));
        // The same worker again proves nothing.
        assert!(matches!(
            checks.judge(0, 1, render("a", 1.0)),
            Verdict::Held
        ));
        assert!(matches!(
            checks.judge(0, 1, render("b", 2.0)),
            Verdict::Held
        ));
        match checks.judge(0, 1, render("c", 2.0)) {
            Verdict::Keep {
                render,
                agreeing,
                wrong,
            } => {
                assert_eq!(render.tile.pixels[0], [2.0; 3]);
                assert_eq!(agreeing, ["b", "c"]);
                assert_eq!(wrong, ["a"]);
            }
            v => panic!("{v:?}"),
        }
        assert!(!checks.has_rendered(0, 1, "a"), "decided: forgotten");
        // A difference of one bit is a difference; -0 is not 0.
        assert!(matches!(
            checks.judge(1, 0, render("a", 0.0)),
            Verdict::Held
        ));
        assert!(matches!(
            checks.judge(1, 0, render("b", -0.0)),
            Verdict::Held
        ));
        assert!(matches!(
            checks.judge(1, 0, render("c", 1.0)),
            Verdict::Held
        ));
        assert!(matches!(
            checks.judge(1, 0, render("d", 3.0)),
            Verdict::Chaos
        ));
    }
}
