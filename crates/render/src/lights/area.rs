//! Diffuse area lights: a shape that emits constant radiance from its surface, one light per
//! emitting triangle (so the light sampler chooses faces by power), per sphere or per
//! quadric (disk, cylinder, partial or transformed sphere).

use super::LightSample;
use crate::math::{Color, luminance};
use crate::sampling::{cosine_hemisphere, uniform_sphere, uniform_triangle};
use crate::shapes::Geometry;
use crate::shapes::quadric::QuadricPoint;
use crate::shapes::sphere::{Rotation, sample_sphere, sphere_pdf, sphere_uv};
use crate::shapes::triangle::{sample_triangle, triangle_pdf};
use glam::{Vec2, Vec3A};
use kiln_scene::textures::TextureImage;
use std::f32::consts::PI;
use std::sync::Arc;

/// One emitting triangle; `n` is its emitting side.
#[derive(Debug, Clone)]
pub struct TriangleLight {
    pub p: [Vec3A; 3],
    pub n: Vec3A,
    pub area: f32,
    /// The radiance, or with an image the scale that multiplies it.
    pub radiance: Color,
    pub two_sided: bool,
    /// The triangle's surface coordinates at its corners (pbrt's defaults without uvs).
    pub uv: [Vec2; 3],
    /// The shape's alpha texture (an index into the geometry's): where alpha masks the
    /// surface it emits nothing, as in pbrt-v4.
    pub alpha: Option<u32>,
    /// An "invisible" light (see [`SphereLight::invisible`]).
    pub invisible: bool,
    /// pbrt-v4's emission image: the radiance at a point is the image there, times `radiance`.
    pub image: Option<Arc<EmissionImage>>,
}

/// An area light's emission image (pbrt-v4's `DiffuseAreaLight` with `filename`): linear
/// RGB looked up at (u, 1 − v), bilinearly, clamped at the edges.
#[derive(Debug)]
pub struct EmissionImage {
    image: Arc<TextureImage>,
    /// The mean over all pixels, for the light's power.
    mean: Color,
}

impl EmissionImage {
    pub fn new(image: Arc<TextureImage>) -> EmissionImage {
        let (w, h) = (image.width, image.height);
        let mut sum = [0.0f64; 3];
        for y in 0..h {
            for x in 0..w {
                for (c, s) in sum.iter_mut().enumerate() {
                    *s += f64::from(image.channel(x, y, c as u32).max(0.0));
                }
            }
        }
        let n = f64::from(w) * f64::from(h);
        let mean = crate::math::rgb3(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
        );
        EmissionImage { image, mean }
    }

    /// The luminance of the image's mean.
    pub fn mean_luminance(&self) -> f32 {
        luminance(self.mean)
    }

    /// The image's radiance at surface coordinates `uv`.
    pub fn lookup(&self, uv: Vec2) -> Color {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = (1.0 - uv.y) * h as f32 - 0.5;
        let (xf, yf) = (x.floor(), y.floor());
        let (dx, dy) = (x - xf, y - yf);
        let texel = |xi: i64, yi: i64| {
            let (xi, yi) = (xi.clamp(0, w - 1) as u32, yi.clamp(0, h - 1) as u32);
            crate::math::rgb3(
                self.image.channel(xi, yi, 0),
                self.image.channel(xi, yi, 1),
                self.image.channel(xi, yi, 2),
            )
        };
        // Float to integer casts saturate, so a huge or NaN coordinate clamps to an edge.
        let (xi, yi) = (xf as i64, yf as i64);
        let v = texel(xi, yi) * ((1.0 - dx) * (1.0 - dy))
            + texel(xi.saturating_add(1), yi) * (dx * (1.0 - dy))
            + texel(xi, yi.saturating_add(1)) * ((1.0 - dx) * dy)
            + texel(xi.saturating_add(1), yi.saturating_add(1)) * (dx * dy);
        v.max(Color::ZERO)
    }
}

/// Whether alpha texture `alpha` masks the point `p` with surface coordinates `uv`: alpha 0
/// always, 1 never, and between, by a hash of the point (pbrt-v4's AlphaMasked).
pub fn alpha_masked(geometry: &Geometry, alpha: u32, p: Vec3A, n: Vec3A, uv: Vec2) -> bool {
    let ctx = crate::textures::TextureEvalContext {
        p,
        n,
        uv,
        ..Default::default()
    };
    let a = geometry.prims.alphas[alpha as usize].evaluate(&ctx);
    if a >= 1.0 {
        return false;
    }
    a <= 0.0 || crate::shapes::hash_float(p, Vec3A::ZERO) > a
}

