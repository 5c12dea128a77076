//! Adaptive sampling: a pixel stops taking samples once its own estimate is good enough.
//!
//! The rule reads the pixel's running sums and nothing else, and only at fixed sample
//! counts (every power of two from `minsamples` on, where Owen-scrambled Sobol points are
//! best stratified), so whether a pixel stops, and after how many samples, is the same in
//! one go or in passes, on any tile split, thread count and machine: it is a function of
//! the pixel alone, like everything else about it.
//!
//! The error is the standard error of the mean of the samples' luminance over the square
//! root of the pixel's luminance (at least 1e-4): noise as it shows after a display's
//! gamma, which is close to a square root, so dark pixels are not sampled for ever and
//! bright ones are not left noisy. (Cycles' noise threshold measures much the same.) The
//! samples of a Sobol sequence are not independent, and their sample variance overstates
//! the error of their mean: the rule errs towards more samples. What it cannot see is
//! light no sample has found yet: `minsamples` is the guard against stopping before a rare
//! bright path shows, and raising it is the remedy for a caustic that comes out too dark.

use crate::math::Color;
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
    /// and its error is at most the threshold.
    pub fn converged(&self, p: &PixelSums) -> bool {
        let n = p.taken;
        if !self.is_checkpoint(n) || n < 2 {
            return false;
        }
        let n = f64::from(n);
        let mean = p.lum / n;
        let variance = ((p.lum2 - p.lum * mean) / (n - 1.0)).max(0.0);
        let error = (variance / n).sqrt() / mean.max(FLOOR).sqrt();
        error <= f64::from(self.threshold)
    }
}

/// A sample's luminance (Rec. 709, the sRGB primaries' Y) times its filter weight: what the
/// rule's sums add up.
pub fn sample_luminance(l: Color, w: f32) -> f64 {
    let y = 0.2126 * f64::from(l.x) + 0.7152 * f64::from(l.y) + 0.0722 * f64::from(l.z);
    y * f64::from(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums(values: &[f64]) -> PixelSums {
        PixelSums {
            taken: values.len() as u32,
            lum: values.iter().sum(),
            lum2: values.iter().map(|v| v * v).sum(),
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
    }
}
