//! pbrt-v4's G-buffer film: beside each pixel's radiance, what its camera samples first saw
//! (reflectance, position, depth derivatives, normals, uv) and the variance of their
//! radiance, accumulated per pixel in sample order so that a pixel's channels depend on
//! nothing but its own samples (the same bytes for any tiling, thread count or worker).

use crate::math::Color;
use glam::{Affine3A, Vec2, Vec3A};
use kiln_scene::{GBUFFER_CHANNELS, GBufferSpace};

/// The first surface with a BSDF that a camera ray reached before any scattering, in world
/// space (pbrt-v4's `VisibleSurface`).
#[derive(Debug, Clone, Copy)]
pub struct VisibleSurface {
    pub p: Vec3A,
    /// Geometric and shading normals (the shading one after bump or normal mapping).
    pub ng: Vec3A,
    pub ns: Vec3A,
    pub uv: Vec2,
    /// The BSDF's directional reflectance toward the camera (pbrt-v4's `rho`).
    pub albedo: Color,
    /// How the point moves from one pixel to the next, on its tangent plane: filled in by
    /// the caller that knows the camera.
    pub dpdx: Vec3A,
    pub dpdy: Vec3A,
}

impl VisibleSurface {
    /// This surface in another space: points and vectors by `xf`, normals by its inverse
    /// transpose.
    pub fn transformed(&self, xf: &Affine3A) -> VisibleSurface {
        let normals = crate::motion::normal_matrix(xf);
        VisibleSurface {
            p: xf.transform_point3a(self.p),
            ng: normals * self.ng,
            ns: normals * self.ns,
            dpdx: xf.transform_vector3a(self.dpdx),
            dpdy: xf.transform_vector3a(self.dpdy),
            ..*self
        }
    }
}

/// Fixed samples for the reflectance estimate: pbrt-v4 uses 16 fixed samples too, so the
/// estimate is the same for every pixel and exact for Lambertian surfaces.
pub const RHO_SAMPLES: usize = 16;

/// The i-th reflectance sample: (u for the lobe choice, u for the direction), a shifted
/// Hammersley set.
pub fn rho_sample(i: usize) -> (f32, Vec2) {
    let x = (i as f32 + 0.5) / RHO_SAMPLES as f32;
    let y = (i as u32).reverse_bits() as f32 / 4_294_967_296.0 + 0.5 / RHO_SAMPLES as f32;
    let uc = ((i * 7 + 3) % RHO_SAMPLES) as f32 / RHO_SAMPLES as f32 + 0.5 / RHO_SAMPLES as f32;
    (uc, Vec2::new(x, y.fract()))
}

/// Where each G-buffer channel lands in a pixel's channel values: the order of the names
/// as an image stores them (sorted).
#[derive(Debug, Clone)]
pub struct GBufferLayout {
    /// The output's space from world space (camera space, or the identity for world).
    pub space: GBufferSpace,
    /// For each of [`GBUFFER_CHANNELS`], its index among the sorted names.
    slot: [usize; GBUFFER_CHANNELS.len()],
}

impl GBufferLayout {
    pub fn new(space: GBufferSpace) -> GBufferLayout {
        let mut sorted = GBUFFER_CHANNELS;
        sorted.sort();
        GBufferLayout {
            space,
            slot: GBUFFER_CHANNELS.map(|n| sorted.iter().position(|s| *s == n).unwrap()),
        }
    }

    /// The channel names, sorted (as images hold them).
    pub fn names(&self) -> Vec<String> {
        let mut sorted = GBUFFER_CHANNELS.map(String::from).to_vec();
        sorted.sort();
        sorted
    }

    pub fn channels(&self) -> usize {
        GBUFFER_CHANNELS.len()
    }
}

/// One pixel's G-buffer sums as its samples arrive, in sample order (pbrt-v4's
/// `GBufferFilm::Pixel`).
#[derive(Debug, Clone, Default)]
pub struct GBufferPixel {
    /// Filter weights of every sample, and of those that saw a surface.
    weight_sum: f64,
    surface_weight_sum: f64,
    p: [f64; 3],
    n: [f64; 3],
    ns: [f64; 3],
    dzdx: f64,
    dzdy: f64,
    uv: [f64; 2],
    albedo: [f64; 3],
    /// Welford's running mean and sum of squares of the surface samples' radiance.
    count: u64,
    mean: [f64; 3],
    m2: [f64; 3],
}

impl GBufferPixel {
    /// Adds a sample: its output radiance `rgb`, filter weight, and what it saw (in the
    /// output's space, [`VisibleSurface::transformed`]).
    pub fn add(&mut self, rgb: Color, weight: f32, seen: Option<&VisibleSurface>) {
        let w = weight as f64;
        self.weight_sum += w;
        let Some(s) = seen else {
            return;
        };
        self.surface_weight_sum += w;
        self.count += 1;
        for c in 0..3 {
            let x = rgb[c] as f64;
            let delta = x - self.mean[c];
            self.mean[c] += delta / self.count as f64;
            self.m2[c] += delta * (x - self.mean[c]);
        }
        for c in 0..3 {
            self.p[c] += w * s.p[c] as f64;
            self.n[c] += w * s.ng[c] as f64;
            self.ns[c] += w * s.ns[c] as f64;
            self.albedo[c] += w * s.albedo[c] as f64;
        }
        self.dzdx += w * s.dpdx.z as f64;
        self.dzdy += w * s.dpdy.z as f64;
        self.uv[0] += w * s.uv.x as f64;
        self.uv[1] += w * s.uv.y as f64;
    }

    /// The number of 64-bit values [`GBufferPixel::to_bits`] gives.
    pub const BITS: usize = 25;

