//! One camera sample, from the camera to the film: where it lies on the film and the lens,
//! its instant and wavelengths ([`camera_sample`]), and what the film takes of its path's
//! radiance ([`Taken::take`]: the camera's weight, the sensor, the statistics, the clamp),
//! added to its pixel's running sums ([`accumulate`], the one way every pixel is summed).

use super::{Renderer, SampleId, TileStats};
use crate::features::Feature;
use crate::gbuffer::VisibleSurface;
use crate::integrators::Outcome;
use crate::math::{Color, Ray};
use crate::sampling::PixelSampler;
use crate::spectral::Wavelengths;
use crate::sums::PixelSums;
use crate::work::Work;
use glam::Vec2;
use kiln_scene::GBufferSpace;

/// The sampler dimension a camera sample's time comes from: far from the path's own.
const TIME_DIMENSION: u32 = 0x4000_0000;

/// The sampler dimension a camera sample's wavelengths come from, beside its time's.
const WAVELENGTH_DIMENSION: u32 = 0x4000_0001;

/// One camera sample of a pixel: its sampler (past the film and lens dimensions), and the
/// shot it took.
pub(super) struct CameraSample {
    pub sampler: PixelSampler,
    pub shot: Shot,
}

/// Where a camera sample lies on the film and the lens, its instant, its filter weight, and
/// the camera's ray with the camera's weight (None where a realistic camera's lens stops
/// it): what the film needs of it besides its path's radiance.
#[derive(Debug, Clone, Copy)]
pub(super) struct Shot {
    pub film: Vec2,
    pub lens: Vec2,
    pub time: f32,
    pub weight: f32,
    pub ray: Option<(Ray, f32)>,
    /// The sample's wavelengths in spectral mode.
    pub waves: Option<Wavelengths>,
}

pub(super) fn camera_sample(renderer: &Renderer, x: u32, y: u32, sample: u32) -> CameraSample {
    let scene = &renderer.scene;
    let mut sampler = PixelSampler::new(x, y, sample, renderer.settings.seed);
    let (offset, weight) = scene.filter.sample(sampler.get_2d());
    let film = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + offset;
    let lens = sampler.get_2d();
    // The sample's instant in the shutter, from a dimension of its own (so still scenes
    // keep every other dimension as they were).
    let time = if scene.has_motion {
        let u = sampler.value(TIME_DIMENSION);
        scene.shutter[0] + (scene.shutter[1] - scene.shutter[0]) * u
    } else {
        0.0
    };
    // Its wavelengths, from a dimension of their own too.
    let waves = renderer
        .settings
        .spectral
        .then(|| Wavelengths::sample(sampler.value(WAVELENGTH_DIMENSION)));
    CameraSample {
        sampler,
        shot: Shot {
            film,
            lens,
            time,
            weight,
            ray: scene.camera.generate_weighted_ray_at(film, lens, time),
            waves,
        },
    }
}

/// A camera sample's shot, and what its path gave: radiance, cost, the first surface it
/// saw and the denoiser's feature (None where the lens stopped the ray).
pub(super) struct Taken {
    pub id: SampleId,
    pub shot: Shot,
    pub path: Option<Outcome>,
}

/// A sample as the film takes it: its radiance, filter weight, the first surface it saw
/// (with a G-buffer) and the denoiser's feature.
pub(super) struct FilmSample {
    pub l: Color,
    pub weight: f32,
    pub seen: Option<VisibleSurface>,
    pub feature: Feature,
}

