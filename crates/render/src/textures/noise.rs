//! Perlin noise, fractional Brownian motion and turbulence, and the textures made of them:
//! fbm, wrinkled, windy (float) and marble (spectrum), as pbrt-v4 defines them.
//!
//! The lattice hash is Ken Perlin's (his published permutation of 0..255); the gradient
//! set and the lacunarity of 1.99 are pbrt-v4's, so the patterns match pbrt-v4's images.
//! fBm and turbulence drop the octaves finer than the pixel footprint (the last kept one
//! fades in), which is how they stay free of aliasing.

use super::TextureEvalContext;
use super::mapping::Mapping3D;
use crate::math::Color;
use glam::Vec3A;

/// Ken Perlin's permutation of 0..255 (from his reference implementation of improved noise).
const PERM: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
];

fn perm(i: i32) -> i32 {
    PERM[(i & 255) as usize] as i32
}

/// The gradient at lattice point (x, y, z) dotted with the offset (dx, dy, dz), with
/// pbrt-v4's twelve-plus-four gradient set.
fn grad(x: i32, y: i32, z: i32, dx: f32, dy: f32, dz: f32) -> f32 {
    let h = perm(perm(perm(x) + y) + z) & 15;
    let u = if h < 8 || h == 12 || h == 13 { dx } else { dy };
    let v = if h < 4 || h == 12 || h == 13 { dy } else { dz };
    (if h & 1 != 0 { -u } else { u }) + (if h & 2 != 0 { -v } else { v })
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

/// Perlin noise at `p`: zero at every lattice point, in about [-1, 1].
pub fn noise(p: Vec3A) -> f32 {
    // Reduce the coordinates so that the lattice indices stay exact.
    const PERIOD: f32 = (1u32 << 30) as f32;
    let reduce = |v: f32| if v.abs() < PERIOD { v } else { v % PERIOD };
    let (x, y, z) = (reduce(p.x), reduce(p.y), reduce(p.z));
    let (fx, fy, fz) = (x.floor(), y.floor(), z.floor());
    let (dx, dy, dz) = (x - fx, y - fy, z - fz);
    let (ix, iy, iz) = (fx as i32 & 255, fy as i32 & 255, fz as i32 & 255);
    let w000 = grad(ix, iy, iz, dx, dy, dz);
    let w100 = grad(ix + 1, iy, iz, dx - 1.0, dy, dz);
    let w010 = grad(ix, iy + 1, iz, dx, dy - 1.0, dz);
    let w110 = grad(ix + 1, iy + 1, iz, dx - 1.0, dy - 1.0, dz);
    let w001 = grad(ix, iy, iz + 1, dx, dy, dz - 1.0);
    let w101 = grad(ix + 1, iy, iz + 1, dx - 1.0, dy, dz - 1.0);
    let w011 = grad(ix, iy + 1, iz + 1, dx, dy - 1.0, dz - 1.0);
    let w111 = grad(ix + 1, iy + 1, iz + 1, dx - 1.0, dy - 1.0, dz - 1.0);
    let (wx, wy, wz) = (fade(dx), fade(dy), fade(dz));
    let x00 = lerp(wx, w000, w100);
    let x10 = lerp(wx, w010, w110);
    let x01 = lerp(wx, w001, w101);
    let x11 = lerp(wx, w011, w111);
    lerp(wz, lerp(wy, x00, x10), lerp(wy, x01, x11))
}

/// Noise on the plane z = 0.5.
pub fn noise2(x: f32, y: f32) -> f32 {
    noise(Vec3A::new(x, y, 0.5))
}

fn smooth_step(x: f32, a: f32, b: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// How many octaves the footprint (`dpdx`, `dpdy`) resolves, at most `max_octaves`.
fn octaves(dpdx: Vec3A, dpdy: Vec3A, max_octaves: u32) -> f32 {
    let len2 = dpdx.length_squared().max(dpdy.length_squared());
    let n = -1.0 - 0.5 * libm::log2f(len2);
    if n.is_nan() {
        return max_octaves as f32;
    }
    n.clamp(0.0, max_octaves as f32)
}

/// Fractional Brownian motion: octaves of noise at frequencies 1.99^i, amplitudes omega^i.
pub fn fbm(p: Vec3A, dpdx: Vec3A, dpdy: Vec3A, omega: f32, max_octaves: u32) -> f32 {
    let n = octaves(dpdx, dpdy, max_octaves);
    let whole = n.floor() as u32;
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..whole {
        sum += o * noise(lambda * p);
        lambda *= 1.99;
        o *= omega;
    }
    let partial = n - whole as f32;
    sum + o * smooth_step(partial, 0.3, 0.7) * noise(lambda * p)
}

/// Turbulence: fBm of |noise|, the octaves finer than the footprint replaced by their
/// average (0.2).
pub fn turbulence(p: Vec3A, dpdx: Vec3A, dpdy: Vec3A, omega: f32, max_octaves: u32) -> f32 {
    let n = octaves(dpdx, dpdy, max_octaves);
    let whole = n.floor() as u32;
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..whole {
        sum += o * noise(lambda * p).abs();
        lambda *= 1.99;
        o *= omega;
    }
    let partial = n - whole as f32;
    sum += o * lerp(smooth_step(partial, 0.3, 0.7), 0.2, noise(lambda * p).abs());
    for _ in whole..max_octaves {
        sum += o * 0.2;
        o *= omega;
    }
    sum
}

/// pbrt-v4's "fbm" texture.
#[derive(Debug, Clone)]
pub struct Fbm {
    pub mapping: Mapping3D,
    pub octaves: u32,
    pub roughness: f32,
}

impl Fbm {
    pub fn evaluate(&self, ctx: &TextureEvalContext) -> f32 {
        let c = self.mapping.map(ctx);
        fbm(c.p, c.dpdx, c.dpdy, self.roughness, self.octaves)
    }
}

/// pbrt-v4's "wrinkled" texture.
#[derive(Debug, Clone)]
pub struct Wrinkled {
    pub mapping: Mapping3D,
    pub octaves: u32,
    pub roughness: f32,
}

impl Wrinkled {
    pub fn evaluate(&self, ctx: &TextureEvalContext) -> f32 {
        let c = self.mapping.map(ctx);
        turbulence(c.p, c.dpdx, c.dpdy, self.roughness, self.octaves)
    }
}

/// pbrt-v4's "windy" texture: waves whose height is modulated by a broad wind pattern.
#[derive(Debug, Clone)]
pub struct Windy {
    pub mapping: Mapping3D,
}

impl Windy {
    pub fn evaluate(&self, ctx: &TextureEvalContext) -> f32 {
        let c = self.mapping.map(ctx);
        let wind = fbm(0.1 * c.p, 0.1 * c.dpdx, 0.1 * c.dpdy, 0.5, 3);
        let wave = fbm(c.p, c.dpdx, c.dpdy, 0.5, 6);
        wind.abs() * wave
    }
}

/// pbrt-v4's "marble" texture: veins from the sine of height perturbed by fBm, coloured by
/// a cubic Bézier spline through grey, white and blue-grey.
#[derive(Debug, Clone)]
pub struct Marble {
    pub mapping: Mapping3D,
    pub octaves: u32,
    pub roughness: f32,
    pub scale: f32,
    pub variation: f32,
}

const MARBLE: [[f32; 3]; 9] = [
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.5, 0.5, 0.5],
    [0.6, 0.59, 0.58],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.2, 0.2, 0.33],
    [0.58, 0.58, 0.6],
];

