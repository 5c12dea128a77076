//! A tile's running sums: each pixel's filter-weighted radiance and weight (and, with a
//! G-buffer film, its G-buffer sums) after its first `samples` samples, kept bit for bit.
//!
//! This is what lets a render be done in passes with the same bytes as in one go. A pixel is
//! always accumulated the same way, one sample after the other in sample order from zero
//! (`sum += l * w` in f64); a pass continues the sums where the last one stopped, so the
//! sums after N samples are the same bits whether they were reached in one pass or in many,
//! and so is the pixel made from them. Between passes the sums travel as 32-bit words
//! (an f64 as its low and high halves), which any image format with integer channels holds
//! exactly. Each pixel also keeps the sums of its samples' squares (its variance, which
//! the denoiser reads and adaptive sampling's stopping goes by, [`crate::adaptive`]) and
//! its feature sums ([`crate::features`]); with adaptive sampling, how many samples it took.

use crate::features::FeatureSums;
use crate::gbuffer::GBufferPixel;
use crate::rect::TileRect;

/// One pixel's running sums.
#[derive(Debug, Clone, Default)]
pub struct PixelSums {
    /// Filter-weighted radiance, in sample order.
    pub sum: [f64; 3],
    pub weight: f64,
    /// With a G-buffer film, its sums; unused otherwise.
    pub gbuffer: GBufferPixel,
    /// The samples the pixel took: its tile's count, or fewer if adaptive sampling
    /// stopped it.
    pub taken: u32,
    /// The sums of the squares of the samples' filter-weighted radiance, by channel.
    pub squares: [f64; 3],
    /// The denoiser's features.
    pub features: FeatureSums,
}

/// What a tile's running sums hold besides radiance, weight, squares and features: a
/// G-buffer's sums, and adaptive sampling's counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SumsLayout {
    pub gbuffer: bool,
    pub adaptive: bool,
}

impl PixelSums {
    /// The variance of the pixel's value (its weighted mean) by channel: with n samples of
    /// weighted radiance v (sum S, sum of squares Q) and weights summing to W, the samples'
    /// variance (Q - S^2/n)/(n - 1), times n over W^2 (zero under two samples).
    pub fn value_variance(&self) -> [f32; 3] {
        let n = self.taken as f64;
        if n < 2.0 || self.weight == 0.0 {
            return [0.0; 3];
        }
        std::array::from_fn(|c| {
            let spread = ((self.squares[c] - self.sum[c] * self.sum[c] / n) / (n - 1.0)).max(0.0);
            (spread * n / (self.weight * self.weight)) as f32
        })
    }

    /// The pixel's value: the weighted mean (black where no sample had weight).
    pub fn value(&self) -> [f32; 3] {
        if self.weight == 0.0 {
            return [0.0; 3];
        }
        self.sum.map(|v| (v / self.weight) as f32)
    }
}

/// A tile's running sums after `samples` samples of every pixel (or fewer, where adaptive
/// sampling stopped a pixel).
#[derive(Debug, Clone)]
pub struct TileSums {
    pub rect: TileRect,
    /// How many samples of each pixel the sums hold.
    pub samples: u32,
    /// What they hold.
    pub layout: SumsLayout,
    /// Row-major, `rect.width * rect.height`.
    pub pixels: Vec<PixelSums>,
}

/// Why words could not be read back as a tile's sums.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SumsError {
    #[error("the running sums have channels {found:?}, not the {expected} this render keeps")]
    Channels { found: Vec<String>, expected: usize },
    #[error("the running sums hold {found} values, not {expected} for a {width}x{height} tile")]
    Size {
        found: usize,
        expected: usize,
        width: u32,
        height: u32,
    },
    #[error("the running sums' pixels disagree on how many samples they hold")]
    Samples,
    #[error("the tile's running sums hold {found} samples, not the {expected} of its pass")]
    SampleCount { found: u32, expected: u32 },
    #[error("a pixel's running sums say it took {taken} samples, more than the tile's {samples}")]
    Taken { taken: u32, samples: u32 },
}

/// The name of the channel holding the sample count, of the one holding the samples each
/// pixel took (with adaptive sampling), the prefix of the feature sums' and of the others.
const SAMPLES_WORD: &str = "kiln.sums.samples";
const FEATURE_PREFIX: &str = "kiln.sums.features.";
const TAKEN_WORD: &str = "kiln.sums.taken";
const WORD_PREFIX: &str = "kiln.sums.";

/// 64-bit values per pixel: R, G, B and weight, the sums of squares, then the G-buffer's.
fn value_count(layout: SumsLayout) -> usize {
    7 + if layout.gbuffer {
        GBufferPixel::BITS
    } else {
        0
    }
}

/// 32-bit words per pixel: two per value, the feature sums, the sample count, and with
/// adaptive sampling the samples the pixel took.
fn words_per_pixel(layout: SumsLayout) -> usize {
    2 * value_count(layout) + FeatureSums::WORDS + 1 + usize::from(layout.adaptive)
}

