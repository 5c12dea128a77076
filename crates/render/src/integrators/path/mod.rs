//! The (volumetric) path tracer: next-event estimation with multiple importance sampling,
//! Russian roulette, free-flight sampling through media, VolumeLight interiors, and the
//! caustic photon maps' gathers.
//!
//! A path is a small state ([`PathState`]) advanced by one step per segment: through the
//! medium the segment crosses (`medium.rs`), along a VolumeLight's interior
//! (`interior.rs`), to the surface it reaches ([`surface_emission`], then `surface.rs`) or
//! off to the lights at infinity ([`escape`]). Each estimator keeps its own part of the
//! state: the previous vertex for the MIS weights ([`PrevVertex`]), where the ray travels
//! ([`Travel`]: its medium, the nested shapes it is inside, its subsurface walk), the
//! VolumeLight interior it is in ([`Interior`]) and the photon maps' gathers ([`Gather`]).

mod gather;
mod interior;
mod medium;
mod surface;

use super::direct::{Direct, Shadow, emission_weight, survives_roulette};
use super::{PathSettings, Prepass};
use crate::features::Feature;
use crate::gbuffer::VisibleSurface;
use crate::math::{Color, Ray};
use crate::media::subsurface::Walk;
use crate::nesting::Nesting;
use crate::sampling::PixelSampler;
use crate::scene::Scene;
use crate::shapes::SurfaceHit;
use crate::spectral::Wavelengths;
use crate::work::Work;
use gather::Gather;
use glam::Vec3A;
use interior::Interior;

/// What a path tracer step needs besides the path.
pub(super) struct PathContext<'a> {
    pub scene: &'a Scene,
    pub settings: &'a PathSettings,
    pub prepass: &'a Prepass,
    /// The scale of the camera's pixel footprint for texture filtering.
    pub footprint: f32,
    /// The path's wavelengths in spectral mode (None: RGB).
    pub waves: Option<Wavelengths>,
}

impl PathContext<'_> {
    /// Emission light `light` gave in RGB, as the path sees it (see
    /// [`Scene::light_radiance`](crate::scene::Scene::light_radiance)).
    #[inline]
    pub fn emitted(&self, light: u32, rgb: Color) -> Color {
        self.scene.light_radiance(light, rgb, self.waves.as_ref())
    }
}

/// Everything a path carries from one segment to the next: what it has gathered and
/// carries, how far it has come, and the state each of its estimators owns.
struct PathState {
    /// Radiance gathered so far.
    l: Color,
    /// Throughput.
    beta: Color,
    /// The radiance scaling of refractions so far, which Russian roulette undoes.
    eta_scale: f32,
    /// Bounces so far, towards maxdepth. A subsurface walk is one: the refraction that
    /// entered it counts, and its scatterings and reflections inside do not (see
    /// [`Travel::walk`]).
    depth: u32,
    /// Scattering vertices so far, a walk's included: what the sampler's dimensions,
    /// the tracking numbers and Russian roulette go by.
    vertices: u32,
    prev: PrevVertex,
    travel: Travel,
    interior: Interior,
    gather: Gather,
    /// A spectral path that met a dispersive glass keeps only its hero wavelength (see
    /// [`PathState::keep_hero_only`]).
    hero_only: bool,
    /// For a G-buffer: whether to note the first surface with a BSDF, and what it was.
    want_visible: bool,
    visible: Option<VisibleSurface>,
    /// The denoiser's feature, once the path met its first non-specular vertex, and how
    /// far the path has come until then.
    feature: Option<Feature>,
    travelled: f32,
    /// The light sample of the last vertex waiting on its shadow ray, with the throughput
    /// it is seen through there.
    shadow: Option<(Color, Shadow)>,
}

/// What the previous scattering vertex knew, for weighting emission found by BSDF or phase
/// sampling against light sampling.
#[derive(Clone, Copy)]
struct PrevVertex {
    /// Whether it was the camera or a specular bounce (its emission counts in full).
    first_or_specular: bool,
    p: Vec3A,
    /// Its shading normal (zero in a medium), which the light sampler's choice depends on.
    n: Vec3A,
    /// The density it sampled the current direction with.
    pdf: f32,
    /// Some bounce so far scattered non-specularly (pbrt-v4's regularize waits for one).
    any_non_specular: bool,
}

