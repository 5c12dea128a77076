//! RGB → spectrum coefficients for spectral rendering: a table of Kiln's own sigmoid-quadratic
//! fits (`rgb_spectrum`) over the RGB cube, looked up and interpolated per colour, as pbrt-v4
//! does with its `RGBToSpectrumTable` (Jakob and Hanika 2019). Image textures and other
//! colours that vary over a surface need a spectrum per lookup, far too many to fit one by
//! one.
//!
//! Layout (pbrt-v4's): for each largest component m of a colour (r, g or b), its value z
//! (the brightness) and the other two as fractions x = c[(m+1)%3] / z, y = c[(m+2)%3] / z of
//! it, all three on a grid of `res` nodes. The z nodes crowd towards 0 and 1
//! (smoothstep(smoothstep(k / (res−1)))), where the coefficients change fastest. Each fit
//! continues from its neighbour in z, starting from a flat grey a fifth of the way up, so the
//! table is a pure function of its resolution: built the same on any machine and any number
//! of threads.

use crate::rgb_spectrum::Upsampler;
use glam::Vec4;
use std::sync::OnceLock;

/// Nodes per axis. 32 keeps the build around half a second on one core, and trilinear lookups
/// within 2e-3 of their colour inside the gamut (the test below).
pub const RESOLUTION: usize = 32;

/// The spacing of the fits' colour sums, nm. Against the exact sums over every nanometre
/// this moves a lookup's colour by about 1e-4 (the lattice test's worst error goes from
/// 1.71e-3 at 2.5 nm to 1.78e-3), and halves the build.
const FIT_STEP: f64 = 5.0;

/// Sigmoid-quadratic coefficients (c0, c1, c2): the spectrum is
/// s(c0 + c1·t + c2·t²) with t = (λ − 555) / 175 and s(z) = ½ + z / (2·√(1 + z²)).
pub type Coefficients = [f32; 3];

/// A table of sigmoid-quadratic coefficients over the RGB cube (linear sRGB under D65).
#[derive(Debug, Clone)]
pub struct SigmoidTable {
    res: usize,
    z_nodes: Vec<f32>,
    /// For brightness z, the node at or below `z_guess[(z · (GUESSES − 1)) as usize]`: the
    /// search for z's node starts there (it is at most a step or two further).
    z_guess: Vec<u8>,
    /// `[m][zi][yi][xi]`: largest component, brightness node, the two fractions; each
    /// (c0, c1, c2, 0) so that a lookup interpolates all three at once.
    coeffs: Vec<Vec4>,
}

/// Entries of the brightness search's first guess.
const GUESSES: usize = 1024;

fn smoothstep(x: f64) -> f64 {
    x * x * (3.0 - 2.0 * x)
}

/// The coefficients of the flat spectrum `v` in (0, 1) (exact: c1 = c2 = 0); ±∞ at 0 and 1.
pub fn flat(v: f32) -> Coefficients {
    let v = v.clamp(0.0, 1.0);
    let c0 = if v <= 0.0 {
        f32::NEG_INFINITY
    } else if v >= 1.0 {
        f32::INFINITY
    } else {
        (v - 0.5) / (v * (1.0 - v)).sqrt()
    };
    [c0, 0.0, 0.0]
}

/// The spectrum of `c` at `lambda` nm.
pub fn evaluate(c: Coefficients, lambda: f32) -> f32 {
    let t = (lambda - 555.0) / 175.0;
    let z = c[0] + t * (c[1] + t * c[2]);
    if z.is_infinite() {
        return if z > 0.0 { 1.0 } else { 0.0 };
    }
    0.5 + z / (2.0 * (1.0 + z * z).sqrt())
}

