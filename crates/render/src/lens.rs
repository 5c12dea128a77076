//! pbrt-v4's realistic camera: a lens system of spherical interfaces and an aperture stop,
//! focused by a thick-lens approximation, and rays traced from the film through it toward
//! the exit pupil, whose bounds are found once per ring of the film. Each ray carries the
//! weight pbrt-v4 gives it (the aperture image's value, cos⁴θ over the pupil density and the
//! rear element's squared distance), so images are as bright as pbrt-v4's.
//!
//! Lens space is pbrt-v4's: the film at z = 0, the lens toward −z; camera space flips z.
//! Traced in f64: a ray crosses a dozen interfaces.

use crate::math::solve_quadratic;
use glam::{DVec3, Vec2, Vec3A};
use kiln_scene::{ApertureImage, RealisticLens};
use rayon::prelude::*;

#[derive(Debug, Clone, Copy)]
struct Element {
    /// Metres; 0 for the aperture stop.
    curvature_radius: f64,
    thickness: f64,
    /// The index of refraction behind the interface (0: air, at the stop).
    eta: f64,
    aperture_radius: f64,
}

/// Rings of the film over which exit pupil bounds are found (pbrt-v4's count).
const PUPIL_RINGS: usize = 64;
/// Points tried on the rear element per ring (pbrt-v4 tries 2^20; fewer points widen the
/// bounds by their spacing, which costs noise, never bias).
const PUPIL_SAMPLES: usize = 1 << 16;

#[derive(Debug, Clone)]
pub struct LensSystem {
    elements: Vec<Element>,
    /// Half the film's physical width and height (metres).
    half_extent: (f64, f64),
    diagonal: f64,
    /// Per ring: [xmin, ymin, xmax, ymax] on the rear element's plane, or None where no ray
    /// gets through.
    pupil: Vec<Option<[f64; 4]>>,
    aperture: Option<ApertureImage>,
}

/// Refraction of the unit direction `wi` (pointing away from the interface) through the
/// normal `n` with relative index `eta`, by the BSDFs' refraction (in f32, as pbrt-v4 traces
/// its lenses); None at total internal reflection.
fn refract(wi: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let f = |v: DVec3| Vec3A::new(v.x as f32, v.y as f32, v.z as f32);
    let (wt, _) = crate::bsdfs::refract(f(wi), f(n), eta as f32)?;
    Some(DVec3::new(
        f64::from(wt.x),
        f64::from(wt.y),
        f64::from(wt.z),
    ))
}

/// The ray's hit on the sphere of `radius` about (0, 0, z_center): the nearer or farther
/// root as the ray's direction and the curvature say, and the normal facing the ray.
fn intersect_element(radius: f64, z_center: f64, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    let oc = o - DVec3::new(0.0, 0.0, z_center);
    let a = d.length_squared();
    let b = 2.0 * d.dot(oc);
    let c = oc.length_squared() - radius * radius;
    let (t0, t1) = solve_quadratic(a, b, c, b * b - 4.0 * a * c)?;
    let closer = (d.z > 0.0) ^ (radius < 0.0);
    let t = if closer { t0 } else { t1 };
    if t < 0.0 {
        return None;
    }
    let n = (oc + t * d).normalize();
    Some((t, if n.dot(-d) < 0.0 { -n } else { n }))
}

/// Where the ray meets interface `e` whose vertex is at `z`: the ray parameter and, off the
/// stop, the normal facing the ray; None where it misses or the stop's plane is behind it.
fn meet(e: &Element, z: f64, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    if e.curvature_radius == 0.0 {
        let t = (z - o.z) / d.z;
        (!t.is_nan() && t >= 0.0).then_some((t, DVec3::ZERO))
    } else {
        intersect_element(e.curvature_radius, z + e.curvature_radius, o, d)
    }
}

fn radical_inverse(base: u64, mut i: u64) -> f64 {
    let inv = 1.0 / base as f64;
    let (mut f, mut r) = (inv, 0.0);
    while i > 0 {
        r += (i % base) as f64 * f;
        i /= base;
        f *= inv;
    }
    r
}