/// Where a pixel's sample count sits among its words.
fn samples_word(layout: SumsLayout) -> usize {
    2 * value_count(layout) + FeatureSums::WORDS
}

impl TileSums {
    /// Sums of no samples.
    pub fn empty(rect: TileRect, layout: SumsLayout) -> TileSums {
        TileSums {
            rect,
            samples: 0,
            layout,
            pixels: vec![PixelSums::default(); rect.pixel_count() as usize],
        }
    }

    /// The channel names [`TileSums::to_words`] fills, sorted: two 32-bit words per 64-bit
    /// value (`kiln.sums.000` its low half, `kiln.sums.001` its high half, ...), the feature
    /// sums (`kiln.sums.features.0`, ...), then the sample count, then (with adaptive
    /// sampling) the samples each pixel took.
    pub fn word_names(layout: SumsLayout) -> Vec<String> {
        let mut names: Vec<String> = (0..2 * value_count(layout))
            .map(|i| format!("{WORD_PREFIX}{i:03}"))
            .chain((0..FeatureSums::WORDS).map(|i| format!("{FEATURE_PREFIX}{i}")))
            .chain([SAMPLES_WORD.to_string()])
            .chain(layout.adaptive.then(|| TAKEN_WORD.to_string()))
            .collect();
        names.sort();
        names
    }

