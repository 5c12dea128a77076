//! Walker's alias table: O(1) sampling of a discrete distribution of any size (the light
//! sampler's choice among lights, by power).

/// Walker's alias table: O(1) sampling of a discrete distribution of any size.
#[derive(Debug, Clone, Default)]
pub struct AliasTable {
    bins: Vec<AliasBin>,
}

/// One bin, with its alias's probability beside its own, so that a sample reads one bin
/// (one cache line) whichever of the two it picks: the headline frame's table over 124,061
/// VolumeLight faces is about 2 MB, and a second read missed the cache.
#[derive(Debug, Clone, Copy)]
#[repr(align(16))]
struct AliasBin {
    /// Probability of keeping this bin rather than its alias.
    q: f32,
    /// The probability mass of this bin's own entry.
    pmf: f32,
    alias: u32,
    /// The probability mass of the alias's entry.
    alias_pmf: f32,
}

impl AliasTable {
    /// Builds the table; weights must be finite and non-negative. All-zero weights give an empty table.
    pub fn new(weights: &[f64]) -> AliasTable {
        let total: f64 = weights.iter().sum();
        if weights.is_empty() || total <= 0.0 || !total.is_finite() {
            return AliasTable { bins: Vec::new() };
        }
        let n = weights.len();
        let mut bins: Vec<AliasBin> = weights
            .iter()
            .map(|&w| AliasBin {
                q: 0.0,
                pmf: (w / total) as f32,
                alias: u32::MAX,
                alias_pmf: 0.0,
            })
            .collect();
        // Scaled probabilities: an average bin holds exactly 1.
        let mut scaled: Vec<f64> = weights.iter().map(|&w| w / total * n as f64).collect();
        let mut small: Vec<usize> = Vec::new();
        let mut large: Vec<usize> = Vec::new();
        for (i, &p) in scaled.iter().enumerate() {
            if p < 1.0 {
                small.push(i)
            } else {
                large.push(i)
            }
        }
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            bins[s].q = scaled[s] as f32;
            bins[s].alias = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Whatever is left is 1 up to rounding.
        for i in small.into_iter().chain(large) {
            bins[i].q = 1.0;
            bins[i].alias = i as u32;
        }
        let pmfs: Vec<f32> = bins.iter().map(|b| b.pmf).collect();
        for b in &mut bins {
            b.alias_pmf = pmfs[b.alias as usize];
        }
        AliasTable { bins }
    }

    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Picks an entry with one uniform number; returns (index, pmf).
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        if self.bins.is_empty() {
            return None;
        }
        let n = self.bins.len();
        let scaled = u * n as f32;
        let i = (scaled as usize).min(n - 1);
        let up = (scaled - i as f32).min(1.0);
        let bin = &self.bins[i];
        Some(if up < bin.q {
            (i, bin.pmf)
        } else {
            (bin.alias as usize, bin.alias_pmf)
        })
    }

    pub fn pmf(&self, index: usize) -> f32 {
        self.bins.get(index).map_or(0.0, |b| b.pmf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alias_table_reproduces_its_distribution() {
        let weights = [1.0, 0.0, 3.0, 6.0];
        let table = AliasTable::new(&weights);
        let mut counts = [0u32; 4];
        let n = 100_000;
        for i in 0..n {
            let (k, pmf) = table.sample((i as f32 + 0.5) / n as f32).unwrap();
            assert!((pmf - weights[k] as f32 / 10.0).abs() < 1e-6);
            counts[k] += 1;
        }
        for k in 0..4 {
            let expected = weights[k] / 10.0;
            assert!(
                (counts[k] as f64 / n as f64 - expected).abs() < 2e-3,
                "{counts:?}"
            );
        }
        assert_eq!(table.pmf(1), 0.0);
    }
}