impl LensSystem {
    /// The lens as the scene describes it, focused at its focus distance, for a film of
    /// `xres` x `yres` pixels and `diagonal` metres; an error when it cannot focus there.
    pub fn new(
        lens: &RealisticLens,
        xres: u32,
        yres: u32,
        diagonal: f64,
    ) -> Result<LensSystem, String> {
        let mut elements: Vec<Element> = lens
            .elements
            .iter()
            .map(|e| {
                let mut aperture = e[3] / 1000.0;
                if e[0] == 0.0 {
                    aperture = aperture.min(lens.aperture_diameter / 1000.0);
                }
                Element {
                    curvature_radius: e[0] / 1000.0,
                    thickness: e[1] / 1000.0,
                    eta: e[2],
                    aperture_radius: aperture / 2.0,
                }
            })
            .collect();
        let aspect = f64::from(yres) / f64::from(xres);
        let x = (diagonal * diagonal / (1.0 + aspect * aspect)).sqrt();
        let mut system = LensSystem {
            elements: elements.clone(),
            half_extent: (x / 2.0, aspect * x / 2.0),
            diagonal,
            pupil: Vec::new(),
            aperture: lens.aperture.clone(),
        };
        let film_distance = system.focus_thick_lens(lens.focus_distance)?;
        elements
            .last_mut()
            .expect("a lens has interfaces")
            .thickness = film_distance;
        system.elements = elements;
        system.pupil = (0..PUPIL_RINGS)
            .into_par_iter()
            .map(|i| {
                let r0 = i as f64 / PUPIL_RINGS as f64 * diagonal / 2.0;
                let r1 = (i + 1) as f64 / PUPIL_RINGS as f64 * diagonal / 2.0;
                system.bound_exit_pupil(r0, r1)
            })
            .collect();
        if system.pupil.iter().all(Option::is_none) {
            return Err(
                "no ray from the film gets through this lens system (is the aperture stop closed?)"
                    .into(),
            );
        }
        Ok(system)
    }

    fn rear_z(&self) -> f64 {
        self.elements.last().map_or(0.0, |e| e.thickness)
    }

    fn front_z(&self) -> f64 {
        self.elements.iter().map(|e| e.thickness).sum()
    }

    /// Traces a camera-space ray from the film out through the lens; the camera-space ray
    /// leaving the front and the aperture's weight, or None where the lens stops it.
    fn trace_from_film(&self, o: DVec3, d: DVec3) -> Option<(DVec3, DVec3, f64)> {
        let (mut o, mut d) = (DVec3::new(o.x, o.y, -o.z), DVec3::new(d.x, d.y, -d.z));
        let (mut z, mut weight) = (0.0, 1.0);
        for i in (0..self.elements.len()).rev() {
            let e = self.elements[i];
            z -= e.thickness;
            let stop = e.curvature_radius == 0.0;
            let (t, n) = meet(&e, z, o, d)?;
            let p = o + t * d;
            match (&self.aperture, stop) {
                (Some(image), true) => {
                    let uv = Vec2::new(
                        ((p.x / e.aperture_radius + 1.0) / 2.0) as f32,
                        ((p.y / e.aperture_radius + 1.0) / 2.0) as f32,
                    );
                    weight = f64::from(bilerp_black(image, uv));
                    if weight == 0.0 {
                        return None;
                    }
                }
                _ => {
                    if p.x * p.x + p.y * p.y > e.aperture_radius * e.aperture_radius {
                        return None;
                    }
                }
            }
            o = p;
            if !stop {
                let eta_i = if e.eta != 0.0 { e.eta } else { 1.0 };
                let eta_t = if i > 0 && self.elements[i - 1].eta != 0.0 {
                    self.elements[i - 1].eta
                } else {
                    1.0
                };
                d = refract((-d).normalize(), n, eta_t / eta_i)?;
            }
        }
        Some((
            DVec3::new(o.x, o.y, -o.z),
            DVec3::new(d.x, d.y, -d.z),
            weight,
        ))
    }

    /// Traces a camera-space ray from the scene in through the lens (the aperture's shape
    /// aside); the camera-space ray leaving the rear.
    fn trace_from_scene(&self, o: DVec3, d: DVec3) -> Option<(DVec3, DVec3)> {
        let (mut o, mut d) = (DVec3::new(o.x, o.y, -o.z), DVec3::new(d.x, d.y, -d.z));
        let mut z = -self.front_z();
        for (i, e) in self.elements.iter().enumerate() {
            let stop = e.curvature_radius == 0.0;
            let (t, n) = meet(e, z, o, d)?;
            let p = o + t * d;
            if p.x * p.x + p.y * p.y > e.aperture_radius * e.aperture_radius {
                return None;
            }
            o = p;
            if !stop {
                let eta_i = if i == 0 || self.elements[i - 1].eta == 0.0 {
                    1.0
                } else {
                    self.elements[i - 1].eta
                };
                let eta_t = if e.eta != 0.0 { e.eta } else { 1.0 };
                d = refract((-d).normalize(), n, eta_t / eta_i)?;
            }
            z += e.thickness;
        }
        Some((DVec3::new(o.x, o.y, -o.z), DVec3::new(d.x, d.y, -d.z)))
    }