    /// [`TileSums::word_names`], made once.
    fn names_of(layout: SumsLayout) -> &'static [String] {
        static NAMES: [std::sync::OnceLock<Vec<String>>; 4] =
            [const { std::sync::OnceLock::new() }; 4];
        let cell = &NAMES[usize::from(layout.gbuffer) + 2 * usize::from(layout.adaptive)];
        cell.get_or_init(|| TileSums::word_names(layout))
    }

    /// Checks, without decoding them, that `values` (with `names`) are the sums of a tile
    /// `rect` after `samples` samples: the channels, their count, every pixel's sample
    /// count, and (with adaptive sampling) that no pixel took more. What a coordinator asks
    /// of an upload.
    pub fn check_words(
        rect: TileRect,
        layout: SumsLayout,
        names: &[String],
        values: &[u32],
        samples: u32,
    ) -> Result<(), SumsError> {
        let expected = TileSums::names_of(layout);
        if names != expected {
            return Err(SumsError::Channels {
                found: names.to_vec(),
                expected: expected.len(),
            });
        }
        let per = expected.len();
        let pixels = rect.pixel_count() as usize;
        if values.len() != pixels * per {
            return Err(SumsError::Size {
                found: values.len(),
                expected: pixels * per,
                width: rect.width,
                height: rect.height,
            });
        }
        let at = samples_word(layout);
        let mut counts = values.iter().skip(at).step_by(per);
        if let Some(&found) = counts.clone().find(|&&n| n != samples) {
            return Err(if counts.all(|&n| n == found) {
                SumsError::SampleCount {
                    found,
                    expected: samples,
                }
            } else {
                SumsError::Samples
            });
        }
        if layout.adaptive
            && let Some(&taken) = values
                .iter()
                .skip(at + 1)
                .step_by(per)
                .find(|&&n| n > samples)
        {
            return Err(SumsError::Taken { taken, samples });
        }
        Ok(())
    }

    /// Every pixel's words, in the order of [`TileSums::word_names`].
    pub fn to_words(&self) -> Vec<u32> {
        let layout = self.layout;
        let mut out = Vec::with_capacity(self.pixels.len() * words_per_pixel(layout));
        for p in &self.pixels {
            let rgbw = p.sum.into_iter().chain([p.weight]).chain(p.squares);
            let g = if layout.gbuffer {
                p.gbuffer.to_bits().to_vec()
            } else {
                Vec::new()
            };
            for v in rgbw.map(f64::to_bits).chain(g) {
                out.push(v as u32);
                out.push((v >> 32) as u32);
            }
            out.extend(p.features.to_words());
            out.push(self.samples);
            if layout.adaptive {
                out.push(p.taken);
            }
        }
        out
    }

    /// The sums [`TileSums::to_words`] gave `values` for (with `names` as
    /// [`TileSums::word_names`] gave them), checked against the tile they must be.
    pub fn from_words(
        rect: TileRect,
        layout: SumsLayout,
        names: &[String],
        values_in: &[u32],
    ) -> Result<TileSums, SumsError> {
        let expected = TileSums::names_of(layout);
        if names != expected {
            return Err(SumsError::Channels {
                found: names.to_vec(),
                expected: expected.len(),
            });
        }
        let per = expected.len();
        let pixels = rect.pixel_count() as usize;
        if values_in.len() != pixels * per {
            return Err(SumsError::Size {
                found: values_in.len(),
                expected: pixels * per,
                width: rect.width,
                height: rect.height,
            });
        }
        let at = samples_word(layout);
        let samples = values_in.get(at).copied().unwrap_or(0);
        let mut out = Vec::with_capacity(pixels);
        for words in values_in.chunks_exact(per) {
            if words[at] != samples {
                return Err(SumsError::Samples);
            }
            let v = |i: usize| u64::from(words[2 * i]) | (u64::from(words[2 * i + 1]) << 32);
            let f = |i: usize| f64::from_bits(v(i));
            let gbuffer = if layout.gbuffer {
                let bits: [u64; GBufferPixel::BITS] = std::array::from_fn(|i| v(7 + i));
                GBufferPixel::from_bits(&bits)
            } else {
                GBufferPixel::default()
            };
            let taken = if layout.adaptive {
                let taken = words[at + 1];
                if taken > samples {
                    return Err(SumsError::Taken { taken, samples });
                }
                taken
            } else {
                samples
            };
            let features = &words[2 * value_count(layout)..at];
            out.push(PixelSums {
                sum: [f(0), f(1), f(2)],
                weight: f(3),
                gbuffer,
                taken,
                squares: [f(4), f(5), f(6)],
                features: FeatureSums::from_words(features),
            });
        }
        Ok(TileSums {
            rect,
            samples,
            layout,
            pixels: out,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_carry_every_bit() {
        let rect = TileRect {
            x0: 3,
            y0: 4,
            width: 3,
            height: 2,
        };
        for (gbuffer, adaptive) in [(false, false), (true, false), (false, true), (true, true)] {
            let layout = SumsLayout { gbuffer, adaptive };
            let other = SumsLayout {
                gbuffer: !gbuffer,
                adaptive,
            };
            let mut t = TileSums::empty(rect, layout);
            t.samples = 77;
            for (i, p) in t.pixels.iter_mut().enumerate() {
                p.sum = [
                    0.1 * i as f64,
                    -1e300,
                    f64::from_bits(0x7ff8_dead_beef_0001),
                ];
                p.weight = 1.0 / 3.0 + i as f64;
                if gbuffer {
                    let mut g = GBufferPixel::default();
                    g.add(crate::math::rgb3(1.0, 2.0, 3.0), 0.5 + i as f32, None);
                    p.gbuffer = g;
                }
                p.taken = if adaptive { 64 + i as u32 } else { 77 };
                p.squares = [
                    0.25 + i as f64,
                    f64::from_bits(0x3ff0_0000_0000_0001 + i as u64),
                    -0.0,
                ];
                p.features = FeatureSums {
                    albedo: [0.5, f32::from_bits(0x3f80_0001 + i as u32), -0.0],
                    normal: [1.0 / 3.0, -2.0, f32::MIN_POSITIVE],
                    depth: 1e30 + i as f32,
                };
            }
            let names = TileSums::word_names(layout);
            let words = t.to_words();
            let back = TileSums::from_words(rect, layout, &names, &words).unwrap();
            assert_eq!(back.samples, 77);
            for (a, b) in t.pixels.iter().zip(&back.pixels) {
                assert_eq!(a.sum.map(f64::to_bits), b.sum.map(f64::to_bits));
                assert_eq!(a.weight.to_bits(), b.weight.to_bits());
                assert_eq!(a.gbuffer.to_bits(), b.gbuffer.to_bits());
                assert_eq!(a.taken, b.taken);
                assert_eq!(a.squares.map(f64::to_bits), b.squares.map(f64::to_bits));
                assert_eq!(a.features.to_words(), b.features.to_words());
            }
            // Damaged or foreign words are refused, not misread.
            assert!(TileSums::from_words(rect, other, &names, &words).is_err());
            let flipped = SumsLayout {
                gbuffer,
                adaptive: !adaptive,
            };
            assert!(TileSums::from_words(rect, flipped, &names, &words).is_err());
            assert!(TileSums::from_words(rect, layout, &names, &words[1..]).is_err());
            let per = names.len();
            let at = samples_word(layout);
            let mut mixed = words.clone();
            mixed[per + at] = 76;
            assert_eq!(
                TileSums::from_words(rect, layout, &names, &mixed).unwrap_err(),
                SumsError::Samples
            );
            // The coordinator's check, without decoding, says the same.
            assert!(TileSums::check_words(rect, layout, &names, &words, 77).is_ok());
            assert_eq!(
                TileSums::check_words(rect, layout, &names, &words, 78).unwrap_err(),
                SumsError::SampleCount {
                    found: 77,
                    expected: 78
                }
            );
            assert_eq!(
                TileSums::check_words(rect, layout, &names, &mixed, 77).unwrap_err(),
                SumsError::Samples
            );
            assert!(TileSums::check_words(rect, other, &names, &words, 77).is_err());
            assert!(TileSums::check_words(rect, layout, &names, &words[1..], 77).is_err());
            if adaptive {
                // A pixel that says it took more samples than its tile holds is refused.
                let mut greedy = words.clone();
                greedy[per + at + 1] = 78;
                let taken = SumsError::Taken {
                    taken: 78,
                    samples: 77,
                };
                assert_eq!(
                    TileSums::check_words(rect, layout, &names, &greedy, 77).unwrap_err(),
                    taken
                );
                assert_eq!(
                    TileSums::from_words(rect, layout, &names, &greedy).unwrap_err(),
                    taken
                );
            }
        }
    }
}