/// An emitting sphere; `inward` when ReverseOrientation turned its emitting side inwards.
#[derive(Debug, Clone)]
pub struct SphereLight {
    pub center: Vec3A,
    pub radius: f32,
    pub radiance: Color,
    pub two_sided: bool,
    pub inward: bool,
    /// The shape's alpha texture: where it masks the surface the sphere emits nothing.
    pub alpha: Option<u32>,
    /// pbrt-v4's "invisible area light": a shape whose alpha is the constant 0 emits in
    /// full (its alpha dropped), while every ray passes through it, so only light samples
    /// find its light, each counted whole.
    pub invisible: bool,
    /// The sphere's rotation, by which its (u, v) turn (for the alpha texture).
    pub rotation: Rotation,
}

/// A point on an area light from which photons leave: position, emitting normal, radiance,
/// the light's whole area and whether it emits on both sides.
pub struct EmissionPoint {
    pub p: Vec3A,
    pub n: Vec3A,
    pub radiance: Color,
    pub area: f32,
    pub two_sided: bool,
}

impl EmissionPoint {
    /// A photon leaving the point in a cosine-distributed direction (on a side chosen by
    /// `uc` for a two-sided light): flux = L A pi, twice that for two sides.
    pub fn emit(self, u: Vec2, uc: f32) -> Option<super::EmittedRay> {
        if self.radiance == Color::ZERO || self.area <= 0.0 {
            return None;
        }
        let (n, sides) = match (self.two_sided, uc < 0.5) {
            (false, _) => (self.n, 1.0),
            (true, true) => (self.n, 2.0),
            (true, false) => (-self.n, 2.0),
        };
        Some(super::EmittedRay {
            origin: self.p,
            dir: crate::math::Frame::from_z(n).to_world(cosine_hemisphere(u)),
            n,
            flux: self.radiance * (self.area * PI * sides),
        })
    }
}

/// Radiance leaving a diffuse emitter's point with normal `n` in direction `w`.
/// Whether a diffuse emitter with normal `n` sends light in direction `w`.
fn emits_toward(two_sided: bool, n: Vec3A, w: Vec3A) -> bool {
    two_sided || n.dot(w) > 0.0
}

fn diffuse_le(radiance: Color, two_sided: bool, n: Vec3A, w: Vec3A) -> Color {
    if emits_toward(two_sided, n, w) {
        radiance
    } else {
        Color::ZERO
    }
}

fn sides(two_sided: bool) -> f32 {
    if two_sided { 2.0 } else { 1.0 }
}

/// The power (luminance) of a diffuse emitter of `area` emitting `radiance`, or that times
/// an emission image's mean.
fn diffuse_power(
    radiance: Color,
    image: Option<&EmissionImage>,
    area: f32,
    two_sided: bool,
) -> f32 {
    let radiance = image.map_or(radiance, |i| radiance * i.mean);
    PI * area * luminance(radiance) * sides(two_sided)
}

impl TriangleLight {
    /// A one-sided (or two-sided) emitter facing `n`, for the light hierarchy.
    pub fn bounds(&self, power: f32) -> super::LightBounds {
        let [a, b, c] = self.p;
        super::LightBounds::diffuse(
            a.min(b).min(c),
            a.max(b).max(c),
            self.n,
            1.0,
            power,
            self.two_sided,
        )
    }

    pub fn power(&self) -> f32 {
        diffuse_power(
            self.radiance,
            self.image.as_deref(),
            self.area,
            self.two_sided,
        )
    }

    /// Radiance leaving the triangle's point `q` (normal `n`) in direction `w`.
    pub fn le(&self, geometry: &Geometry, q: Vec3A, n: Vec3A, w: Vec3A) -> Color {
        if !emits_toward(self.two_sided, n, w) {
            return Color::ZERO;
        }
        self.emitted(geometry, q)
    }

    /// Radiance at the triangle's point `q` on its emitting side(s): zero where alpha masks
    /// it, the image there if it has one.
    fn emitted(&self, geometry: &Geometry, q: Vec3A) -> Color {
        if self.alpha.is_none() && self.image.is_none() {
            return self.radiance;
        }
        let b = crate::shapes::triangle::barycentrics(q, self.p[0], self.p[1], self.p[2]);
        let uv = self.uv[0] * b[0] + self.uv[1] * b[1] + self.uv[2] * b[2];
        if let Some(alpha) = self.alpha
            && alpha_masked(geometry, alpha, q, self.n, uv)
        {
            return Color::ZERO;
        }
        match &self.image {
            Some(image) => self.radiance * image.lookup(uv),
            None => self.radiance,
        }
    }

    pub fn sample(&self, geometry: &Geometry, p: Vec3A, u: Vec2) -> Option<LightSample> {
        let (point, _) = sample_triangle(&self.p, self.n, self.area, p, u)?;
        let q = p + point.wi * point.distance;
        let radiance = self.le(geometry, q, self.n, -point.wi);
        (radiance != Color::ZERO).then(|| LightSample::on_surface(point, radiance))
    }

