//! The tile function: the pure function from (scene, settings, tile) to pixels
//! that `kiln render` and the farm's workers both call, and the [`Renderer`] it renders
//! with: a scene, its settings, and the integrator's pre-passes, done once per job.

use crate::adaptive::Adaptive;
use crate::gbuffer::{GBufferLayout, VisibleSurface};
use crate::integrators::photons::Gather;
use crate::integrators::sppm::PassCache;
use crate::integrators::{Integrator, Prepass};
use crate::math::Color;
use crate::rect::TileRect;
use crate::sampling::PixelSampler;
use crate::scene::{BuildError, MediaPolicy, Scene};
use crate::shared::SharedPrepass;
use crate::spectral::Wavelengths;
use crate::sums::{PixelSums, SumsLayout, TileSums};
use crate::work::Work;
use glam::Vec2;
use rayon::prelude::*;
use std::sync::Arc;

/// Everything besides the scene that decides the pixels.
#[derive(Debug, Clone)]
pub struct RenderSettings {
    pub samples_per_pixel: u32,
    pub seed: u32,
    pub integrator: Integrator,
    /// Clamp each sample's radiance to this maximum component (0 disables it).
    pub max_radiance: f32,
    /// A G-buffer film: its channels beside each pixel's radiance, in this space.
    pub gbuffer: Option<kiln_scene::GBufferSpace>,
    /// Filter textures as a render of this many samples per pixel would (default: the
    /// samples rendered). A farm job in passes renders every pass with its last pass's
    /// footprint, so the frame after a pass of fewer than 64 samples is the first samples of
    /// the longer render: `kiln render --spp N --footprint-spp LAST` gives its bytes.
    pub footprint_spp: Option<u32>,
    /// Adaptive sampling: a pixel stops taking samples once its own estimate is good
    /// enough (the scene's Sampler `noisethreshold`), or None.
    pub adaptive: Option<Adaptive>,
    /// Spectral rendering: each camera sample carries four wavelengths (see
    /// [`crate::spectral`]); otherwise RGB.
    pub spectral: bool,
}

impl RenderSettings {
    /// The scale of a pixel's footprint for texture filtering: with many samples per pixel
    /// each filters over less than a pixel, as pbrt-v4 does (1/sqrt(spp), at least 1/8).
    pub fn footprint(&self) -> f32 {
        texture_footprint(self.footprint_spp.unwrap_or(self.samples_per_pixel))
    }

    /// What a tile's running sums hold for these settings.
    pub fn sums_layout(&self) -> SumsLayout {
        SumsLayout {
            gbuffer: self.gbuffer.is_some(),
            adaptive: self.adaptive.is_some(),
        }
    }

    /// Settings as the scene file gives them.
    pub fn from_description(desc: &kiln_scene::SceneDescription) -> RenderSettings {
        let mut integrator = Integrator::from_description(&desc.integrator);
        // pbrt-v4's SPPM traces as many photons per iteration as the image has pixels.
        if let Integrator::Sppm(s) = &mut integrator
            && s.photons_per_iteration == 0
        {
            s.photons_per_iteration = desc.rendered_pixels();
        }
        RenderSettings {
            samples_per_pixel: desc.sampler.pixel_samples,
            seed: desc.sampler.seed,
            integrator,
            max_radiance: desc.integrator.max_radiance,
            gbuffer: desc.film.gbuffer,
            footprint_spp: None,
            adaptive: Adaptive::of(&desc.sampler),
            spectral: desc.spectral,
        }
    }
}

/// The texture filter's footprint, in pixels, for a render of `spp` samples per pixel
/// ([`RenderSettings::footprint`]): the same for every count from 64 up, so a render of 64
/// or more samples can be extended to more with the same samples.
pub fn texture_footprint(spp: u32) -> f32 {
    (1.0 / (spp.max(1) as f32).sqrt()).max(0.125)
}

/// Everything a tile is rendered from: the scene, the settings, and what the integrator
/// computed once before any tile (photon maps). Build it once per job and share it between
/// threads; every tile rendered from it is a pure function of it and the tile.
pub struct Renderer {
    scene: Scene,
    settings: RenderSettings,
    prepass: Prepass,
    /// SPPM's photon passes kept between tiles rendered one at a time (a farm worker's
    /// leases), so a worker traces each pass once per job, not once per tile.
    sppm_passes: PassCache,
    /// Where a farm's workers share the job's pre-passes and SPPM passes.
    shared: Option<Arc<dyn SharedPrepass>>,
}

