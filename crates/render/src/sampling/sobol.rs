//! Owen-scrambled Sobol points four dimensions at a time, bit for bit what
//! `sobol_burley::sample_4d` gives, at less cost per call.
//!
//! `sample_4d` spends most of its time in two places that a path tracer pays for again and
//! again with the same inputs:
//!
//! - **The index shuffle** depends only on the sample index and the seed, not on the
//!   dimension. [`SobolPoint`] computes it once per pixel sample; every dimension set of
//!   the path reuses it.
//! - **The Sobol matrix product** XORs one direction vector per set bit of the shuffled
//!   index (about eight of its sixteen bits), a loop whose every step waits for the last.
//!   The product is linear over XOR, so it equals the XOR of the products of the index's
//!   four nibbles: [`Tables`] holds, for every dimension set, the product of each value of
//!   each nibble (16 values x 4 nibbles x 16 bytes = 1 KiB per set, 64 KiB for all), and a
//!   point is four independent loads.
//!
//! The Owen scramble of the result and the conversion to floats are `sobol_burley`'s own
//! functions, so nothing but the order of XORs changes, and XOR is associative.

use sobol_burley::parts::{Int4, hash, hash_int4, owen_scramble_int4_rev, owen_scramble_rev};
use sobol_burley::{NUM_DIMENSION_SETS_4D, parts::sobol_int4_rev};
use std::sync::OnceLock;

/// For each dimension set, each of the four nibbles of the (top 16 bits of the) reversed
/// index and each of its 16 values: the Sobol product of that nibble alone.
struct Tables {
    sets: Vec<[[[u32; 4]; 16]; 4]>,
}

impl Tables {
    fn get() -> &'static Tables {
        static TABLES: OnceLock<Tables> = OnceLock::new();
        TABLES.get_or_init(|| Tables {
            sets: (0..NUM_DIMENSION_SETS_4D)
                .map(|set| {
                    std::array::from_fn(|nibble| {
                        std::array::from_fn(|value| {
                            let index_rev = (value as u32) << (16 + 4 * nibble);
                            sobol_int4_rev(index_rev, set).into()
                        })
                    })
                })
                .collect(),
        })
    }

    /// `sobol_int4_rev(index_rev, set)`, by nibbles.
    #[inline(always)]
    fn product(&self, index_rev: u32, set: u32) -> Int4 {
        let t = &self.sets[set as usize];
        let n = |k: usize| Int4::from(t[k][((index_rev >> (16 + 4 * k)) & 15) as usize]);
        (n(0) ^ n(1)) ^ (n(2) ^ n(3))
    }
}

/// One sample index of one seed's shuffled, scrambled Sobol sequence, ready to give any of
/// its dimension sets.
#[derive(Debug, Clone, Copy)]
pub struct SobolPoint {
    /// The shuffled index, bits reversed, as `sample_4d` computes it.
    index_rev: u32,
    seed: u32,
}

impl SobolPoint {
    pub fn new(sample_index: u32, seed: u32) -> SobolPoint {
        debug_assert!(sample_index < (1 << 16));
        SobolPoint {
            index_rev: owen_scramble_rev(sample_index.reverse_bits(), hash(seed ^ 0x79c6_8e4a)),
            seed,
        }
    }

    /// Dimensions 4 `set` .. 4 `set` + 3: `sobol_burley::sample_4d(index, set, seed)`.
    #[inline]
    pub fn set(&self, set: u32) -> [f32; 4] {
        let sobol = Tables::get().product(self.index_rev, set);
        let scramble = {
            let seed: Int4 = [self.seed.wrapping_mul(0x9c8f_2d3b); 4].into();
            let ds: Int4 = [set; 4].into();
            seed ^ ds ^ [0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8].into()
        };
        owen_scramble_int4_rev(sobol, hash_int4(scramble))
            .reverse_bits()
            .to_f32_norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every dimension set of many indices and seeds, against the crate's own function.
    #[test]
    fn equals_sample_4d_bit_for_bit() {
        let mut seed = 0x1234_5678u32;
        for i in 0..4000u32 {
            seed = hash(seed ^ i);
            let index = if i < 2000 { i } else { hash(i) & 0xffff };
            let point = SobolPoint::new(index, seed);
            for set in 0..NUM_DIMENSION_SETS_4D {
                let ours = point.set(set).map(f32::to_bits);
                let theirs = sobol_burley::sample_4d(index, set, seed).map(f32::to_bits);
                assert_eq!(ours, theirs, "index {index} set {set} seed {seed:#x}");
            }
        }
        // The last index a pixel may use, where every bit of the reversed index is set.
        let point = SobolPoint::new(0xffff, 7);
        for set in 0..NUM_DIMENSION_SETS_4D {
            assert_eq!(
                point.set(set).map(f32::to_bits),
                sobol_burley::sample_4d(0xffff, set, 7).map(f32::to_bits)
            );
        }
    }
}