    pub fn pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        triangle_pdf(self.area, p, wi, q, n)
    }

    pub fn emission_point(&self, geometry: &Geometry, u: Vec2) -> EmissionPoint {
        let b = uniform_triangle(u);
        let p = self.p[0] * b[0] + self.p[1] * b[1] + self.p[2] * b[2];
        EmissionPoint {
            p,
            n: self.n,
            radiance: self.emitted(geometry, p),
            area: self.area,
            two_sided: self.two_sided,
        }
    }
}

impl SphereLight {
    pub fn power(&self) -> f32 {
        PI * 4.0 * PI * self.radius * self.radius * luminance(self.radiance) * sides(self.two_sided)
    }

    /// Radiance leaving the sphere's point `q` (normal `n`, oriented as its emitting side
    /// is) in direction `w`.
    pub fn le(&self, geometry: &Geometry, q: Vec3A, n: Vec3A, w: Vec3A) -> Color {
        if self.masked(geometry, q) {
            return Color::ZERO;
        }
        diffuse_le(self.radiance, self.two_sided, n, w)
    }

    /// Whether alpha masks the sphere's point `q` (its uv as hits on it get them).
    fn masked(&self, geometry: &Geometry, q: Vec3A) -> bool {
        let Some(alpha) = self.alpha else {
            return false;
        };
        let n = ((q - self.center) / self.radius).normalize_or_zero();
        alpha_masked(geometry, alpha, q, n, sphere_uv(self.rotation.to_object(n)))
    }

    pub fn sample(&self, geometry: &Geometry, p: Vec3A, u: Vec2) -> Option<LightSample> {
        let mut point = sample_sphere(self.center, self.radius, p, u)?;
        if self.inward {
            point.n = -point.n;
        }
        let q = p + point.wi * point.distance;
        let radiance = self.le(geometry, q, point.n, -point.wi);
        (radiance != Color::ZERO).then(|| LightSample::on_surface(point, radiance))
    }

    pub fn pdf(&self, p: Vec3A, wi: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
        sphere_pdf(self.center, self.radius, p, wi, q, n)
    }

    pub fn emission_point(&self, geometry: &Geometry, u: Vec2) -> EmissionPoint {
        let d = uniform_sphere(u);
        let p = self.center + d * self.radius;
        EmissionPoint {
            p,
            n: if self.inward { -d } else { d },
            radiance: if self.masked(geometry, p) {
                Color::ZERO
            } else {
                self.radiance
            },
            area: 4.0 * PI * self.radius * self.radius,
            two_sided: self.two_sided,
        }
    }
}

/// An emitting quadric (a disk, a cylinder, a partial or transformed sphere), sampled
/// uniformly by area; `n` of its points is its emitting side.
#[derive(Debug, Clone)]
pub struct QuadricLight {
    /// Index into the geometry's quadrics.
    pub quadric: u32,
    /// The radiance, or with an image the scale that multiplies it.
    pub radiance: Color,
    pub two_sided: bool,
    /// World-space area.
    pub area: f32,
    pub alpha: Option<u32>,
    /// An "invisible" light (see [`SphereLight::invisible`]).
    pub invisible: bool,
    pub image: Option<Arc<EmissionImage>>,
}

impl QuadricLight {
    pub fn power(&self) -> f32 {
        diffuse_power(
            self.radiance,
            self.image.as_deref(),
            self.area,
            self.two_sided,
        )
    }

    /// Radiance leaving the quadric's point `q` (normal `n`, oriented as hits are) in
    /// direction `w`.
    pub fn le(&self, geometry: &Geometry, q: Vec3A, n: Vec3A, w: Vec3A) -> Color {
        if !emits_toward(self.two_sided, n, w) {
            return Color::ZERO;
        }
        self.emitted(
            geometry,
            &geometry.prims.quadrics[self.quadric as usize].point_at(q),
        )
    }

    fn emitted(&self, geometry: &Geometry, at: &QuadricPoint) -> Color {
        if let Some(alpha) = self.alpha
            && alpha_masked(geometry, alpha, at.p, at.n, at.uv)
        {
            return Color::ZERO;
        }
        match &self.image {
            Some(image) => self.radiance * image.lookup(at.uv),
            None => self.radiance,
        }
    }

    pub fn sample(&self, geometry: &Geometry, p: Vec3A, u: Vec2) -> Option<LightSample> {
        let quadric = &geometry.prims.quadrics[self.quadric as usize];
        let (q, point) = quadric.sample_from(p, u)?;
        if !self.two_sided && q.n.dot(point.wi) >= 0.0 {
            return None;
        }
        let radiance = self.emitted(geometry, &q);
        (radiance != Color::ZERO).then(|| LightSample::on_surface(point, radiance))
    }