impl Marble {
    pub fn evaluate(&self, ctx: &TextureEvalContext) -> Color {
        let c = self.mapping.map(ctx);
        let p = c.p * self.scale;
        let m = p.y
            + self.variation
                * fbm(
                    p,
                    self.scale * c.dpdx,
                    self.scale * c.dpdy,
                    self.roughness,
                    self.octaves,
                );
        let t = 0.5 + 0.5 * libm::sinf(m);
        let first = ((t * 6.0).floor() as usize).min(5);
        let u = t * 6.0 - first as f32;
        let cp = |i: usize| crate::math::rgb(MARBLE[first + i]);
        let v = 1.0 - u;
        let rgb = cp(0) * (v * v * v)
            + cp(1) * (3.0 * v * v * u)
            + cp(2) * (3.0 * v * u * u)
            + cp(3) * (u * u * u);
        // Marble is an albedo: clamped to [0, 1] whatever uses it.
        (rgb * 1.5).clamp(Color::ZERO, Color::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_a_permutation() {
        let mut seen = [false; 256];
        for &v in &PERM {
            assert!(!seen[v as usize], "{v} twice");
            seen[v as usize] = true;
        }
    }

    #[test]
    fn noise_vanishes_on_the_lattice_and_is_bounded() {
        for i in -5..5 {
            for j in -5..5 {
                let p = Vec3A::new(i as f32, j as f32, (i * j) as f32);
                assert_eq!(noise(p), 0.0);
            }
        }
        let mut sum = 0.0;
        let mut sum2 = 0.0;
        let n = 20_000;
        for i in 0..n {
            let x = i as f32 * 0.618_034 * 7.1;
            let p = Vec3A::new(x % 97.0, (x * 1.3) % 89.0, (x * 0.7) % 83.0);
            let v = noise(p);
            assert!(v.abs() <= 1.5, "{v} at {p}");
            sum += v as f64;
            sum2 += (v * v) as f64;
        }
        let mean = sum / n as f64;
        let sd = (sum2 / n as f64 - mean * mean).sqrt();
        // Zero-mean, and not degenerate.
        assert!(mean.abs() < 0.02 && sd > 0.1, "mean {mean}, sd {sd}");
    }

    #[test]
    fn noise_is_continuous() {
        let p = Vec3A::new(3.3, 7.7, 1.1);
        let e = 1e-3;
        for d in [Vec3A::X, Vec3A::Y, Vec3A::Z] {
            assert!((noise(p + d * e) - noise(p)).abs() < 0.01);
        }
    }

    #[test]
    fn fbm_drops_octaves_finer_than_the_footprint() {
        let p = Vec3A::new(0.3, 0.4, 0.5);
        // A footprint of 1 unit resolves no octave: 0 whole octaves, the first fades.
        let wide = Vec3A::new(1.0, 0.0, 0.0);
        assert_eq!(fbm(p, wide, wide, 0.5, 8), 0.0);
        // A tiny footprint resolves them all; turbulence then has no 0.2 fill-in.
        let tiny = Vec3A::splat(1e-9);
        let all: f32 = (0..8)
            .map(|i| 0.5f32.powi(i) * noise(1.99f32.powi(i) * p))
            .sum();
        assert!((fbm(p, tiny, tiny, 0.5, 8) - all).abs() < 1e-5);
        // Turbulence with nothing resolved is the fill-in: 0.2 + 0.2 * (sum of the rest).
        let t = turbulence(p, wide, wide, 0.5, 2);
        assert!((t - (0.2 + 0.2 * 1.0 + 0.2 * 0.5)).abs() < 1e-6, "{t}");
    }
}