impl SigmoidTable {
    /// The table for linear sRGB, built once per process.
    pub fn srgb() -> &'static SigmoidTable {
        static TABLE: OnceLock<SigmoidTable> = OnceLock::new();
        TABLE.get_or_init(|| SigmoidTable::build(RESOLUTION))
    }

    /// Fits every node of a `res`-node table, on as many threads as the machine has.
    pub fn build(res: usize) -> SigmoidTable {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        SigmoidTable::build_on(res, threads)
    }

    /// [`SigmoidTable::build`] on `threads` threads: each chain of fits along z is
    /// independent, so the result does not depend on them.
    pub fn build_on(res: usize, threads: usize) -> SigmoidTable {
        assert!(res >= 4, "a sigmoid table needs at least 4 nodes per axis");
        let steps =
            ((crate::spectrum::LAMBDA_MAX - crate::spectrum::LAMBDA_MIN) / FIT_STEP) as usize;
        let lambdas = (0..=steps)
            .map(|i| crate::spectrum::LAMBDA_MIN + FIT_STEP * i as f64)
            .collect();
        let up = Upsampler::on(lambdas);
        let z_nodes: Vec<f64> = (0..res)
            .map(|k| smoothstep(smoothstep(k as f64 / (res - 1) as f64)))
            .collect();
        let chains = 3 * res * res;
        let threads = threads.clamp(1, chains);
        let mut per_chain: Vec<Vec<Coefficients>> = vec![Vec::new(); chains];
        std::thread::scope(|scope| {
            for (t, slots) in per_chain.chunks_mut(chains.div_ceil(threads)).enumerate() {
                let (up, z_nodes) = (&up, &z_nodes);
                let first = t * chains.div_ceil(threads);
                scope.spawn(move || {
                    for (i, slot) in slots.iter_mut().enumerate() {
                        *slot = fit_chain(up, z_nodes, first + i, res);
                    }
                });
            }
        });
        // Chain (m, yi, xi) holds the fits along z; store them [m][zi][yi][xi].
        let mut coeffs = vec![[0.0; 3]; 3 * res * res * res];
        for (chain, fits) in per_chain.iter().enumerate() {
            let (m, rest) = (chain / (res * res), chain % (res * res));
            for (zi, c) in fits.iter().enumerate() {
                coeffs[((m * res + zi) * res * res) + rest] = *c;
            }
        }
        let z_nodes: Vec<f32> = z_nodes.iter().map(|&z| z as f32).collect();
        let z_guess = (0..GUESSES)
            .map(|i| {
                let z = i as f32 / (GUESSES - 1) as f32;
                (z_nodes.partition_point(|&n| n <= z).saturating_sub(1)).min(res - 2) as u8
            })
            .collect();
        SigmoidTable {
            res,
            z_nodes,
            z_guess,
            coeffs: coeffs
                .iter()
                .map(|c| Vec4::new(c[0], c[1], c[2], 0.0))
                .collect(),
        }
    }

    /// The coefficients of a colour (each component clamped to [0, 1]): trilinear in the
    /// table, exact for greys.
    pub fn coefficients(&self, rgb: [f32; 3]) -> Coefficients {
        let rgb = rgb.map(|c| if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) });
        if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
            return flat(rgb[0]);
        }
        let m = if rgb[0] > rgb[1] {
            if rgb[0] > rgb[2] { 0 } else { 2 }
        } else if rgb[1] > rgb[2] {
            1
        } else {
            2
        };
        let z = rgb[m];
        let last = (self.res - 1) as f32;
        let x = rgb[(m + 1) % 3] / z * last;
        let y = rgb[(m + 2) % 3] / z * last;
        let mut zi = usize::from(self.z_guess[(z * (GUESSES - 1) as f32) as usize]);
        while zi + 2 < self.res && self.z_nodes[zi + 1] <= z {
            zi += 1;
        }
        let dz = (z - self.z_nodes[zi]) / (self.z_nodes[zi + 1] - self.z_nodes[zi]);
        let xi = (x as usize).min(self.res - 2);
        let yi = (y as usize).min(self.res - 2);
        let (dx, dy) = (x - xi as f32, y - yi as f32);
        let res = self.res;
        let plane = |zj: usize| {
            let row = ((m * res + zj) * res + yi) * res + xi;
            let (a, b) = (self.coeffs[row], self.coeffs[row + 1]);
            let (c, d) = (self.coeffs[row + res], self.coeffs[row + res + 1]);
            a.lerp(b, dx).lerp(c.lerp(d, dx), dy)
        };
        let c = plane(zi).lerp(plane(zi + 1), dz);
        [c.x, c.y, c.z]
    }
}

