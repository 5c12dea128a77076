//! Caustic photon maps (seeds 003 and 004): light that reaches a diffuse surface or a
//! participating medium only through specular surfaces (a lens of glass focusing a small
//! light) is nearly impossible for a path tracer to find from the camera, and easy to find
//! from the light. Photons are traced from the area lights through specular bounces and
//! stored where they first meet a diffuse surface or scatter in a medium; the path tracer
//! then estimates that light by density estimation at its own vertices, and stops counting
//! the same paths when they reach a light through specular bounces.
//!
//! The maps are built once per render, before any tile, from a fixed number of photons
//! with seeds that depend only on the photon's index: every worker of a farm builds the
//! same map, so tiles stay independent and the image bit-identical.

use crate::lights::EmissionPoint;
use crate::math::{Color, Frame, Ray, offset_origin};
use crate::media::MediumEvent;
use crate::sampling::{AliasTable, TrackingRng, cosine_hemisphere};
use crate::scene::Scene;
use crate::shapes::{NO_MEDIUM, SurfaceHit};
use glam::{Vec2, Vec3A};
use rayon::prelude::*;
use std::collections::HashMap;
use std::f32::consts::PI;

/// One stored photon: where, from which direction it arrived (pointing away from `p`),
/// the surface normal there (zero in a medium) and its flux.
#[derive(Debug, Clone, Copy)]
pub struct Photon {
    pub p: Vec3A,
    pub wi: Vec3A,
    pub n: Vec3A,
    pub power: Color,
}

/// Photons bucketed in a uniform hash grid whose cells are as wide as the search radius,
/// so a query visits at most 27 cells.
#[derive(Debug, Clone, Default)]
pub struct PhotonGrid {
    photons: Vec<Photon>,
    cells: HashMap<(i32, i32, i32), (u32, u32)>,
    radius: f32,
}