impl Taken {
    /// The sample as the film takes it: its radiance (zeroed if not finite, clamped, through
    /// the sensor), its filter weight, with `gbuffer` the first surface it saw in that
    /// space, and its feature; counted in `stats`.
    pub fn take(
        &self,
        renderer: &Renderer,
        gbuffer: Option<GBufferSpace>,
        stats: &mut TileStats,
    ) -> FilmSample {
        let (scene, settings) = (&renderer.scene, &renderer.settings);
        let SampleId { x, y, sample } = self.id;
        let Shot {
            film,
            lens,
            time,
            weight,
            ray,
            waves,
        } = self.shot;
        let (mut l, work, seen, feature) = match (ray, self.path) {
            (Some((ray, camera_weight)), Some(o)) => {
                let seen = match (gbuffer, o.visible) {
                    (Some(space), Some(s)) => Some(seen_from_camera(
                        renderer, &s, &ray, film, lens, time, space,
                    )),
                    (_, seen) => seen,
                };
                (o.l * camera_weight, o.work, seen, o.feature)
            }
            // A realistic camera's lens may stop the ray: the sample counts, black.
            _ => (Color::ZERO, Work::default(), None, Feature::NOTHING),
        };
        // The film records a spectral sample as linear sRGB, or as a named camera's raw RGB.
        if let Some(w) = &waves {
            l = scene.sensor.sample(l, w);
        }
        stats.samples += 1;
        stats.rays += work.rays;
        if work.cut_walks > 0 {
            stats.cut_off += 1;
            if stats.cut_off_examples.len() < TileStats::MAX_EXAMPLES {
                stats.cut_off_examples.push(SampleId { x, y, sample });
            }
        }
        if !l.is_finite() {
            stats.nonfinite += 1;
            if stats.nonfinite_examples.len() < TileStats::MAX_EXAMPLES {
                stats.nonfinite_examples.push(SampleId { x, y, sample });
            }
            l = Color::ZERO;
        }
        if settings.max_radiance > 0.0 {
            let m = l.max_element();
            if m > settings.max_radiance {
                l *= settings.max_radiance / m;
            }
        }
        FilmSample {
            l: scene.sensor.respond(l, waves.is_some()),
            weight,
            seen,
            feature,
        }
    }
}

/// Adds sample `s` of a pixel to the pixel's running sums: the one way every pixel is
/// summed, in sample order, in one go or in passes, whatever order its paths ended in.
pub(super) fn accumulate(p: &mut PixelSums, s: u32, sample: FilmSample, gbuffer: bool) {
    let FilmSample {
        l,
        weight: w,
        seen,
        feature,
    } = sample;
    for c in 0..3 {
        let v = (l[c] * w) as f64;
        p.sum[c] += v;
        p.squares[c] += v * v;
    }
    p.weight += w as f64;
    if gbuffer {
        p.gbuffer.add(l, w, seen.as_ref());
    }
    p.features.add(&feature, w);
    p.taken = s + 1;
}

/// One camera sample traced on its own, path after path: its radiance (zeroed if not
/// finite) and filter weight, and with `gbuffer` the first surface it saw. What a wave of
/// paths gives each of its samples, bit for bit (`tests/wavefront.rs` holds them to it).
pub(super) fn render_sample_seeing(
    renderer: &Renderer,
    x: u32,
    y: u32,
    sample: u32,
    stats: &mut TileStats,
    gbuffer: Option<GBufferSpace>,
) -> FilmSample {
    let CameraSample { mut sampler, shot } = camera_sample(renderer, x, y, sample);
    let path = shot.ray.map(|(ray, _)| {
        let tracer = renderer.path_tracer();
        tracer.trace(ray, &mut sampler, gbuffer.is_some(), shot.waves)
    });
    let taken = Taken {
        id: SampleId { x, y, sample },
        shot,
        path,
    };
    taken.take(renderer, gbuffer, stats)
}

/// A visible surface with its screen-space derivatives, in the G-buffer's space. The
/// derivatives are pbrt-v4's: rays through the next pixel right and down (same lens sample
/// and time), their offsets scaled by the footprint scale (1/sqrt(spp), at least 1/8), met
/// on the surface's tangent plane.
fn seen_from_camera(
    renderer: &Renderer,
    s: &VisibleSurface,
    ray: &Ray,
    film: Vec2,
    lens: Vec2,
    time: f32,
    space: GBufferSpace,
) -> VisibleSurface {
    let camera = &renderer.scene.camera;
    let scale = renderer.settings.footprint();
    let derivative = |step: Vec2| {
        let Some((r, _)) = camera.generate_weighted_ray_at(film + step, lens, time) else {
            return glam::Vec3A::ZERO;
        };
        let o = ray.origin + (r.origin - ray.origin) * scale;
        let d = ray.dir + (r.dir - ray.dir) * scale;
        let denom = s.ng.dot(d);
        if denom == 0.0 {
            return glam::Vec3A::ZERO;
        }
        let t = s.ng.dot(s.p - o) / denom;
        o + d * t - s.p
    };
    let world = VisibleSurface {
        dpdx: derivative(Vec2::X),
        dpdy: derivative(Vec2::Y),
        ..*s
    };
    match space {
        GBufferSpace::World => world,
        GBufferSpace::Camera => world.transformed(&camera.camera_to_world_at(time).inverse()),
    }
}
