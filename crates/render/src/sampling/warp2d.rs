//! A piecewise-bilinear distribution over the unit square, conditioned on up to three
//! parameters (Dupuy & Jakob 2018, the warp behind RGL's measured BRDFs, which pbrt-v4 and
//! Mitsuba 3 call `PiecewiseLinear2D` / `Marginal2D`).
//!
//! The density is bilinear between the samples of an `nx` by `ny` grid; sampling inverts its
//! marginal over rows, then its conditional over the row's columns, both piecewise
//! quadratic. For a parameter between two of its sample values the grids are mixed
//! linearly, CDFs included, so a sample and its density always agree. Lookups never
//! allocate.

use glam::Vec2;

/// At most this many conditioning parameters (RGL's spectra use three).
const MAX_PARAMS: usize = 3;

#[derive(Debug, Clone)]
pub struct Warp2D {
    nx: usize,
    ny: usize,
    /// Sample values of each conditioning parameter, increasing.
    params: Vec<Vec<f32>>,
    /// Slice stride of each parameter (0 where it has a single value).
    strides: Vec<usize>,
    /// The grid of each slice; divided by the slice's integral when normalised.
    data: Vec<f32>,
    /// Per slice, the CDF over rows (ny entries); empty without sampling.
    marginal: Vec<f32>,
    /// Per slice, the CDF along each row (nx·ny entries); empty without sampling.
    conditional: Vec<f32>,
    /// What a bilinear lookup in `data` is multiplied by to give the value or density.
    scale: f32,
}

/// The slices a parameter point mixes, with their weights.
struct Mix {
    slice: [usize; 1 << MAX_PARAMS],
    weight: [f32; 1 << MAX_PARAMS],
    n: usize,
}

