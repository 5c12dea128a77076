//! Adaptive sampling: a pixel stops taking samples once its own estimate is good enough.
//!
//! The rule reads the pixel's running sums and nothing else, and only at fixed sample
//! counts (every power of two from `minsamples` on, where Owen-scrambled Sobol points are
//! best stratified), so whether a pixel stops, and after how many samples, is the same in
//! one go or in passes, on any tile split, thread count and machine: it is a function of
//! the pixel alone, like everything else about it.
//!
//! The error, in each of R, G and B, is the standard error of the mean of the samples'
//! filter-weighted radiance over the square root of the pixel's value (at least 1e-4):
//! noise as it shows after a display's gamma, which is close to a square root, so dark
//! pixels are not sampled for ever and bright ones are not left noisy (Cycles' noise
//! threshold measures much the same). A pixel stops when every channel's error is at most
//! the threshold: light of one colour (a blue glint in amber glass) keeps it going, where
//! its luminance would hardly show it. The samples of a Sobol sequence are not
//! independent, and their sample variance overstates the error of their mean: the rule errs
//! towards more samples. What it cannot see is light no sample has found yet: `minsamples`
//! (256 by default: on the headline frame 128 let visibly more pixels stop too dark) is the
//! guard against stopping before a rare bright path shows, and raising it is the remedy for
//! a caustic that comes out too dark.

use crate::sums::PixelSums;

/// A render's adaptive sampling: the noise a pixel may keep, and the fewest samples it
/// takes before it may stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adaptive {
    pub threshold: f32,
    pub min_samples: u32,
}

/// The luminance floor under the error's square root.
const FLOOR: f64 = 1e-4;

impl Adaptive {
    /// The scene's adaptive sampling, if it asks for it.
    pub fn of(sampler: &kiln_scene::SamplerDesc) -> Option<Adaptive> {
        sampler.noise_threshold.map(|threshold| Adaptive {
            threshold,
            min_samples: sampler.min_samples.max(1),
        })
    }

    /// Whether the rule is asked after `n` samples: at every power of two from the
    /// minimum on.
    pub fn is_checkpoint(&self, n: u32) -> bool {
        n >= self.min_samples && n.is_power_of_two()
    }

    /// Whether a pixel whose sums hold `p.taken` samples has stopped: it is at a checkpoint
    /// and every channel's error is at most the threshold.
    pub fn converged(&self, p: &PixelSums) -> bool {
        let n = p.taken;
        if !self.is_checkpoint(n) || n < 2 {
            return false;
        }
        let n = f64::from(n);
        (0..3).all(|c| {
            let mean = p.sum[c] / n;
            let variance = ((p.squares[c] - p.sum[c] * mean) / (n - 1.0)).max(0.0);
            let error = (variance / n).sqrt() / mean.max(FLOOR).sqrt();
            error <= f64::from(self.threshold)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grey pixel's sums after samples of `values` in every channel.
    fn sums(values: &[f64]) -> PixelSums {
        let sum: f64 = values.iter().sum();
        let squares: f64 = values.iter().map(|v| v * v).sum();
        PixelSums {
            taken: values.len() as u32,
            sum: [sum; 3],
            squares: [squares; 3],
            ..PixelSums::default()
        }
    }

    #[test]
    fn a_pixel_stops_only_at_a_checkpoint_past_the_minimum_and_below_the_threshold() {
        let a = Adaptive {
            threshold: 0.01,
            min_samples: 64,
        };
        assert!(!a.is_checkpoint(32) && a.is_checkpoint(64) && !a.is_checkpoint(96));
        assert!(a.is_checkpoint(128) && a.is_checkpoint(4096));
        // Black, or constant: no error.
        assert!(a.converged(&sums(&[0.0; 64])));
        assert!(a.converged(&sums(&[0.5; 128])));
        assert!(!a.converged(&sums(&[0.5; 32])), "before the minimum");
        assert!(!a.converged(&sums(&[0.5; 65])), "not a checkpoint");
        // Alternating 0 and 2: mean 1, standard deviation about 1; after 64 samples the
        // error is about 1/8, after 65536 samples 1/256.
        let alternating =
            |n: usize| sums(&(0..n).map(|i| 2.0 * (i % 2) as f64).collect::<Vec<_>>());
        assert!(!a.converged(&alternating(64)));
        let loose = Adaptive {
            threshold: 0.13,
            ..a
        };
        assert!(loose.converged(&alternating(64)));
        assert!(!a.converged(&alternating(4096)), "1/64 > 0.01");
        assert!(a.converged(&alternating(16384)), "1/128 < 0.01");
        // The error is measured against the square root of the luminance: the same
        // relative noise at a hundredth of the brightness is a tenth of the error, and
        // under the floor it shrinks with the luminance itself.
        let dim = |n: usize, scale: f64| {
            sums(
                &(0..n)
                    .map(|i| scale * 2.0 * (i % 2) as f64)
                    .collect::<Vec<_>>(),
            )
        };
        let tight = Adaptive {
            threshold: 0.02,
            ..a
        };
        assert!(!tight.converged(&dim(64, 1.0)) && tight.converged(&dim(64, 0.01)));
        let tiny = Adaptive {
            threshold: 5e-5,
            ..a
        };
        assert!(tiny.converged(&dim(64, 1e-6)), "under the floor");
        assert!(!tiny.converged(&dim(64, 1e-4)));
        // Every channel must be good enough: noise in blue alone keeps a pixel going.
        let mut blue = sums(&[0.5; 64]);
        let noisy = alternating(64);
        blue.sum[2] = noisy.sum[2];
        blue.squares[2] = noisy.squares[2];
        assert!(a.converged(&sums(&[0.5; 64])) && !a.converged(&blue));
    }
}