impl PrevVertex {
    /// The camera at `origin`.
    fn camera(origin: Vec3A) -> PrevVertex {
        PrevVertex {
            first_or_specular: true,
            p: origin,
            n: Vec3A::ZERO,
            pdf: 0.0,
            any_non_specular: false,
        }
    }

    /// The MIS weight of `light`'s emission met at `x` (normal `n`, zero in a medium) along
    /// `dir`, which this vertex sampled with density `pdf`.
    fn emission_weight(
        &self,
        ctx: &PathContext,
        light: u32,
        pdf: f32,
        dir: Vec3A,
        x: Vec3A,
        n: Vec3A,
    ) -> f32 {
        let unsampled =
            ctx.settings.pbrt_estimator && ctx.scene.lights[light as usize].found_by_bsdf_alone();
        emission_weight(
            ctx.settings,
            self.first_or_specular || unsampled,
            pdf,
            || ctx.scene.light_pdf(light, self.p, self.n, dir, x, n),
        )
    }
}

/// Where the ray travels: the participating medium it is in, the nested dielectric shapes
/// it is inside, and the subsurface walk it is on.
struct Travel {
    medium: Option<u32>,
    /// A spectral path's lanes' relative densities of being sampled so far (see
    /// [`crate::media::LANE_PDFS`]).
    lane_pdfs: Color,
    /// Medium segments so far (each gets its own tracking numbers).
    segments: u32,
    nesting: Nesting,
    /// The subsurface walk: its events (scatterings, and reflections off the inside of its
    /// surface, up to the integrator's `walk_depth`) and its coefficients where they came
    /// from a texture.
    walk: Walk,
    /// Interface surfaces crossed without scattering.
    pass_throughs: u32,
}

impl Travel {
    /// Whether the ray is inside a subsurface material's interior.
    fn in_walk(&self, scene: &Scene) -> bool {
        self.medium.is_some_and(|m| scene.is_walk_medium(m))
    }

    /// Crosses `hit` straight on (an interface): false when the path should end.
    fn pass_through(&mut self, scene: &Scene, hit: &SurfaceHit, ray: &mut Ray) -> bool {
        let before = self.medium;
        if !super::pass_through(
            scene,
            hit,
            ray,
            &mut self.medium,
            &mut self.nesting,
            &mut self.pass_throughs,
        ) {
            return false;
        }
        scene.enter_walk(hit, ray.dir, before, self.medium, &mut self.walk);
        true
    }

    /// Leaves `hit`, reached along `dir`, along `wi`: into (or out of) a nested shape or
    /// the medium on that side, and a walk's interior. False when the path should end.
    fn scatter(&mut self, scene: &Scene, hit: &SurfaceHit, dir: Vec3A, wi: Vec3A) -> bool {
        let before = self.medium;
        if !self
            .nesting
            .cross(&scene.nested, hit, dir, wi, &mut self.medium)
        {
            return false;
        }
        scene.enter_walk(hit, wi, before, self.medium, &mut self.walk);
        true
    }
}

impl PathState {
    /// From a dispersive glass on, the path's direction depends on its hero wavelength (the
    /// first lane), so the other three are dropped, as pbrt-v4's `TerminateSecondary` drops
    /// them: what the path carries on is the hero's alone, four times over, since the film
    /// averages the four lanes (the hero's wavelength alone is distributed as each lane is),
    /// over the hero's own density of any media crossed ([`crate::media::hero_only`]). What
    /// the path gathered before stays four wavelengths'.
    fn keep_hero_only(&mut self) {
        if !self.hero_only {
            self.hero_only = true;
            self.beta = crate::media::hero_only(self.beta, self.travel.lane_pdfs);
            self.travel.lane_pdfs = crate::media::HERO_ONLY_LANE_PDFS;
        }
    }