    /// The film distance that focuses the lens at `focus_distance`, by pbrt-v4's thick-lens
    /// approximation (the cardinal points from a ray traced each way near the axis).
    fn focus_thick_lens(&self, focus_distance: f64) -> Result<f64, String> {
        let cardinal = |o_in: DVec3, o_out: DVec3, d_out: DVec3| {
            let tf = -o_out.x / d_out.x;
            let fz = -(o_out + tf * d_out).z;
            let tp = (o_in.x - o_out.x) / d_out.x;
            let pz = -(o_out + tp * d_out).z;
            (pz, fz)
        };
        let x = 0.001 * self.diagonal;
        let fail =
            "a ray near the axis does not get through the lens (is the aperture stop closed?)";
        let o_scene = DVec3::new(x, 0.0, self.front_z() + 1.0);
        let (o, d) = self
            .trace_from_scene(o_scene, DVec3::new(0.0, 0.0, -1.0))
            .ok_or(fail)?;
        let (pz0, fz0) = cardinal(o_scene, o, d);
        let o_film = DVec3::new(x, 0.0, self.rear_z() - 1.0);
        let (o, d, _) = self
            .trace_from_film(o_film, DVec3::new(0.0, 0.0, 1.0))
            .ok_or(fail)?;
        let (pz1, _) = cardinal(o_film, o, d);
        let f = fz0 - pz0;
        let z = -focus_distance;
        let c = (pz1 - z - pz0) * (pz1 - z - 4.0 * f - pz0);
        if c.is_nan() || c <= 0.0 {
            return Err(format!(
                "it cannot focus at {focus_distance} m (too near for this lens)"
            ));
        }
        let delta = (pz1 - z + pz0 - c.sqrt()) / 2.0;
        Ok(self.rear_z() + delta)
    }

    /// The bounds, on the rear element's plane, of the points through which rays from the
    /// film segment x in [x0, x1] on the x axis get through the lens.
    fn bound_exit_pupil(&self, x0: f64, x1: f64) -> Option<[f64; 4]> {
        let rear = self.elements.last().map_or(0.0, |e| e.aperture_radius);
        let (lo, hi) = (-1.5 * rear, 1.5 * rear);
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for i in 0..PUPIL_SAMPLES {
            let t = (i as f64 + 0.5) / PUPIL_SAMPLES as f64;
            let film = DVec3::new(x0 + t * (x1 - x0), 0.0, 0.0);
            let (u0, u1) = (radical_inverse(2, i as u64), radical_inverse(3, i as u64));
            let p = DVec3::new(lo + u0 * (hi - lo), lo + u1 * (hi - lo), self.rear_z());
            let inside = p.x >= b[0] && p.x <= b[2] && p.y >= b[1] && p.y <= b[3];
            if !inside && self.trace_from_film(film, p - film).is_some() {
                b = [b[0].min(p.x), b[1].min(p.y), b[2].max(p.x), b[3].max(p.y)];
            }
        }
        if b[0] > b[2] || b[1] > b[3] {
            return None;
        }
        let grow = 2.0 * (hi - lo) * std::f64::consts::SQRT_2 / (PUPIL_SAMPLES as f64).sqrt();
        Some([b[0] - grow, b[1] - grow, b[2] + grow, b[3] + grow])
    }