impl Renderer {
    /// Builds the scene a description gives, with the settings it gives, and runs the
    /// integrator's pre-passes.
    pub fn build(desc: &kiln_scene::SceneDescription) -> Result<Renderer, BuildError> {
        Renderer::build_sharing(desc, None)
    }

    /// [`Renderer::build`] sharing the job's pre-passes (see [`Renderer::new_sharing`]).
    pub fn build_sharing(
        desc: &kiln_scene::SceneDescription,
        shared: Option<Arc<dyn SharedPrepass>>,
    ) -> Result<Renderer, BuildError> {
        let settings = RenderSettings::from_description(desc);
        let media = if settings.integrator.renders_media() {
            MediaPolicy::Render
        } else {
            MediaPolicy::Ignore
        };
        if settings.gbuffer.is_some() && matches!(settings.integrator, Integrator::Sppm(_)) {
            return Err(BuildError::Unsupported {
                loc: desc.integrator.loc.clone(),
                message: "Integrator 'sppm' does not write a G-buffer film's channels; use 'volpath' with Film \"gbuffer\"".into(),
            });
        }
        let scene = Scene::build(desc, media)?;
        Ok(Renderer::new_sharing(scene, settings, shared))
    }

    /// Runs the integrator's pre-passes on `scene`. The scene should have been built with
    /// the media policy the integrator asks for (see [`Integrator::renders_media`]).
    pub fn new(scene: Scene, settings: RenderSettings) -> Renderer {
        Renderer::new_sharing(scene, settings, None)
    }

    /// [`Renderer::new`] for one of a farm's workers: the pre-passes, and SPPM's photon
    /// passes, are computed once for the job by whichever worker claims each first, and
    /// shared through `shared`. The pixels are the same bytes as without it.
    pub fn new_sharing(
        scene: Scene,
        settings: RenderSettings,
        shared: Option<Arc<dyn SharedPrepass>>,
    ) -> Renderer {
        let prepass =
            settings
                .integrator
                .prepare_sharing(&scene, shared.as_deref(), settings.spectral);
        Renderer {
            scene,
            settings,
            prepass,
            sppm_passes: PassCache::default(),
            shared,
        }
    }

    /// The same renderer with textures filtered as a render of `spp` samples per pixel does
    /// ([`RenderSettings::footprint_spp`]); pre-passes do not filter textures, so they stay.
    pub fn with_footprint_spp(mut self, spp: u32) -> Renderer {
        self.settings.footprint_spp = Some(spp);
        self
    }

    /// The same scene with other settings (pre-passes run again, not shared).
    pub fn with_settings(self, settings: RenderSettings) -> Renderer {
        Renderer::new(self.scene, settings)
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    pub fn prepass(&self) -> &Prepass {
        &self.prepass
    }
}

/// One camera sample: its pixel and its index (what `kiln render` prints so it can be
/// replayed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleId {
    pub x: u32,
    pub y: u32,
    pub sample: u32,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct TileStats {
    pub samples: u64,
    pub rays: u64,
    /// Samples whose radiance was NaN or infinite (counted as black).
    pub nonfinite: u64,
    /// The first few non-finite samples, for replaying them.
    pub nonfinite_examples: Vec<SampleId>,
    /// Samples whose path was cut off in a medium at
    /// [`MAX_TRACKING_STEPS`](crate::work::MAX_TRACKING_STEPS): a render that has any has
    /// failed, and says so.
    pub cut_off: u64,
    pub cut_off_examples: Vec<SampleId>,
}

impl TileStats {
    pub const MAX_EXAMPLES: usize = 16;

    /// Why a render with samples cut off in a medium failed; None when none was.
    pub fn cut_off_error(&self) -> Option<String> {
        let first = self.cut_off_examples.first()?;
        Some(format!(
            "{} samples gave up after {} tracking steps in a medium (the first at pixel {}, {}, sample {}): a medium's density is far too large for tracking to cross it",
            self.cut_off,
            crate::work::MAX_TRACKING_STEPS,
            first.x,
            first.y,
            first.sample
        ))
    }

