//! A tile's running sums: each pixel's filter-weighted radiance and weight (and, with a
//! G-buffer film, its G-buffer sums) after its first `samples` samples, kept bit for bit.
//!
//! This is what lets a render be done in passes with the same bytes as in one go. A pixel is
//! always accumulated the same way, one sample after the other in sample order from zero
//! (`sum += l * w` in f64); a pass continues the sums where the last one stopped, so the
//! sums after N samples are the same bits whether they were reached in one pass or in many,
//! and so is the pixel made from them. Between passes the sums travel as 32-bit words
//! (an f64 as its low and high halves), which any image format with integer channels holds
//! exactly.

use crate::gbuffer::GBufferPixel;
use crate::tile::TileRect;

/// One pixel's running sums.
#[derive(Debug, Clone, Default)]
pub struct PixelSums {
    /// Filter-weighted radiance, in sample order.
    pub sum: [f64; 3],
    pub weight: f64,
    /// With a G-buffer film, its sums; unused otherwise.
    pub gbuffer: GBufferPixel,
}

impl PixelSums {
    /// The pixel's value: the weighted mean (black where no sample had weight).
    pub fn value(&self) -> [f32; 3] {
        if self.weight == 0.0 {
            return [0.0; 3];
        }
        self.sum.map(|v| (v / self.weight) as f32)
    }
}

/// A tile's running sums after `samples` samples of every pixel.
#[derive(Debug, Clone)]
pub struct TileSums {
    pub rect: TileRect,
    /// How many samples of each pixel the sums hold.
    pub samples: u32,
    /// Whether they hold G-buffer sums.
    pub gbuffer: bool,
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
}

/// The name of the channel holding the sample count, and the prefix of the others.
const SAMPLES_WORD: &str = "kiln.sums.samples";
const WORD_PREFIX: &str = "kiln.sums.";

/// 64-bit values per pixel: R, G, B and weight, then the G-buffer's.
fn values(gbuffer: bool) -> usize {
    4 + if gbuffer { GBufferPixel::BITS } else { 0 }
}

impl TileSums {
    /// Sums of no samples.
    pub fn empty(rect: TileRect, gbuffer: bool) -> TileSums {
        TileSums {
            rect,
            samples: 0,
            gbuffer,
            pixels: vec![PixelSums::default(); rect.pixel_count() as usize],
        }
    }

    /// The channel names [`TileSums::to_words`] fills, sorted: two 32-bit words per 64-bit
    /// value (`kiln.sums.000` its low half, `kiln.sums.001` its high half, ...), then the
    /// sample count.
    pub fn word_names(gbuffer: bool) -> Vec<String> {
        let mut names: Vec<String> = (0..2 * values(gbuffer))
            .map(|i| format!("{WORD_PREFIX}{i:03}"))
            .chain([SAMPLES_WORD.to_string()])
            .collect();
        names.sort();
        names
    }

    /// [`TileSums::word_names`], made once.
    fn names_of(gbuffer: bool) -> &'static [String] {
        static PLAIN: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
        static GBUFFER: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
        let cell = if gbuffer { &GBUFFER } else { &PLAIN };
        cell.get_or_init(|| TileSums::word_names(gbuffer))
    }

    /// Checks, without decoding them, that `values` (with `names`) are the sums of a tile
    /// `rect` after `samples` samples: the channels, their count and every pixel's sample
    /// count. What a coordinator asks of an upload.
    pub fn check_words(
        rect: TileRect,
        gbuffer: bool,
        names: &[String],
        values: &[u32],
        samples: u32,
    ) -> Result<(), SumsError> {
        let expected = TileSums::names_of(gbuffer);
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
        let mut counts = values.iter().skip(per - 1).step_by(per);
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
        Ok(())
    }

    /// Every pixel's words, in the order of [`TileSums::word_names`].
    pub fn to_words(&self) -> Vec<u32> {
        let n = values(self.gbuffer);
        let mut out = Vec::with_capacity(self.pixels.len() * (2 * n + 1));
        for p in &self.pixels {
            let rgbw = p.sum.into_iter().chain([p.weight]).map(f64::to_bits);
            let g = if self.gbuffer {
                p.gbuffer.to_bits().to_vec()
            } else {
                Vec::new()
            };
            for v in rgbw.chain(g) {
                out.push(v as u32);
                out.push((v >> 32) as u32);
            }
            out.push(self.samples);
        }
        out
    }

    /// The sums [`TileSums::to_words`] gave `values` for (with `names` as
    /// [`TileSums::word_names`] gave them), checked against the tile they must be.
    pub fn from_words(
        rect: TileRect,
        gbuffer: bool,
        names: &[String],
        values_in: &[u32],
    ) -> Result<TileSums, SumsError> {
        let expected = TileSums::names_of(gbuffer);
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
        let samples = values_in.get(per - 1).copied().unwrap_or(0);
        let mut out = Vec::with_capacity(pixels);
        for words in values_in.chunks_exact(per) {
            if words[per - 1] != samples {
                return Err(SumsError::Samples);
            }
            let v = |i: usize| u64::from(words[2 * i]) | (u64::from(words[2 * i + 1]) << 32);
            let f = |i: usize| f64::from_bits(v(i));
            let gbuffer = if gbuffer {
                let bits: [u64; GBufferPixel::BITS] = std::array::from_fn(|i| v(4 + i));
                GBufferPixel::from_bits(&bits)
            } else {
                GBufferPixel::default()
            };
            out.push(PixelSums {
                sum: [f(0), f(1), f(2)],
                weight: f(3),
                gbuffer,
            });
        }
        Ok(TileSums {
            rect,
            samples,
            gbuffer,
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
        for gbuffer in [false, true] {
            let mut t = TileSums::empty(rect, gbuffer);
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
                    g.add(crate::math::Color::new(1.0, 2.0, 3.0), 0.5 + i as f32, None);
                    p.gbuffer = g;
                }
            }
            let names = TileSums::word_names(gbuffer);
            let words = t.to_words();
            let back = TileSums::from_words(rect, gbuffer, &names, &words).unwrap();
            assert_eq!(back.samples, 77);
            for (a, b) in t.pixels.iter().zip(&back.pixels) {
                assert_eq!(a.sum.map(f64::to_bits), b.sum.map(f64::to_bits));
                assert_eq!(a.weight.to_bits(), b.weight.to_bits());
                assert_eq!(a.gbuffer.to_bits(), b.gbuffer.to_bits());
            }
            // Damaged or foreign words are refused, not misread.
            assert!(TileSums::from_words(rect, !gbuffer, &names, &words).is_err());
            assert!(TileSums::from_words(rect, gbuffer, &names, &words[1..]).is_err());
            let mut mixed = words.clone();
            let per = names.len();
            mixed[2 * per - 1] = 76;
            assert_eq!(
                TileSums::from_words(rect, gbuffer, &names, &mixed).unwrap_err(),
                SumsError::Samples
            );
            // The coordinator's check, without decoding, says the same.
            assert!(TileSums::check_words(rect, gbuffer, &names, &words, 77).is_ok());
            assert_eq!(
                TileSums::check_words(rect, gbuffer, &names, &words, 78).unwrap_err(),
                SumsError::SampleCount {
                    found: 77,
                    expected: 78
                }
            );
            assert_eq!(
                TileSums::check_words(rect, gbuffer, &names, &mixed, 77).unwrap_err(),
                SumsError::Samples
            );
            assert!(TileSums::check_words(rect, !gbuffer, &names, &words, 77).is_err());
            assert!(TileSums::check_words(rect, gbuffer, &names, &words[1..], 77).is_err());
        }
    }
}