/// The largest `i` in `0..=size-2` for which `pred(i)` holds, or 0 (pred must be monotone:
/// true then false).
fn find_interval(size: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0usize, size.saturating_sub(1));
    // Invariant: pred holds below lo (or lo = 0); fails at and above hi.
    while lo + 1 < hi {
        let mid = (lo + hi) / 2;
        if pred(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo.min(size.saturating_sub(2))
}

impl Warp2D {
    /// A distribution (`sampled`: normalised, with CDFs for sampling) or a plain
    /// interpolant (values as given) over `data`: one `nx` x `ny` grid (x fastest) per
    /// combination of the parameters, the first parameter outermost.
    pub fn new(
        data: &[f32],
        nx: usize,
        ny: usize,
        params: Vec<Vec<f32>>,
        sampled: bool,
    ) -> Result<Warp2D, String> {
        if nx < 2 || ny < 2 {
            return Err(format!("a {nx}x{ny} grid is too small (2x2 at least)"));
        }
        if params.len() > MAX_PARAMS || params.iter().any(|p| p.is_empty()) {
            return Err("a warp takes at most three parameters, each with values".into());
        }
        let mut strides = vec![0; params.len()];
        let mut slices = 1usize;
        for (i, p) in params.iter().enumerate().rev() {
            strides[i] = if p.len() > 1 { slices } else { 0 };
            slices *= p.len();
        }
        let cells = nx * ny;
        if data.len() != slices * cells {
            return Err(format!(
                "{} values for {slices} slices of {nx}x{ny}",
                data.len()
            ));
        }
        let patches = ((nx - 1) * (ny - 1)) as f32;
        let mut out = Warp2D {
            nx,
            ny,
            params,
            strides,
            data: Vec::with_capacity(data.len()),
            marginal: Vec::new(),
            conditional: Vec::new(),
            scale: 1.0,
        };
        if !sampled {
            out.data.extend_from_slice(data);
            return Ok(out);
        }
        out.scale = patches;
        out.marginal.reserve(slices * ny);
        out.conditional.reserve(slices * cells);
        for slice in data.chunks_exact(cells) {
            // A slice with nothing in it (or with negative values) is taken as uniform, so
            // that sampling it stays defined; its density is then uniform too.
            let uniform = slice.iter().all(|v| *v <= 0.0) || slice.iter().any(|v| *v < 0.0);
            let value = |i: usize| if uniform { 1.0 } else { f64::from(slice[i]) };
            let mut cond = vec![0.0f64; cells];
            for y in 0..ny {
                for x in 0..nx - 1 {
                    let i = y * nx + x;
                    cond[i + 1] = cond[i] + 0.5 * (value(i) + value(i + 1));
                }
            }
            let mut marg = vec![0.0f64; ny];
            for y in 0..ny - 1 {
                marg[y + 1] = marg[y] + 0.5 * (cond[(y + 1) * nx - 1] + cond[(y + 2) * nx - 1]);
            }
            let norm = 1.0 / marg[ny - 1];
            out.conditional
                .extend(cond.iter().map(|v| (v * norm) as f32));
            out.marginal.extend(marg.iter().map(|v| (v * norm) as f32));
            out.data
                .extend((0..cells).map(|i| (value(i) * norm) as f32));
        }
        Ok(out)
    }

    fn mix(&self, param: &[f32]) -> Mix {
        let mut m = Mix {
            slice: [0; 1 << MAX_PARAMS],
            weight: [0.0; 1 << MAX_PARAMS],
            n: 1,
        };
        m.weight[0] = 1.0;
        for (dim, values) in self.params.iter().enumerate() {
            if values.len() == 1 {
                continue;
            }
            let p = param[dim];
            let i = find_interval(values.len(), |k| values[k] <= p);
            let t = ((p - values[i]) / (values[i + 1] - values[i])).clamp(0.0, 1.0);
            let t = if t.is_nan() { 0.0 } else { t };
            let stride = self.strides[dim];
            for j in 0..m.n {
                let (s, w) = (m.slice[j], m.weight[j]);
                m.slice[j] = s + stride * i;
                m.weight[j] = w * (1.0 - t);
                m.slice[j + m.n] = s + stride * (i + 1);
                m.weight[j + m.n] = w * t;
            }
            m.n *= 2;
        }
        m
    }

    /// The mix of `array`'s entry `offset` within each of `mix`'s slices of `size`.
    fn lookup(array: &[f32], size: usize, offset: usize, mix: &Mix) -> f32 {
        (0..mix.n)
            .map(|j| mix.weight[j] * array[mix.slice[j] * size + offset])
            .sum()
    }

    /// The grid cell holding `pos` and the position within it.
    fn cell(&self, pos: Vec2) -> ((usize, usize), Vec2) {
        let s = pos * Vec2::new((self.nx - 1) as f32, (self.ny - 1) as f32);
        let x = (s.x.max(0.0) as usize).min(self.nx - 2);
        let y = (s.y.max(0.0) as usize).min(self.ny - 2);
        ((x, y), s - Vec2::new(x as f32, y as f32))
    }

    /// The value (or density, for a sampled warp) at `pos`.
    pub fn evaluate(&self, pos: Vec2, param: &[f32]) -> f32 {
        let mix = self.mix(param);
        let ((x, y), w1) = self.cell(pos);
        let w0 = Vec2::ONE - w1;
        let (nx, size) = (self.nx, self.nx * self.ny);
        let at = |o: usize| Self::lookup(&self.data, size, o, &mix);
        let i = y * nx + x;
        let v = w0.y * (w0.x * at(i) + w1.x * at(i + 1))
            + w1.y * (w0.x * at(i + nx) + w1.x * at(i + nx + 1));
        v * self.scale
    }

    /// Warps a uniform `u` to the distribution: the point and its density (0 where the
    /// distribution is empty).
    pub fn sample(&self, u: Vec2, param: &[f32]) -> (Vec2, f32) {
        let mix = self.mix(param);
        let (nx, ny, size) = (self.nx, self.ny, self.nx * self.ny);
        let mut s = u.clamp(
            Vec2::splat(f32::EPSILON * 0.5),
            Vec2::splat(1.0 - f32::EPSILON),
        );
        let marginal = |i: usize| Self::lookup(&self.marginal, ny, i, &mix);
        let row = find_interval(ny, |i| marginal(i) < s.y);
        s.y -= marginal(row);
        let offset = row * nx;
        let cond = |o: usize| Self::lookup(&self.conditional, size, o, &mix);
        let (r0, r1) = (cond(offset + nx - 1), cond(offset + 2 * nx - 1));
        s.y = invert_linear(r0, r1, s.y);
        s.x *= (1.0 - s.y) * r0 + s.y * r1;
        let row_cdf = |i: usize| (1.0 - s.y) * cond(offset + i) + s.y * cond(offset + nx + i);
        let col = find_interval(nx, |i| row_cdf(i) < s.x);
        s.x -= row_cdf(col);
        let o = offset + col;
        let at = |o: usize| Self::lookup(&self.data, size, o, &mix);
        let c0 = (1.0 - s.y) * at(o) + s.y * at(o + nx);
        let c1 = (1.0 - s.y) * at(o + 1) + s.y * at(o + nx + 1);
        s.x = invert_linear(c0, c1, s.x);
        let p = Vec2::new(
            (col as f32 + s.x) / (nx - 1) as f32,
            (row as f32 + s.y) / (ny - 1) as f32,
        );
        let pdf = ((1.0 - s.x) * c0 + s.x * c1) * self.scale;
        (p.clamp(Vec2::ZERO, Vec2::ONE), pdf.max(0.0))
    }

    /// The inverse of [`Warp2D::sample`]: the uniform point that warps to `pos`, and the
    /// density at `pos`.
    pub fn invert(&self, pos: Vec2, param: &[f32]) -> (Vec2, f32) {
        let mix = self.mix(param);
        let (nx, ny, size) = (self.nx, self.ny, self.nx * self.ny);
        let ((x, y), mut s) = self.cell(pos);
        let at = |o: usize| Self::lookup(&self.data, size, o, &mix);
        let cond = |o: usize| Self::lookup(&self.conditional, size, o, &mix);
        let o = y * nx + x;
        let (v00, v10, v01, v11) = (at(o), at(o + 1), at(o + nx), at(o + nx + 1));
        let c0 = (1.0 - s.y) * v00 + s.y * v01;
        let c1 = (1.0 - s.y) * v10 + s.y * v11;
        let pdf = (1.0 - s.x) * c0 + s.x * c1;
        s.x *= c0 + 0.5 * s.x * (c1 - c0);
        s.x += (1.0 - s.y) * cond(o) + s.y * cond(o + nx);
        let row = y * nx;
        let (r0, r1) = (cond(row + nx - 1), cond(row + 2 * nx - 1));
        let total = (1.0 - s.y) * r0 + s.y * r1;
        s.x = if total > 0.0 { s.x / total } else { 0.0 };
        s.y *= r0 + 0.5 * s.y * (r1 - r0);
        s.y += Self::lookup(&self.marginal, ny, y, &mix);
        (s.clamp(Vec2::ZERO, Vec2::ONE), (pdf * self.scale).max(0.0))
    }
}

/// Solves ∫₀ᵗ (a(1 − x) + b x) dx = s for t in [0, 1], the density linear from a to b.
fn invert_linear(a: f32, b: f32, s: f32) -> f32 {
    if (a - b).abs() < 1e-4 * (a + b) {
        return if a + b > 0.0 { 2.0 * s / (a + b) } else { 0.0 };
    }
    let t = (a - (a * a - 2.0 * s * (a - b)).max(0.0).sqrt()) / (a - b);
    if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PixelSampler;

    /// A lopsided 4x3 grid in two slices of one parameter.
    fn warp() -> Warp2D {
        let a = [0.1, 0.5, 2.0, 1.0, 0.3, 0.0, 1.0, 4.0, 0.2, 0.2, 0.9, 1.5];
        let b = [1.0, 1.0, 0.5, 0.5, 2.0, 0.1, 0.1, 3.0, 0.7, 1.2, 0.2, 0.4];
        let data: Vec<f32> = a.iter().chain(&b).copied().collect();
        Warp2D::new(&data, 4, 3, vec![vec![0.0, 1.0]], true).unwrap()
    }

    #[test]
    fn density_integrates_to_one_and_sampling_follows_it() {
        let w = warp();
        for param in [0.0, 0.3, 1.0] {
            // The density integrates to 1 over the square.
            let m = 400;
            let mut total = 0.0f64;
            for i in 0..m {
                for j in 0..m {
                    let p = Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                    total += f64::from(w.evaluate(p, &[param]));
                }
            }
            total /= (m * m) as f64;
            assert!((total - 1.0).abs() < 1e-3, "param {param}: {total}");
            // Samples report the density there, invert back to their uniform point, and
            // land in a region as often as its integral says.
            let n = 1 << 15;
            let mut left = 0usize;
            for k in 0..n {
                let s = PixelSampler::new(1, 2, k, 5);
                let u = Vec2::new(s.value(0), s.value(1));
                let (p, pdf) = w.sample(u, &[param]);
                let eval = w.evaluate(p, &[param]);
                assert!(
                    (pdf - eval).abs() <= 2e-3 * eval.max(1.0),
                    "{pdf} vs {eval}"
                );
                let (back, pdf2) = w.invert(p, &[param]);
                assert!(
                    (back - u).abs().max_element() < 2e-3,
                    "{u} -> {p} -> {back}"
                );
                assert!((pdf2 - eval).abs() <= 2e-3 * eval.max(1.0));
                left += usize::from(p.x < 0.5);
            }
            let mut left_mass = 0.0f64;
            for i in 0..m / 2 {
                for j in 0..m {
                    let p = Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                    left_mass += f64::from(w.evaluate(p, &[param])) / (m * m) as f64;
                }
            }
            let frac = left as f64 / n as f64;
            assert!((frac - left_mass).abs() < 0.01, "{frac} vs {left_mass}");
        }
    }

    #[test]
    fn an_interpolant_returns_its_values() {
        let w = Warp2D::new(&[1.0, 2.0, 3.0, 5.0], 2, 2, vec![], false).unwrap();
        assert_eq!(w.evaluate(Vec2::ZERO, &[]), 1.0);
        assert_eq!(w.evaluate(Vec2::ONE, &[]), 5.0);
        assert!((w.evaluate(Vec2::splat(0.5), &[]) - 2.75).abs() < 1e-6);
        assert!(Warp2D::new(&[1.0; 3], 2, 2, vec![], false).is_err());
    }
}