    pub fn pdf(&self, geometry: &Geometry, p: Vec3A, wi: Vec3A, q: Vec3A) -> f32 {
        geometry.prims.quadrics[self.quadric as usize].solid_angle_pdf(p, wi, q)
    }

    /// A photon's starting point. Its `area` is the reciprocal of the sampled point's area
    /// density, which under a non-uniform scale varies over the surface.
    pub fn emission_point(&self, geometry: &Geometry, u: Vec2) -> EmissionPoint {
        let (q, area_pdf) = geometry.prims.quadrics[self.quadric as usize].sample(u);
        EmissionPoint {
            p: q.p,
            n: q.n,
            radiance: self.emitted(geometry, &q),
            area: if area_pdf > 0.0 { 1.0 / area_pdf } else { 0.0 },
            two_sided: self.two_sided,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::PixelSampler;

    /// The pdf a light reports for a direction must be the density its sampler produces:
    /// integrating 1/pdf over samples estimates the subtended solid angle.
    #[test]
    fn sphere_and_triangle_pdfs_integrate_to_their_solid_angle() {
        let sphere = SphereLight {
            center: Vec3A::new(0.0, 0.0, 5.0),
            radius: 1.0,
            radiance: Color::ONE,
            two_sided: false,
            inward: false,
            alpha: None,
            invisible: false,
            rotation: Rotation::IDENTITY,
        };
        let geometry = Geometry::new(Default::default());
        let n = 4096;
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = PixelSampler::new(0, 0, i, 2);
            let ls = sphere
                .sample(&geometry, Vec3A::ZERO, Vec2::new(s.value(0), s.value(1)))
                .unwrap();
            let q = ls.wi * ls.distance;
            let pdf = sphere.pdf(Vec3A::ZERO, ls.wi, q, ls.n);
            assert!((pdf - ls.pdf).abs() < 1e-3 * pdf);
            sum += 1.0 / ls.pdf as f64;
        }
        let expected = 2.0 * std::f64::consts::PI * (1.0 - (1.0f64 - 1.0 / 25.0).sqrt());
        assert!(((sum / n as f64) - expected).abs() < 1e-4 * expected.max(1.0));

        let tri = TriangleLight {
            p: [
                Vec3A::new(-1.0, -1.0, 2.0),
                Vec3A::new(1.0, -1.0, 2.0),
                Vec3A::new(0.0, 1.0, 2.0),
            ],
            n: -Vec3A::Z,
            area: 2.0,
            radiance: Color::ONE,
            two_sided: false,
            uv: [Vec2::ZERO, Vec2::X, Vec2::ONE],
            alpha: None,
            invisible: false,
            image: None,
        };
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = PixelSampler::new(1, 0, i, 2);
            let ls = tri
                .sample(&geometry, Vec3A::ZERO, Vec2::new(s.value(0), s.value(1)))
                .unwrap();
            sum += 1.0 / ls.pdf as f64;
        }
        // Solid angle of the triangle by a fine numerical integral over its area.
        let mut omega = 0.0f64;
        let m = 400;
        for i in 0..m {
            for j in 0..m {
                let u = Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                let b = uniform_triangle(u);
                let q = Vec3A::new(-1.0, -1.0, 2.0) * b[0]
                    + Vec3A::new(1.0, -1.0, 2.0) * b[1]
                    + Vec3A::new(0.0, 1.0, 2.0) * b[2];
                omega += (2.0 * q.z / q.length().powi(3)) as f64 / (m * m) as f64;
            }
        }
        assert!(
            ((sum / n as f64) - omega).abs() < 0.01 * omega,
            "{} vs {omega}",
            sum / n as f64
        );
    }

    #[test]
    fn one_sided_area_lights_emit_on_their_normal_side() {
        let tri = TriangleLight {
            p: [Vec3A::ZERO, Vec3A::X, Vec3A::Y],
            n: Vec3A::Z,
            area: 0.5,
            radiance: Color::ONE,
            two_sided: false,
            uv: [Vec2::ZERO, Vec2::X, Vec2::ONE],
            alpha: None,
            invisible: false,
            image: None,
        };
        let g = Geometry::new(Default::default());
        let q = Vec3A::new(0.2, 0.2, 0.0);
        assert_eq!(tri.le(&g, q, Vec3A::Z, Vec3A::Z), Color::ONE);
        assert_eq!(tri.le(&g, q, Vec3A::Z, -Vec3A::Z), Color::ZERO);
        assert!(
            tri.sample(&g, Vec3A::new(0.2, 0.2, -1.0), Vec2::splat(0.3))
                .is_none()
        );
    }
}