    pub fn merge(&mut self, other: &TileStats) {
        self.samples += other.samples;
        self.rays += other.rays;
        self.nonfinite += other.nonfinite;
        self.cut_off += other.cut_off;
        for (mine, theirs) in [
            (&mut self.nonfinite_examples, &other.nonfinite_examples),
            (&mut self.cut_off_examples, &other.cut_off_examples),
        ] {
            let room = Self::MAX_EXAMPLES.saturating_sub(mine.len());
            mine.extend(theirs.iter().take(room));
        }
    }
}

#[derive(Debug, Clone)]
pub struct TileResult {
    pub rect: TileRect,
    /// Row-major, `rect.width * rect.height` linear RGB pixels.
    pub pixels: Vec<[f32; 3]>,
    /// With a G-buffer film, each pixel's channels in turn (named by
    /// [`GBufferLayout::names`]); empty otherwise.
    pub aovs: Vec<f32>,
    pub stats: TileStats,
}

/// The names of the further channels a film writes beside R, G and B (sorted, as images
/// hold them): a G-buffer's, or none.
pub fn aov_names(gbuffer: Option<kiln_scene::GBufferSpace>) -> Vec<String> {
    gbuffer.map_or_else(Vec::new, |space| GBufferLayout::new(space).names())
}

/// Renders one tile. The result depends only on the scene, the settings and the
/// tile's pixels: not on the tile's size, its neighbours, or the thread count.
pub fn render_tile(renderer: &Renderer, rect: TileRect) -> TileResult {
    render_tile_until(renderer, rect, &|| false).expect("never stopped")
}

/// [`render_tile`], asking `stop` before each pixel: None as soon as it says yes (a job
/// cancelled, a lease lost, a worker told to leave). A tile that runs to its end is the
/// same bytes as [`render_tile`]'s.
pub fn render_tile_until(
    renderer: &Renderer,
    rect: TileRect,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<TileResult> {
    if let Integrator::Sppm(sppm) = &renderer.settings.integrator {
        return render_sppm(renderer, sppm, &[rect], stop, &|| {}, true)?.pop();
    }
    let from = TileSums::empty(rect, renderer.settings.sums_layout());
    let to = renderer.settings.samples_per_pixel;
    continue_tile(renderer, &from, to, stop).map(|(result, _)| result)
}

/// Why a tile cannot be rendered as a pass.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PassError {
    #[error("SPPM renders in one pass: its photon radius shrinks over all its iterations together")]
    Sppm,
    #[error("a pass must end past the {from} samples its tile holds, not at {to}")]
    Backwards { from: u32, to: u32 },
    #[error("the running sums are of another tile or another film")]
    Mismatch,
}

/// Continues a tile's running sums `from` (of the same rect, as the renderer's film keeps
/// them) up to `to` samples of each pixel: a pass of a progressive render. The result's
/// pixels are the same bytes as [`render_tile`]'s with `to` samples per pixel, whatever
/// passes led here, because each pixel's sums go on in sample order exactly where they
/// stopped. (The renderer's own sample count only sets the texture filter's footprint,
/// which [`RenderSettings::footprint`] keeps constant from 64 samples up.) None if `stop`
/// said yes.
pub fn render_tile_pass(
    renderer: &Renderer,
    from: &TileSums,
    to: u32,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Option<(TileResult, TileSums)>, PassError> {
    if let Integrator::Sppm(_) = &renderer.settings.integrator {
        return Err(PassError::Sppm);
    }
    if to <= from.samples {
        return Err(PassError::Backwards {
            from: from.samples,
            to,
        });
    }
    if from.layout != renderer.settings.sums_layout()
        || from.pixels.len() as u64 != from.rect.pixel_count()
    {
        return Err(PassError::Mismatch);
    }
    Ok(continue_tile(renderer, from, to, stop))
}

/// Each pixel of `from.rect` from its sums in `from` on to `to` samples.
fn continue_tile(
    renderer: &Renderer,
    from: &TileSums,
    to: u32,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(TileResult, TileSums)> {
    let rect = from.rect;
    let layout = renderer.settings.gbuffer.map(GBufferLayout::new);
    let channels = layout.as_ref().map_or(0, |l| l.channels());
    let want = layout.as_ref().map(|l| l.space);
    let width = rect.width as usize;
    type Row = (Vec<[f32; 3]>, Vec<f32>, Vec<PixelSums>, TileStats);
    let rows: Option<Vec<Row>> = (0..rect.height as usize)
        .into_par_iter()
        .map(|row| {
            let y = rect.y0 + row as u32;
            let mut stats = TileStats::default();
            let mut aovs = vec![0.0f32; channels * width];
            let mut sums = from.pixels[row * width..(row + 1) * width].to_vec();
            let mut pixels = Vec::with_capacity(width);
            for (i, p) in sums.iter_mut().enumerate() {
                if stop() {
                    return None;
                }
                let x = rect.x0 + i as u32;
                add_samples(renderer, x, y, from.samples..to, want, &mut stats, p);
                if let Some(l) = &layout {
                    p.gbuffer
                        .finish(l, &mut aovs[i * channels..(i + 1) * channels]);
                }
                pixels.push(p.value());
            }
            Some((pixels, aovs, sums, stats))
        })
        .collect();
    let mut pixels = Vec::with_capacity(rect.pixel_count() as usize);
    let mut aovs = Vec::with_capacity(rect.pixel_count() as usize * channels);
    let mut sums = Vec::with_capacity(rect.pixel_count() as usize);
    let mut stats = TileStats::default();
    for (row, row_aovs, row_sums, s) in rows? {
        pixels.extend(row);
        aovs.extend(row_aovs);
        sums.extend(row_sums);
        stats.merge(&s);
    }
    let result = TileResult {
        rect,
        pixels,
        aovs,
        stats,
    };
    let sums = TileSums {
        rect,
        samples: to,
        layout: from.layout,
        pixels: sums,
    };
    Some((result, sums))
}

/// Renders `rects` (each as [`render_tile`] would) and calls `progress` after each unit of
/// work: a tile, or for SPPM an iteration over all of them, which is why they are rendered
/// together (each iteration's photons are traced once for every tile). The number of
/// units is [`progress_units`].
pub fn render_tiles(
    renderer: &Renderer,
    rects: &[TileRect],
    progress: &(dyn Fn() + Sync),
) -> Vec<TileResult> {
    if let Integrator::Sppm(sppm) = &renderer.settings.integrator {
        return render_sppm(renderer, sppm, rects, &|| false, progress, false)
            .expect("never stopped");
    }
    rects
        .par_iter()
        .map(|r| {
            let t = render_tile(renderer, *r);
            progress();
            t
        })
        .collect()
}

/// How many times [`render_tiles`] reports progress for `tiles` tiles.
pub fn progress_units(renderer: &Renderer, tiles: usize) -> u64 {
    match &renderer.settings.integrator {
        Integrator::Sppm(_) => renderer.settings.samples_per_pixel as u64,
        Integrator::Path(_) | Integrator::VolPath(_) => tiles as u64,
    }
}

/// SPPM over the pixels of `rects`: iterations outermost (a camera pass, a photon pass, the
/// gathers), then each pixel's radiance. Every pixel's value depends only on its own
/// samples and the photon passes, so any split gives the same bytes. With `keep`, the
/// passes are kept for the renderer's next tiles.
fn render_sppm(
    renderer: &Renderer,
    sppm: &crate::integrators::SppmSettings,
    rects: &[TileRect],
    stop: &(dyn Fn() -> bool + Sync),
    progress: &(dyn Fn() + Sync),
    keep: bool,
) -> Option<Vec<TileResult>> {
    use crate::integrators::sppm::{PixelState, camera_pass, gather, photon_pass};
    let (scene, settings) = (&renderer.scene, &renderer.settings);
    let pixels: Vec<(u32, u32)> = rects
        .iter()
        .flat_map(|r| {
            (r.y0..r.y0 + r.height).flat_map(move |y| (r.x0..r.x0 + r.width).map(move |x| (x, y)))
        })
        .collect();
    let mut states = vec![(PixelState::new(sppm.radius), 0u64); pixels.len()];
    let iterations = settings.samples_per_pixel;
    let emitters = crate::integrators::photons::Emitters::of(scene);
    for it in 0..iterations {
        if stop() {
            return None;
        }
        let waves = settings
            .spectral
            .then(|| crate::integrators::sppm::pass_wavelengths(settings.seed, it));
        let vps: Vec<_> = pixels
            .par_iter()
            .zip(states.par_iter_mut())
            .map(|(&(x, y), (state, rays))| {
                let CameraSample {
                    mut sampler,
                    weight,
                    ray,
                    ..
                } = camera_sample(renderer, x, y, it);
                let mut work = Work::default();
                let (ray, weight) = ray.map_or((None, 0.0), |(r, w)| (Some(r), w * weight));
                let vp = camera_pass(
                    scene,
                    sppm,
                    ray,
                    weight,
                    &mut sampler,
                    &mut work,
                    state,
                    waves.as_ref(),
                );
                *rays += work.rays;
                vp
            })
            .collect();
        let trace = |i: u32| {
            photon_pass(
                scene,
                sppm,
                emitters.as_ref(),
                settings.seed,
                i,
                settings.spectral,
            )
        };
        let map = if keep {
            renderer.sppm_passes.get(
                it,
                iterations,
                renderer.shared.as_deref(),
                &trace,
                Gather::Radius(sppm.radius),
                stop,
            )?
        } else {
            Arc::new(trace(it))
        };
        vps.par_iter()
            .zip(states.par_iter_mut())
            .for_each(|(vp, (state, _))| gather(&scene.sensor, &map, vp.as_ref(), state));
        progress();
    }
    let mut results = Vec::with_capacity(rects.len());
    let mut start = 0;
    for &rect in rects {
        let n = rect.pixel_count() as usize;
        let mut stats = TileStats::default();
        let pixels = states[start..start + n]
            .iter()
            .zip(&pixels[start..start + n])
            .map(|((state, rays), &(x, y))| {
                stats.samples += iterations as u64;
                stats.rays += rays;
                let mut l = state.radiance(iterations, sppm.photons_per_iteration);
                if !l.is_finite() {
                    stats.nonfinite += 1;
                    if stats.nonfinite_examples.len() < TileStats::MAX_EXAMPLES {
                        stats.nonfinite_examples.push(SampleId { x, y, sample: 0 });
                    }
                    l = Color::ZERO;
                }
                crate::math::rgb_of(scene.sensor.respond(l, settings.spectral))
            })
            .collect();
        results.push(TileResult {
            rect,
            pixels,
            aovs: Vec::new(),
            stats,
        });
        start += n;
    }
    Some(results)
}

/// One camera sample of a pixel: its sampler (past the film and lens dimensions), where it
/// lies on the film and the lens, its instant, its filter weight, and the camera's ray with
/// the camera's weight (None where a realistic camera's lens stops it).
struct CameraSample {
    sampler: PixelSampler,
    film: Vec2,
    lens: Vec2,
    time: f32,
    weight: f32,
    ray: Option<(crate::math::Ray, f32)>,
    /// The sample's wavelengths in spectral mode.
    waves: Option<Wavelengths>,
}

fn camera_sample(renderer: &Renderer, x: u32, y: u32, sample: u32) -> CameraSample {
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
        film,
        lens,
        time,
        weight,
        ray: scene.camera.generate_weighted_ray_at(film, lens, time),
        waves,
    }
}

/// Renders every sample of one pixel, in sample order, and returns their filter-weighted mean
/// (for SPPM, the pixel's estimate after all its iterations: the same value its tile gives).
pub fn render_pixel(renderer: &Renderer, x: u32, y: u32, stats: &mut TileStats) -> [f32; 3] {
    if let Integrator::Sppm(_) = &renderer.settings.integrator {
        let rect = TileRect {
            x0: x,
            y0: y,
            width: 1,
            height: 1,
        };
        let tile = render_tile(renderer, rect);
        stats.merge(&tile.stats);
        return tile.pixels[0];
    }
    render_pixel_with(renderer, x, y, stats, None)
}

/// [`render_pixel`], and with `gbuffer` the pixel's G-buffer channels written there.
fn render_pixel_with(
    renderer: &Renderer,
    x: u32,
    y: u32,
    stats: &mut TileStats,
    gbuffer: Option<(&GBufferLayout, &mut [f32])>,
) -> [f32; 3] {
    let mut p = PixelSums::default();
    let samples = 0..renderer.settings.samples_per_pixel;
    let want = gbuffer.as_ref().map(|(l, _)| l.space);
    add_samples(renderer, x, y, samples, want, stats, &mut p);
    if let Some((layout, out)) = gbuffer {
        p.gbuffer.finish(layout, out);
    }
    p.value()
}

/// Adds the pixel's `samples`, in sample order, to its running sums: the one way every
/// pixel is accumulated, in one go or in passes. With adaptive sampling the pixel stops at
/// the first checkpoint where its own sums say it is good enough; a pixel that stopped
/// before (it took fewer samples than `samples` starts from) takes none.
fn add_samples(
    renderer: &Renderer,
    x: u32,
    y: u32,
    samples: std::ops::Range<u32>,
    want: Option<kiln_scene::GBufferSpace>,
    stats: &mut TileStats,
    p: &mut PixelSums,
) {
    let adaptive = renderer.settings.adaptive;
    for s in samples {
        if p.taken < s || adaptive.is_some_and(|a| a.converged(p)) {
            break;
        }
        let (l, w, seen) = render_sample_seeing(renderer, x, y, s, stats, want);
        for c in 0..3 {
            let v = (l[c] * w) as f64;
            p.sum[c] += v;
            if adaptive.is_some() {
                p.squares[c] += v * v;
            }
        }
        p.weight += w as f64;
        if want.is_some() {
            p.gbuffer.add(l, w, seen.as_ref());
        }
        p.taken = s + 1;
    }
}

/// The sampler dimension a camera sample's time comes from: far from the path's own.
const TIME_DIMENSION: u32 = 0x4000_0000;

/// The sampler dimension a camera sample's wavelengths come from, beside its time's.
const WAVELENGTH_DIMENSION: u32 = 0x4000_0001;

/// One camera sample: its radiance (zeroed if not finite) and filter weight. (SPPM has no
/// estimate from one camera sample: it gives black; its pixels come from [`render_tile`].)
pub fn render_sample(
    renderer: &Renderer,
    x: u32,
    y: u32,
    sample: u32,
    stats: &mut TileStats,
) -> (Color, f32) {
    let (l, w, _) = render_sample_seeing(renderer, x, y, sample, stats, None);
    (l, w)
}

/// [`render_sample`], and with `gbuffer` the first surface the sample saw, in that space,
/// with its screen-space derivatives.
fn render_sample_seeing(
    renderer: &Renderer,
    x: u32,
    y: u32,
    sample: u32,
    stats: &mut TileStats,
    gbuffer: Option<kiln_scene::GBufferSpace>,
) -> (Color, f32, Option<VisibleSurface>) {
    let (scene, settings) = (&renderer.scene, &renderer.settings);
    let mut seen = None;
    let CameraSample {
        mut sampler,
        film,
        lens,
        time,
        weight,
        ray,
        waves,
    } = camera_sample(renderer, x, y, sample);
    let mut work = Work::default();
    // A realistic camera's lens may stop the ray (the sample counts, black) and weighs it.
    let mut l = match ray {
        Some((ray, camera_weight)) => {
            let l = settings.integrator.li(
                &renderer.prepass,
                scene,
                settings.footprint(),
                ray,
                &mut sampler,
                &mut work,
                gbuffer.is_some().then_some(&mut seen),
                waves,
            ) * camera_weight;
            if let (Some(space), Some(s)) = (gbuffer, seen.as_mut()) {
                *s = seen_from_camera(renderer, s, &ray, film, lens, time, space);
            }
            l
        }
        None => Color::ZERO,
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
    (scene.sensor.respond(l, waves.is_some()), weight, seen)
}

/// A visible surface with its screen-space derivatives, in the G-buffer's space. The
/// derivatives are pbrt-v4's: rays through the next pixel right and down (same lens sample
/// and time), their offsets scaled by the footprint scale (1/sqrt(spp), at least 1/8), met
/// on the surface's tangent plane.
fn seen_from_camera(
    renderer: &Renderer,
    s: &VisibleSurface,
    ray: &crate::math::Ray,
    film: Vec2,
    lens: Vec2,
    time: f32,
    space: kiln_scene::GBufferSpace,
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
        kiln_scene::GBufferSpace::World => world,
        kiln_scene::GBufferSpace::Camera => {
            world.transformed(&camera.camera_to_world_at(time).inverse())
        }
    }
}