    /// The camera-space ray from raster position `film` (pixels, on a film of `resolution`)
    /// through the lens, by the lens sample `u`, and its weight; None where the lens stops it.
    pub fn generate(&self, film: Vec2, resolution: Vec2, u: Vec2) -> Option<(Vec3A, Vec3A, f32)> {
        let s = (
            f64::from(film.x / resolution.x),
            f64::from(film.y / resolution.y),
        );
        let (hx, hy) = self.half_extent;
        let p_film = DVec3::new(-(-hx + s.0 * 2.0 * hx), -hy + s.1 * 2.0 * hy, 0.0);
        let r = (p_film.x * p_film.x + p_film.y * p_film.y).sqrt();
        let ring = ((r / (self.diagonal / 2.0) * PUPIL_RINGS as f64) as usize).min(PUPIL_RINGS - 1);
        let b = self.pupil[ring]?;
        let (lx, ly) = (
            b[0] + f64::from(u.x) * (b[2] - b[0]),
            b[1] + f64::from(u.y) * (b[3] - b[1]),
        );
        let area = (b[2] - b[0]) * (b[3] - b[1]);
        let (sin, cos) = if r != 0.0 {
            (p_film.y / r, p_film.x / r)
        } else {
            (0.0, 1.0)
        };
        let pupil = DVec3::new(cos * lx - sin * ly, sin * lx + cos * ly, self.rear_z());
        let d_film = pupil - p_film;
        let (o, d, weight) = self.trace_from_film(p_film, d_film)?;
        let cos_theta = d_film.normalize().z;
        let weight = weight * cos_theta.powi(4) * area / (self.rear_z() * self.rear_z());
        let d = d.normalize();
        Some((
            Vec3A::new(o.x as f32, o.y as f32, o.z as f32),
            Vec3A::new(d.x as f32, d.y as f32, d.z as f32),
            weight as f32,
        ))
    }
}

/// The image bilinearly at `uv` (pixel centres at half-integers), zero outside, as pbrt-v4's
/// Bilerp with WrapMode::Black.
fn bilerp_black(image: &ApertureImage, uv: Vec2) -> f32 {
    let (w, h) = (image.width as i64, image.height as i64);
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * h as f32 - 0.5;
    let (xi, yi) = (x.floor() as i64, y.floor() as i64);
    let (dx, dy) = (x - xi as f32, y - yi as f32);
    let at = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= w || y >= h {
            0.0
        } else {
            image.values[(y * w + x) as usize]
        }
    };
    (1.0 - dx) * (1.0 - dy) * at(xi, yi)
        + dx * (1.0 - dy) * at(xi + 1, yi)
        + (1.0 - dx) * dy * at(xi, yi + 1)
        + dx * dy * at(xi + 1, yi + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A biconvex singlet with a stop behind it.
    fn singlet() -> RealisticLens {
        RealisticLens {
            elements: vec![
                [40.0, 6.0, 1.6, 24.0],
                [-40.0, 4.0, 1.0, 24.0],
                [0.0, 0.0, 0.0, 16.0],
            ],
            aperture_diameter: 12.0,
            focus_distance: 2.0,
            aperture: None,
        }
    }

    /// Rays from one film point through different parts of the pupil meet again at the
    /// focus distance (the thick-lens focus is close to the traced one near the axis).
    #[test]
    fn a_focused_singlet_images_a_film_point_at_the_focus_distance() {
        let lens = LensSystem::new(&singlet(), 64, 64, 0.035).unwrap();
        let film = Vec2::new(32.0, 32.0);
        let mut points = Vec::new();
        for (u, v) in [(0.45, 0.5), (0.55, 0.5), (0.5, 0.45), (0.5, 0.55)] {
            if let Some((o, d, w)) = lens.generate(film, Vec2::new(64.0, 64.0), Vec2::new(u, v)) {
                assert!(w > 0.0 && d.z > 0.0);
                let t = (2.0 - o.z) / d.z;
                points.push(o + d * t);
            }
        }
        assert!(points.len() >= 3, "{points:?}");
        for p in &points {
            assert!(p.truncate().length() < 2e-3, "{points:?}");
        }
    }

    /// A ring's exit pupil bounds hold every pupil point a ray gets through.
    #[test]
    fn exit_pupil_bounds_hold_the_pupil() {
        let lens = LensSystem::new(&singlet(), 64, 64, 0.035).unwrap();
        let rear = lens.rear_z();
        for ring in [0, 20, 40] {
            let Some(b) = lens.pupil[ring] else { continue };
            let x = (ring as f64 + 0.5) / PUPIL_RINGS as f64 * lens.diagonal / 2.0;
            let film = DVec3::new(x, 0.0, 0.0);
            for i in 0..4000 {
                let p = DVec3::new(
                    -0.02 + 0.04 * radical_inverse(5, i),
                    -0.02 + 0.04 * radical_inverse(7, i),
                    rear,
                );
                if lens.trace_from_film(film, p - film).is_some() {
                    assert!(
                        p.x >= b[0] && p.x <= b[2] && p.y >= b[1] && p.y <= b[3],
                        "{p} outside {b:?}"
                    );
                }
            }
        }
    }
}