    /// Every running sum, bit for bit (f64s by their bits, the count as it is), so that a
    /// pixel can be carried between passes and continued with the same bytes.
    pub fn to_bits(&self) -> [u64; Self::BITS] {
        let floats = [self.weight_sum, self.surface_weight_sum]
            .into_iter()
            .chain(self.p)
            .chain(self.n)
            .chain(self.ns)
            .chain([self.dzdx, self.dzdy])
            .chain(self.uv)
            .chain(self.albedo);
        let rest = self.mean.into_iter().chain(self.m2);
        let bits: Vec<u64> = floats
            .map(f64::to_bits)
            .chain([self.count])
            .chain(rest.map(f64::to_bits))
            .collect();
        bits.try_into().expect("25 values")
    }

    /// The pixel [`GBufferPixel::to_bits`] gave these bits for.
    pub fn from_bits(b: &[u64; Self::BITS]) -> GBufferPixel {
        let f = |i: usize| f64::from_bits(b[i]);
        let v3 = |i: usize| [f(i), f(i + 1), f(i + 2)];
        GBufferPixel {
            weight_sum: f(0),
            surface_weight_sum: f(1),
            p: v3(2),
            n: v3(5),
            ns: v3(8),
            dzdx: f(11),
            dzdy: f(12),
            uv: [f(13), f(14)],
            albedo: v3(15),
            count: b[18],
            mean: v3(19),
            m2: v3(22),
        }
    }

    /// The pixel's channel values, in `layout`'s order, as pbrt-v4 writes them: albedo over
    /// every sample's weight; position, uv and depth derivatives (their magnitudes) over the
    /// weight of the samples that saw a surface; normals normalised; variance and relative
    /// variance (variance over mean) of the surface samples' radiance.
    pub fn finish(&self, layout: &GBufferLayout, out: &mut [f32]) {
        let over = |v: f64, w: f64| if w != 0.0 { v / w } else { v };
        let unit = |v: [f64; 3]| {
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if l > 0.0 { v.map(|x| x / l) } else { [0.0; 3] }
        };
        let (n, ns) = (unit(self.n), unit(self.ns));
        let sw = self.surface_weight_sum;
        let variance = |c: usize| {
            if self.count > 1 {
                self.m2[c] / (self.count - 1) as f64
            } else {
                0.0
            }
        };
        let relative = |c: usize| {
            if self.count < 1 || self.mean[c] == 0.0 {
                0.0
            } else {
                variance(c) / self.mean[c]
            }
        };
        let values: [f64; GBUFFER_CHANNELS.len()] = [
            over(self.albedo[0], self.weight_sum),
            over(self.albedo[1], self.weight_sum),
            over(self.albedo[2], self.weight_sum),
            over(self.p[0], sw),
            over(self.p[1], sw),
            over(self.p[2], sw),
            over(self.dzdx, sw).abs(),
            over(self.dzdy, sw).abs(),
            n[0],
            n[1],
            n[2],
            ns[0],
            ns[1],
            ns[2],
            over(self.uv[0], sw),
            over(self.uv[1], sw),
            variance(0),
            variance(1),
            variance(2),
            relative(0),
            relative(1),
            relative(2),
        ];
        for (i, v) in values.iter().enumerate() {
            out[layout.slot[i]] = *v as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rho_samples_are_in_the_unit_square_and_stratified() {
        let mut xs: Vec<f32> = (0..RHO_SAMPLES).map(|i| rho_sample(i).1.x).collect();
        let mut ucs: Vec<f32> = (0..RHO_SAMPLES).map(|i| rho_sample(i).0).collect();
        for v in [&mut xs, &mut ucs] {
            v.sort_by(f32::total_cmp);
            for (i, x) in v.iter().enumerate() {
                assert!((*x - (i as f32 + 0.5) / RHO_SAMPLES as f32).abs() < 1e-6);
            }
        }
        assert!((0..RHO_SAMPLES).all(|i| (0.0..1.0).contains(&rho_sample(i).1.y)));
    }

    /// Welford's variance equals the two-pass one; surface channels average over the
    /// samples that saw a surface, albedo over all of them.
    #[test]
    fn a_pixel_averages_as_pbrt_v4_does() {
        let layout = GBufferLayout::new(GBufferSpace::World);
        let mut px = GBufferPixel::default();
        let seen = VisibleSurface {
            p: Vec3A::new(1.0, 2.0, 3.0),
            ng: Vec3A::new(0.0, 0.0, -2.0),
            ns: Vec3A::new(0.0, 1.0, 0.0),
            uv: Vec2::new(0.25, 0.75),
            albedo: crate::math::rgb3(0.5, 0.4, 0.3),
            dpdx: Vec3A::new(0.1, 0.0, -0.2),
            dpdy: Vec3A::ZERO,
        };
        let values = [1.0f32, 3.0, 8.0];
        for v in values {
            px.add(Color::splat(v), 1.0, Some(&seen));
        }
        px.add(Color::splat(100.0), 1.0, None);
        let mut out = [0.0f32; GBUFFER_CHANNELS.len()];
        px.finish(&layout, &mut out);
        let names = layout.names();
        let get = |n: &str| out[names.iter().position(|s| s == n).unwrap()];
        let mean = 4.0f32;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / 2.0;
        assert!((get("Variance.G") - var).abs() < 1e-5);
        assert!((get("RelativeVariance.B") - var / mean).abs() < 1e-5);
        assert_eq!(get("P.Y"), 2.0);
        assert_eq!(get("u"), 0.25);
        assert_eq!(get("N.Z"), -1.0);
        assert_eq!(get("Albedo.R"), 0.5 * 3.0 / 4.0);
        assert!((get("dzdx") - 0.2).abs() < 1e-6);
    }
}