/// The fits of chain (m, yi, xi) at every z node: upwards from a fifth of the way, then
/// downwards from there, each starting from its neighbour's solution.
fn fit_chain(up: &Upsampler, z_nodes: &[f64], chain: usize, res: usize) -> Vec<Coefficients> {
    let m = chain / (res * res);
    let (yi, xi) = ((chain % (res * res)) / res, chain % res);
    let last = (res - 1) as f64;
    let (x, y) = (xi as f64 / last, yi as f64 / last);
    let target = |z: f64| {
        let mut rgb = [0.0; 3];
        rgb[m] = z;
        rgb[(m + 1) % 3] = x * z;
        rgb[(m + 2) % 3] = y * z;
        rgb
    };
    let mut out = vec![[0.0f32; 3]; res];
    let start = res / 5;
    for range in [
        (start..res).collect::<Vec<_>>(),
        (0..=start).rev().collect::<Vec<_>>(),
    ] {
        let mut c = [0.0; 3];
        for zi in range {
            c = up.fit_within(target(z_nodes[zi]), c, 1e-12);
            out[zi] = c.map(|v| v as f32);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Table lookups reproduce colours: over a lattice of in-gamut colours (reachable by a
    /// reflectance, so not the cube's saturated corners) the spectrum of the interpolated
    /// coefficients has the colour asked for within 2e-3, and greys are exact.
    #[test]
    fn lookups_give_back_their_colours() {
        let started = std::time::Instant::now();
        let table = SigmoidTable::srgb();
        println!(
            "sRGB sigmoid table ({RESOLUTION}^3 x 3) built in {:?}",
            started.elapsed()
        );
        let exact = Upsampler::new();
        let colour_of = |c: Coefficients| exact.colour(c.map(f64::from)).0;
        let mut worst = 0.0f64;
        for r in 0..8 {
            for g in 0..8 {
                for b in 0..8 {
                    let rgb = [r, g, b].map(|v| 0.05 + 0.8 * v as f32 / 7.0);
                    // Keep to colours a reflectance reaches: not too saturated.
                    let (lo, hi) = (
                        rgb.iter().cloned().fold(1.0, f32::min),
                        rgb.iter().cloned().fold(0.0, f32::max),
                    );
                    if lo < 0.12 * hi {
                        continue;
                    }
                    let got = colour_of(table.coefficients(rgb));
                    for k in 0..3 {
                        worst = worst.max((got[k] - rgb[k] as f64).abs());
                    }
                }
            }
        }
        println!("worst colour error over the lattice: {worst:.2e}");
        assert!(worst < 2e-3, "worst colour error {worst}");
        for v in [0.0, 0.18, 0.5, 0.9, 1.0] {
            let c = table.coefficients([v; 3]);
            for l in [380.0, 555.0, 700.0] {
                assert!(
                    (evaluate(c, l) - v).abs() < 1e-6,
                    "{v} at {l}: {}",
                    evaluate(c, l)
                );
            }
        }
    }

    /// The table is the same whatever the number of threads that built it.
    #[test]
    fn the_table_does_not_depend_on_threads() {
        let a = SigmoidTable::build_on(8, 1);
        let b = SigmoidTable::build_on(8, 3);
        let bits = |t: &SigmoidTable| {
            t.coeffs
                .iter()
                .flat_map(|v| v.to_array())
                .map(f32::to_bits)
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&a), bits(&b));
    }
}