impl PhotonGrid {
    fn new(mut photons: Vec<Photon>, radius: f32) -> PhotonGrid {
        let key = |p: Vec3A| {
            let c = (p / radius).floor();
            (c.x as i32, c.y as i32, c.z as i32)
        };
        // A stable sort keeps the photons' (deterministic) order within a cell.
        photons.sort_by_key(|ph| key(ph.p));
        let mut cells = HashMap::new();
        let mut start = 0;
        while start < photons.len() {
            let k = key(photons[start].p);
            let mut end = start + 1;
            while end < photons.len() && key(photons[end].p) == k {
                end += 1;
            }
            cells.insert(k, (start as u32, end as u32));
            start = end;
        }
        PhotonGrid {
            photons,
            cells,
            radius,
        }
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// Calls `f` for each photon within the radius of `p`.
    fn for_each_near(&self, p: Vec3A, mut f: impl FnMut(&Photon)) {
        if self.photons.is_empty() {
            return;
        }
        let r2 = self.radius * self.radius;
        let c = (p / self.radius).floor();
        let (cx, cy, cz) = (c.x as i32, c.y as i32, c.z as i32);
        for z in cz - 1..=cz + 1 {
            for y in cy - 1..=cy + 1 {
                for x in cx - 1..=cx + 1 {
                    if let Some(&(a, b)) = self.cells.get(&(x, y, z)) {
                        for ph in &self.photons[a as usize..b as usize] {
                            if (ph.p - p).length_squared() <= r2 {
                                f(ph);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The caustic photon maps of a scene.
#[derive(Debug, Clone, Default)]
pub struct CausticMaps {
    pub surface: PhotonGrid,
    pub volume: PhotonGrid,
}

/// Settings of the caustic photon pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CausticSettings {
    pub photons: u64,
    /// Search radius on surfaces and in media (world units).
    pub radius: f32,
}

/// Photons per parallel batch: the batches, not the threads, fix the order of the result.
const BATCH: u64 = 4096;

impl CausticMaps {
    /// Traces `settings.photons` photons from the scene's area lights, chosen in
    /// proportion to their power. Lights of other kinds (points, spots, distant,
    /// environments, VolumeLights, emissive media) shoot none: their caustics are left to
    /// the path tracer, which counts them as usual.
    pub fn build(scene: &Scene, settings: CausticSettings) -> CausticMaps {
        let powers: Vec<f64> = scene
            .lights
            .iter()
            .map(|l| {
                if l.shoots_photons() {
                    l.power(scene.radius) as f64
                } else {
                    0.0
                }
            })
            .collect();
        if settings.photons == 0 || powers.iter().all(|p| *p <= 0.0) {
            return CausticMaps::default();
        }
        let table = AliasTable::new(&powers);
        let n = settings.photons;
        let batches: Vec<(Vec<Photon>, Vec<Photon>)> = (0..n.div_ceil(BATCH))
            .into_par_iter()
            .map(|b| {
                let mut surface = Vec::new();
                let mut volume = Vec::new();
                for i in b * BATCH..((b + 1) * BATCH).min(n) {
                    trace_photon(scene, &table, i, n, &mut surface, &mut volume);
                }
                (surface, volume)
            })
            .collect();
        let mut surface = Vec::new();
        let mut volume = Vec::new();
        for (s, v) in batches {
            surface.extend(s);
            volume.extend(v);
        }
        CausticMaps {
            surface: PhotonGrid::new(surface, settings.radius),
            volume: PhotonGrid::new(volume, settings.radius),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.surface.is_empty() && self.volume.is_empty()
    }

    /// Caustic radiance scattered at medium point `p` towards `wo` (both away from `p`),
    /// per unit scattering coefficient: (1 / sigma_s) sum phase * flux / (4/3 pi r^3) is
    /// what the caller gets after dividing by sigma_s. `phase(wo, wi)`.
    pub fn volume_radiance(
        &self,
        p: Vec3A,
        wo: Vec3A,
        phase: impl Fn(Vec3A, Vec3A) -> f32,
    ) -> Color {
        let mut sum = Color::ZERO;
        self.volume.for_each_near(p, |ph| {
            sum += ph.power * phase(wo, ph.wi);
        });
        let r = self.volume.radius;
        sum / (4.0 / 3.0 * PI * r * r * r)
    }

    /// Caustic radiance leaving surface point `p` (normal `n`) towards `wo`, given the
    /// BSDF times nothing (`f(wi)`, the photon's flux already holds its cosine).
    pub fn surface_radiance(&self, p: Vec3A, n: Vec3A, f: impl Fn(Vec3A) -> Color) -> Color {
        let mut sum = Color::ZERO;
        self.surface.for_each_near(p, |ph| {
            if ph.n.dot(n) > 0.9 {
                sum += ph.power * f(ph.wi);
            }
        });
        let r = self.surface.radius;
        sum / (PI * r * r)
    }
}

/// Traces photon `index` of `count`; stores it where it first meets a diffuse surface or
/// scatters in a medium after at least one specular bounce.
fn trace_photon(
    scene: &Scene,
    table: &AliasTable,
    index: u64,
    count: u64,
    surface: &mut Vec<Photon>,
    volume: &mut Vec<Photon>,
) {
    let mut rng = TrackingRng::new(index.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0xc0ff_ee00);
    let Some((light_index, pmf)) = table.sample(rng.next_f32()) else {
        return;
    };
    let u1 = Vec2::new(rng.next_f32(), rng.next_f32());
    let u2 = Vec2::new(rng.next_f32(), rng.next_f32());
    let light = &scene.lights[light_index];
    // A point and a cosine-distributed direction on the emitting side; flux = L A pi
    // (twice for two-sided lights, which pick a side at random).
    let Some(EmissionPoint {
        p,
        n,
        radiance,
        area,
        two_sided,
    }) = light.emission_point(&scene.light_context(), u1)
    else {
        return;
    };
    let (n, sides) = if two_sided {
        (if rng.next_f32() < 0.5 { n } else { -n }, 2.0)
    } else {
        (n, 1.0)
    };
    let dir = Frame::from_z(n).to_world(cosine_hemisphere(u2));
    let mut beta = radiance * (area * PI * sides / (pmf * count as f32));
    let mut medium = scene
        .light_media
        .get(light_index)
        .copied()
        .flatten()
        .and_then(|[inside, outside]| {
            let m = if dir.dot(n) > 0.0 { outside } else { inside };
            (m != NO_MEDIUM).then_some(m)
        });
    // A photon flies at one instant of the shutter, as a camera path does.
    let time = if scene.has_motion {
        scene.shutter[0] + (scene.shutter[1] - scene.shutter[0]) * rng.next_f32()
    } else {
        0.0
    };
    let mut ray = Ray::at_time(offset_origin(p, n, dir), dir, time);
    let mut specular_bounces = 0u32;
    for _ in 0..64 {
        let found = scene.geometry.intersect(&ray, f32::INFINITY);
        if let Some(m) = medium {
            let t_max = found.as_ref().map_or(f32::INFINITY, |h| h.t);
            // The path tracer's free-flight sampling (photons carry no medium emission).
            match scene.media[m as usize].sample_interaction(
                &ray,
                t_max,
                &mut rng,
                &mut beta,
                |_| {},
            ) {
                MediumEvent::Crossed => {}
                // A photon whose walk is cut off is lost (the camera paths report theirs).
                MediumEvent::Absorbed | MediumEvent::CutOff => return,
                MediumEvent::Scattered(t) => {
                    if specular_bounces > 0 {
                        volume.push(Photon {
                            p: ray.at(t),
                            wi: -ray.dir,
                            n: Vec3A::ZERO,
                            power: beta,
                        });
                    }
                    return;
                }
            }
        }
        let Some(mut hit) = found else { return };
        let Some(bsdf) = scene.bsdf(&mut hit, 1.0) else {
            // An interface: straight on, into the medium on the other side.
            if let Some(next) = hit.surface.medium_towards(ray.dir, hit.ng) {
                medium = next;
            }
            ray = ray.spawn(offset_origin(hit.p, hit.ng, ray.dir), ray.dir);
            continue;
        };
        if !bsdf.is_specular() {
            if specular_bounces > 0 {
                store_surface(surface, &hit, &ray, beta);
            }
            return;
        }
        let frame = Frame::new(hit.ns, hit.dpdu);
        let wo = frame.to_local(-ray.dir);
        let uc = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(bs) = bsdf.sample(wo, uc, u) else {
            return;
        };
        let wi = frame.to_world(bs.wi);
        // Flux, not radiance, crosses the boundary: undo the BSDF's 1/eta^2.
        beta *= bs.f * wi.dot(hit.ns).abs() / bs.pdf * (bs.eta * bs.eta);
        if !beta.is_finite() || beta == Color::ZERO {
            return;
        }
        specular_bounces += 1;
        if let Some(next) = hit.surface.medium_towards(wi, hit.ng) {
            medium = next;
        }
        ray = ray.spawn(offset_origin(hit.p, hit.ng, wi), wi);
    }
}

fn store_surface(surface: &mut Vec<Photon>, hit: &SurfaceHit, ray: &Ray, power: Color) {
    // The side the photon arrived on.
    let n = if ray.dir.dot(hit.ns) < 0.0 {
        hit.ns
    } else {
        -hit.ns
    };
    surface.push(Photon {
        p: hit.p,
        wi: -ray.dir,
        n,
        power,
    });
}