    /// A vertex's light sample: added now, or once its shadow ray is traced. Nothing else
    /// adds to `l` between a light sample and the next segment, which waits for the shadow
    /// ray: the sums are in the same order either way.
    fn add_direct(&mut self, direct: Direct) {
        assert!(
            self.shadow.is_none(),
            "a vertex's shadow ray was never traced"
        );
        match direct {
            Direct::Done(c) => self.l += self.beta * c,
            Direct::Shadow(s) => self.shadow = Some((self.beta, s)),
        }
    }

    /// Russian roulette after a scattering event: the path goes on, or stops.
    fn roulette(&mut self, settings: &PathSettings, sampler: &mut PixelSampler) -> Next {
        if survives_roulette(
            &mut self.beta,
            self.eta_scale,
            self.vertices,
            settings,
            sampler,
        ) {
            Next::Continue
        } else {
            Next::Stop
        }
    }
}

/// What a path gave when it ended.
#[derive(Debug, Clone, Copy)]
pub struct Outcome {
    pub l: Color,
    pub work: Work,
    /// The first surface it saw, for a G-buffer (when asked for).
    pub visible: Option<VisibleSurface>,
    pub feature: Feature,
}

/// What the path does after a step.
enum Next {
    /// Trace the next segment.
    Continue,
    /// Go on to the surface the segment reached.
    Surface,
    /// The path ends.
    Stop,
}

/// The path tracer of one render: what every path's steps read.
pub struct PathTracer<'a> {
    pub scene: &'a Scene,
    pub settings: &'a PathSettings,
    pub prepass: &'a Prepass,
    /// The scale of the camera's pixel footprint for texture filtering.
    pub footprint: f32,
}

/// One path between its segments: what it carries, the ray of its next segment, its
/// sampler and what it cost so far. A path is advanced in stages (the closest hit of
/// [`Path::ray`], [`PathTracer::advance`], then [`PathTracer::shadow`]), so that a wave of
/// paths can run each stage over all of them; one path after another gives the same bytes,
/// since every number a path uses is its own.
pub struct Path {
    state: PathState,
    ray: Ray,
    sampler: PixelSampler,
    work: Work,
    waves: Option<Wavelengths>,
}

impl Path {
    /// The ray of the path's next segment, whose closest hit [`PathTracer::advance`] takes.
    pub fn ray(&self) -> &Ray {
        &self.ray
    }

    /// Whether a light sample waits on its shadow ray ([`PathTracer::shadow`]).
    pub fn waits_on_shadow(&self) -> bool {
        self.state.shadow.is_some()
    }

    /// The radiance gathered, what it cost, (if asked for) the first surface it saw, and
    /// the denoiser's feature.
    pub fn outcome(&self) -> Outcome {
        assert!(self.state.shadow.is_none(), "a shadow ray is still waiting");
        Outcome {
            l: self.state.l,
            work: self.work,
            visible: self.state.visible,
            feature: self.state.feature.unwrap_or(Feature::NOTHING),
        }
    }
}

