//! A row of pixels rendered as waves of paths: each stage of the path tracer (the closest
//! hits, the segment and its vertex, the shadow rays) runs over every live path of the wave
//! before the next stage starts, rather than one path running from the camera to its end
//! before the next begins.
//!
//! A row renders in rounds: its pixels times a range of samples, at most [`WAVE`] paths, or
//! one sample of each pixel of a row wider than that (every sample of a round is one path
//! of its wave). Rounds end at adaptive sampling's
//! checkpoints, so a pixel's decision to go on is taken on all the samples before it, as
//! one path at a time takes it. Paths end in any order; when the last has, the round is
//! folded into each pixel's sums in sample order ([`accumulate`]), and into statistics
//! kept per pixel and merged in pixel order, so the sums and the statistics are the same
//! bytes as one path at a time gives, for any wave size.

use super::sample::{Taken, accumulate, camera_sample};
use super::{Renderer, SampleId, TileStats};
use crate::integrators::Path;
use crate::shapes::ClosestHit;
use crate::sums::PixelSums;
use kiln_scene::GBufferSpace;
use std::ops::Range;

/// The most paths a round holds, unless its row is wider (a round takes at least one sample
/// of every pixel that goes on, and whole samples: fewer than this where the row's width
/// does not divide it). Measured on the Cornell box (2026-11-28, `benches/cornell.rs`
/// against one path at a time, CPU time): 128 paths 1.04x, 256 1.06x, 512 1.00x, 1024
/// 1.04x, each within the machine's 5% noise; past 1024 a wave's paths (0.7 KB each, with
/// their hits and samples about 1.2 KB) outgrow the second-level cache.
pub(super) const WAVE: usize = 512;

/// A wave's room: its size, and the buffers its rounds reuse for their paths and samples
/// (each of a tile's row jobs renders row after row in the same room, so those pages stay
/// mapped: allocating them every round cost 3.6% in page faults on a medium scene).
pub(super) struct Wave {
    size: usize,
    /// The round's samples, in the order they are folded.
    taken: Vec<Taken>,
    paths: Vec<Path>,
    /// The sample each path is of (a sample whose lens stopped its ray has none).
    sample_of: Vec<usize>,
    /// The paths still going, and for each its closest hit and whether it goes on.
    live: Vec<usize>,
    found: Vec<Option<ClosestHit>>,
    goes_on: Vec<bool>,
}

impl Wave {
    /// A room for rounds of at most `size` paths (at least one).
    pub fn new(size: usize) -> Wave {
        Wave {
            size: size.max(1),
            taken: Vec::new(),
            paths: Vec::new(),
            sample_of: Vec::new(),
            live: Vec::new(),
            found: Vec::new(),
            goes_on: Vec::new(),
        }
    }
}

/// Adds `samples` to the running sums of the row of pixels at `x0..`, `y` (one sum a
/// pixel, in `sums`), with statistics into `stats`: as many paths at a time as `wave`
/// allows. With adaptive sampling a pixel stops at the first checkpoint where its own sums
/// say it is good enough; a pixel that stopped before (it took fewer samples than
/// `samples` starts from) takes none. None as soon as `stop` says yes (asked between
/// rounds).
#[allow(clippy::too_many_arguments)]
pub(super) fn add_row_samples(
    renderer: &Renderer,
    wave: &mut Wave,
    (x0, y): (u32, u32),
    sums: &mut [PixelSums],
    samples: Range<u32>,
    gbuffer: Option<GBufferSpace>,
    stats: &mut TileStats,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<()> {
    let adaptive = renderer.settings.adaptive;
    let per_pixel = (wave.size / sums.len().max(1)).clamp(1, u32::MAX as usize) as u32;
    let mut pixel_stats = vec![TileStats::default(); sums.len()];
    let mut s0 = samples.start;
    if stop() {
        return None;
    }
    while s0 < samples.end {
        let mut s1 = samples.end.min(s0.saturating_add(per_pixel));
        if let Some(a) = adaptive {
            // No checkpoint strictly inside a round.
            s1 = (s0 + 1..s1).find(|&n| a.is_checkpoint(n)).unwrap_or(s1);
        }
        let taking: Vec<usize> = (0..sums.len())
            .filter(|&i| {
                let p = &sums[i];
                p.taken >= s0 && !adaptive.is_some_and(|a| a.converged(p))
            })
            .collect();
        if taking.is_empty() {
            // Every pixel has stopped, and a stopped pixel takes no more samples.
            break;
        }
        let ids = taking.iter().flat_map(|&i| {
            (s0..s1).map(move |sample| SampleId {
                x: x0 + i as u32,
                y,
                sample,
            })
        });
        wave.trace(renderer, ids, gbuffer.is_some());
        let mut round = wave.taken.iter();
        for &i in &taking {
            for s in s0..s1 {
                let taken = round.next().expect("one result a sample");
                let sample = taken.take(renderer, gbuffer, &mut pixel_stats[i]);
                accumulate(&mut sums[i], s, sample, gbuffer.is_some());
            }
        }
        s0 = s1;
        if s0 < samples.end && stop() {
            return None;
        }
    }
    for s in &pixel_stats {
        stats.merge(s);
    }
    Some(())
}

impl Wave {
    /// Traces the paths of camera samples `ids` as one wave: every stage over all the live
    /// paths in turn, until every path has ended. Its samples, in the order of `ids`, are
    /// left in `self.taken`.
    fn trace(&mut self, renderer: &Renderer, ids: impl Iterator<Item = SampleId>, visible: bool) {
        let tracer = renderer.path_tracer();
        let geometry = &renderer.scene.geometry;
        let Wave {
            taken,
            paths,
            sample_of,
            live,
            found,
            goes_on,
            ..
        } = self;
        taken.clear();
        paths.clear();
        sample_of.clear();
        for id in ids {
            let c = camera_sample(renderer, id.x, id.y, id.sample);
            if let Some((ray, _)) = c.shot.ray {
                sample_of.push(taken.len());
                paths.push(tracer.start(ray, c.sampler, c.shot.waves, visible));
            }
            taken.push(Taken {
                id,
                shot: c.shot,
                path: None,
            });
        }
        live.clear();
        live.extend(0..paths.len());
        while !live.is_empty() {
            // The closest hits of every live path's ray.
            found.clear();
            found.extend(
                live.iter()
                    .map(|&i| geometry.closest_hit(paths[i].ray(), f32::INFINITY)),
            );
            // Each path's segment and vertex (the hit's record made there, while the path
            // is at hand), its light sample waiting on its shadow ray.
            goes_on.clear();
            goes_on.extend(live.iter().zip(found.iter()).map(|(&i, &hit)| {
                let path = &mut paths[i];
                let hit = hit.and_then(|h| geometry.record(path.ray(), f32::INFINITY, h));
                tracer.advance(path, hit)
            }));
            // The shadow rays.
            for &i in live.iter() {
                if paths[i].waits_on_shadow() {
                    tracer.shadow(&mut paths[i]);
                }
            }
            // The paths that ended leave the wave.
            let mut k = 0;
            live.retain(|&i| {
                let on = goes_on[k];
                k += 1;
                if !on {
                    taken[sample_of[i]].path = Some(paths[i].outcome());
                }
                on
            });
        }
    }
}
