//! Kiln's deterministic sampler.
//!
//! Every sample value is a pure function of (seed, pixel, sample index,
//! dimension): an Owen-scrambled Sobol sequence (Burley 2020, through the
//! `sobol_burley` crate) whose scramble seed is a hash of the pixel and the
//! render seed. Nothing depends on tiles, threads or the order pixels are
//! rendered in, which is what makes tiles independent and images bit-identical
//! however a frame is split.

use super::sobol::SobolPoint;
use glam::Vec2;

/// The most samples per pixel the Sobol sequence supports.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 16;

/// Sobol dimensions available before dimensions are folded into the seed.
const SOBOL_DIMENSIONS: u32 = sobol_burley::NUM_DIMENSIONS;

/// A 32-bit finaliser (from MurmurHash3) to decorrelate structured inputs.
fn mix32(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^= h >> 16;
    h
}

/// The sampler's scramble seed for one pixel.
pub fn pixel_seed(x: u32, y: u32, seed: u32) -> u32 {
    mix32(mix32(mix32(x ^ 0x5bd1_e995).wrapping_add(y) ^ 0x27d4_eb2f).wrapping_add(seed))
}

/// Samples for one pixel sample; dimensions are consumed in order.
#[derive(Debug, Clone)]
pub struct PixelSampler {
    seed: u32,
    index: u32,
    /// The index shuffled by `seed`, for the dimensions before the first fold.
    point: SobolPoint,
    dimension: u32,
    /// The last four-dimension set computed (dimensions 4k..4k+3), since Sobol
    /// dimensions are cheapest four at a time (SIMD) and paths use them in order.
    cached_set: u32,
    cached: [f32; 4],
}

impl PixelSampler {
    pub fn new(x: u32, y: u32, sample_index: u32, seed: u32) -> PixelSampler {
        debug_assert!(sample_index < MAX_SAMPLES_PER_PIXEL);
        let seed = pixel_seed(x, y, seed);
        PixelSampler {
            seed,
            index: sample_index,
            point: SobolPoint::new(sample_index, seed),
            dimension: 0,
            cached_set: u32::MAX,
            cached: [0.0; 4],
        }
    }

    /// Jumps to a fixed dimension, so that each bounce uses the same dimensions in every path.
    pub fn set_dimension(&mut self, dimension: u32) {
        self.dimension = dimension;
    }

    pub fn dimension(&self) -> u32 {
        self.dimension
    }

    /// Past the table's dimensions, a new scramble seed gives an independent sequence.
    fn seed_for(&self, dimension: u32) -> u32 {
        let fold = dimension / SOBOL_DIMENSIONS;
        if fold == 0 {
            self.seed
        } else {
            mix32(self.seed ^ mix32(fold))
        }
    }

    /// The value of one dimension, without advancing.
    pub fn value(&self, dimension: u32) -> f32 {
        sobol_burley::sample(
            self.index,
            dimension % SOBOL_DIMENSIONS,
            self.seed_for(dimension),
        )
    }

    pub fn get_1d(&mut self) -> f32 {
        let d = self.dimension;
        let set = d / 4;
        if set != self.cached_set {
            // sobol_burley::sample_4d (which SobolPoint equals) equals four calls of
            // sample(), bit for bit.
            let table_set = (d % SOBOL_DIMENSIONS) / 4;
            self.cached = if d < SOBOL_DIMENSIONS {
                self.point.set(table_set)
            } else {
                SobolPoint::new(self.index, self.seed_for(d)).set(table_set)
            };
            self.cached_set = set;
        }
        self.dimension += 1;
        self.cached[(d % 4) as usize]
    }

    pub fn get_2d(&mut self) -> Vec2 {
        let a = self.get_1d();
        let b = self.get_1d();
        Vec2::new(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pbrt-v4's ConsistentValues: the same (pixel, index, dimension) gives the
    /// same value whatever was asked before and in whatever order.
    #[test]
    fn consistent_values_in_any_order() {
        let mut forward = Vec::new();
        for y in 0..3 {
            for x in 0..3 {
                for i in 0..16 {
                    let mut s = PixelSampler::new(x, y, i, 7);
                    let v: Vec<f32> = (0..300).map(|_| s.get_1d()).collect();
                    forward.push(((x, y, i), v));
                }
            }
        }
        for ((x, y, i), v) in forward.iter().rev() {
            let s = PixelSampler::new(*x, *y, *i, 7);
            for d in (0..300).rev() {
                assert_eq!(s.value(d).to_bits(), v[d as usize].to_bits());
            }
        }
    }

    /// The four-at-a-time path that paths use gives exactly what one dimension at a time gives.
    #[test]
    fn cached_sets_equal_single_dimensions() {
        for i in 0..8 {
            let mut s = PixelSampler::new(9, 8, i, 5);
            for d in [0u32, 3, 4, 5, 13, 250, 255, 256, 257, 600] {
                s.set_dimension(d);
                assert_eq!(s.get_1d().to_bits(), s.value(d).to_bits(), "dimension {d}");
            }
        }
    }

    #[test]
    fn values_are_in_unit_interval_and_seed_matters() {
        let a = PixelSampler::new(1, 2, 3, 0).value(5);
        let b = PixelSampler::new(1, 2, 3, 1).value(5);
        assert_ne!(a, b);
        for d in 0..600 {
            let v = PixelSampler::new(4, 5, 6, 0).value(d);
            assert!((0.0..1.0).contains(&v));
        }
    }

    /// Stratification: the first 2^k samples of a 2D pair fill every cell of a 2^k grid
    /// in one dimension (an elementary interval property of (0,2)-sequences).
    #[test]
    fn first_dimensions_are_stratified() {
        let n = 64;
        let mut seen = vec![false; n];
        for i in 0..n as u32 {
            let v = PixelSampler::new(10, 20, i, 3).value(0);
            seen[(v * n as f32) as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
    }

    /// Error at equal samples: estimating the integral of a smooth 2D function,
    /// Sobol's error must be far below independent random sampling's.
    #[test]
    fn converges_faster_than_random() {
        let f = |x: f32, y: f32| libm::sinf(x * y * 3.0) + x * x;
        let exact = {
            let n = 2000;
            let mut s = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    s += f((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32) as f64;
                }
            }
            s / (n * n) as f64
        };
        let mut sobol_err = 0.0;
        let mut random_err = 0.0;
        let spp = 256;
        for p in 0..64u32 {
            let mut s = 0.0f64;
            let mut r = 0.0f64;
            for i in 0..spp {
                let smp = PixelSampler::new(p, 0, i, 0);
                s += f(smp.value(0), smp.value(1)) as f64;
                let h1 = mix32(p.wrapping_mul(7919) ^ mix32(i)) as f32 / u32::MAX as f32;
                let h2 = mix32(h1.to_bits() ^ 0x1234_5678) as f32 / u32::MAX as f32;
                r += f(h1, h2) as f64;
            }
            sobol_err += (s / spp as f64 - exact).powi(2);
            random_err += (r / spp as f64 - exact).powi(2);
        }
        assert!(
            sobol_err * 10.0 < random_err,
            "sobol {sobol_err} random {random_err}"
        );
    }
}