impl PathTracer<'_> {
    fn context(&self, waves: Option<Wavelengths>) -> PathContext<'_> {
        PathContext {
            scene: self.scene,
            settings: self.settings,
            prepass: self.prepass,
            footprint: self.footprint,
            waves,
        }
    }

    /// A path from the camera along `ray`, at `waves` in spectral mode; with
    /// `want_visible`, it notes the first surface it sees for a G-buffer.
    pub fn start(
        &self,
        ray: Ray,
        sampler: PixelSampler,
        waves: Option<Wavelengths>,
        want_visible: bool,
    ) -> Path {
        let state = PathState {
            l: Color::ZERO,
            beta: Color::ONE,
            eta_scale: 1.0,
            depth: 0,
            vertices: 0,
            prev: PrevVertex::camera(ray.origin),
            travel: Travel {
                medium: self.scene.camera_medium,
                lane_pdfs: crate::media::LANE_PDFS,
                segments: 0,
                nesting: Nesting::default(),
                walk: Walk::default(),
                pass_throughs: 0,
            },
            interior: Interior::default(),
            gather: Gather::default(),
            hero_only: false,
            want_visible,
            visible: None,
            feature: None,
            travelled: 0.0,
            shadow: None,
        };
        Path {
            state,
            ray,
            sampler,
            work: Work::default(),
            waves,
        }
    }

    /// The path's segment up to `found`, the closest hit of its ray (counted here): through
    /// its medium, to the surface or off to the lights at infinity, and the next vertex's
    /// scattering. True while the path goes on (after [`PathTracer::shadow`] if it waits
    /// on a shadow ray, as it may also when it ends).
    pub fn advance(&self, path: &mut Path, mut found: Option<SurfaceHit>) -> bool {
        let ctx = self.context(path.waves);
        let Path {
            state,
            ray,
            sampler,
            work,
            ..
        } = path;
        work.rays += 1;
        if state.travel.medium.is_some() {
            match medium::medium_step(&ctx, state, ray, found.as_ref(), sampler, work) {
                Next::Continue => return true,
                Next::Stop => return false,
                Next::Surface => {}
            }
        }
        state.interior_segment(ctx.scene, ray, found.as_ref(), ctx.waves.as_ref());
        let Some(hit) = found.as_mut() else {
            escape(&ctx, state, ray);
            return false;
        };
        surface_emission(&ctx, state, ray, hit, work);
        match surface::surface_step(&ctx, state, ray, hit, sampler, work) {
            Next::Continue | Next::Surface => true,
            Next::Stop => false,
        }
    }

    /// Traces the shadow ray the path's light sample waits on, and adds the sample.
    pub fn shadow(&self, path: &mut Path) {
        if let Some((beta, shadow)) = path.state.shadow.take() {
            path.state.l += beta * shadow.resolve(self.scene, &mut path.work, path.waves.as_ref());
        }
    }

    /// One path along `ray` traced on its own to its end, and what it gave; with
    /// `want_visible`, the first surface it saw.
    pub fn trace(
        &self,
        ray: Ray,
        sampler: &mut PixelSampler,
        want_visible: bool,
        waves: Option<Wavelengths>,
    ) -> Outcome {
        let mut path = self.start(ray, sampler.clone(), waves, want_visible);
        loop {
            let found = self.scene.geometry.intersect(path.ray(), f32::INFINITY);
            let goes_on = self.advance(&mut path, found);
            self.shadow(&mut path);
            if !goes_on {
                break;
            }
        }
        *sampler = path.sampler.clone();
        path.outcome()
    }
}

/// A ray that left the scene: the lights at infinity.
fn escape(ctx: &PathContext, state: &mut PathState, ray: &Ray) {
    let scene = ctx.scene;
    // The caustic photons of the lights at infinity counted this path's light.
    if state.gather.after_caustic_gather() {
        return;
    }
    for &i in &scene.infinite_lights {
        let le = scene.lights[i as usize].infinite_le(ray.origin, ray.dir);
        if le != Color::ZERO {
            let prev = &state.prev;
            let w = prev.emission_weight(ctx, i, prev.pdf, ray.dir, Vec3A::ZERO, Vec3A::ZERO);
            state.l += state.beta * ctx.emitted(i, le) * w;
        }
    }
}

/// Emission of the light whose surface the ray reached, weighted against light sampling.
fn surface_emission(
    ctx: &PathContext,
    state: &mut PathState,
    ray: &Ray,
    hit: &SurfaceHit,
    work: &mut Work,
) {
    let scene = ctx.scene;
    let Some(light_id) = hit.light else {
        return;
    };
    let light = &scene.lights[light_id as usize];
    // Reached through specular bounces from a vertex that gathered caustic photons: the
    // photon map has already counted it (every light shoots photons).
    if state.gather.after_caustic_gather() {
        return;
    }
    let ctx_at = scene.light_context_at(ctx.waves.as_ref());
    let (le, traced) = light.le(&ctx_at, hit.p, hit.ng, hit.ns, -ray.dir);
    work.rays += traced;
    if le != Color::ZERO {
        let prev = &state.prev;
        let w = prev.emission_weight(ctx, light_id, prev.pdf, ray.dir, hit.p, hit.ng);
        state.l += state.beta * ctx.emitted(light_id, le) * w;
    }
}
