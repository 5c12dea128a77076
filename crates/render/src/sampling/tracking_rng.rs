//! The generator behind tracking's unbounded count of random numbers.

/// A small deterministic generator for the unbounded number of random numbers that
/// tracking may need, seeded from the path's sampler (so still a pure function of
/// pixel, sample and dimension).
pub struct TrackingRng(u64);

impl TrackingRng {
    pub fn new(seed: u64) -> TrackingRng {
        TrackingRng(seed)
    }

    /// Seeded from sample values already drawn (their bits), with a stream number.
    pub fn from_values(values: &[f32], stream: u32) -> TrackingRng {
        let mut seed = 0x243f_6a88_85a3_08d3u64 ^ u64::from(stream);
        for v in values {
            seed = (seed ^ u64::from(v.to_bits())).wrapping_mul(0x1000_0000_01b3);
            seed ^= seed >> 29;
        }
        TrackingRng(seed)
    }

    /// A second generator whose stream is this one's state mixed with `salt` (this one is
    /// not advanced).
    pub fn split(&self, salt: u64) -> TrackingRng {
        TrackingRng(self.0 ^ salt)
    }

    pub fn next_f32(&mut self) -> f32 {
        // SplitMix64.
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }
}
