//! The tile function: the pure function from (scene, settings, tile) to pixels
//! that `kiln render` and the farm's workers both call, and the [`Renderer`] it renders
//! with: a scene, its settings, and the integrator's pre-passes, done once per job.

mod sample;
mod wave;

use crate::adaptive::Adaptive;
use crate::film::FilmChannels;
use crate::integrators::photons::Gather;
use crate::integrators::sppm::PassCache;
use crate::integrators::{Integrator, PathTracer, Prepass};
use crate::math::Color;
use crate::rect::TileRect;
use crate::scene::{BuildError, MediaPolicy, Scene};
use crate::shared::SharedPrepass;
use crate::sums::{PixelSums, SumsLayout, TileSums};
use crate::work::Work;
use rayon::prelude::*;
use sample::{CameraSample, camera_sample};
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

    /// The path tracer of this render's camera rays (not SPPM's, which has its own driver).
    fn path_tracer(&self) -> PathTracer<'_> {
        self.settings
            .integrator
            .path_tracer(&self.prepass, &self.scene, self.settings.footprint())
            .expect("SPPM renders through its own driver")
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
    /// Each pixel's further channels in turn, named by [`aov_names`]: the denoiser's
    /// features ([`crate::features`]) and with a G-buffer film its channels.
    pub aovs: Vec<f32>,
    pub stats: TileStats,
}

/// The names of the further channels a film writes beside R, G and B (sorted, as images
/// hold them): the denoiser's features, and a G-buffer's if it has one.
pub fn aov_names(gbuffer: Option<kiln_scene::GBufferSpace>) -> Vec<String> {
    FilmChannels::new(gbuffer).names().to_vec()
}

/// Renders one tile. The result depends only on the scene, the settings and the
/// tile's pixels: not on the tile's size, its neighbours, or the thread count.
pub fn render_tile(renderer: &Renderer, rect: TileRect) -> TileResult {
    render_tile_until(renderer, rect, &|| false).expect("never stopped")
}

/// [`render_tile`], asking `stop` before each round of a row (a wave of at most 512 paths,
/// or one sample of each pixel of a wider row): None as soon as it says yes (a job
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
    continue_tile_in_waves(renderer, from, to, wave::WAVE, stop)
}

/// [`continue_tile`] with at most `wave` paths at a time in each row.
fn continue_tile_in_waves(
    renderer: &Renderer,
    from: &TileSums,
    to: u32,
    wave: usize,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<(TileResult, TileSums)> {
    let rect = from.rect;
    let film = FilmChannels::new(renderer.settings.gbuffer);
    let channels = film.channels();
    let want = film.gbuffer_space();
    let width = rect.width as usize;
    type Row = (Vec<[f32; 3]>, Vec<f32>, Vec<PixelSums>, TileStats);
    let rows: Option<Vec<Row>> = (0..rect.height as usize)
        .into_par_iter()
        .map_init(
            || wave::Wave::new(wave),
            |room, row| {
                let y = rect.y0 + row as u32;
                let mut stats = TileStats::default();
                let mut aovs = vec![0.0f32; channels * width];
                let mut sums = from.pixels[row * width..(row + 1) * width].to_vec();
                let samples = from.samples..to;
                let at = (rect.x0, y);
                let (sums_, stats_) = (&mut sums, &mut stats);
                wave::add_row_samples(renderer, room, at, sums_, samples, want, stats_, stop)?;
                let mut pixels = Vec::with_capacity(width);
                for (i, p) in sums.iter().enumerate() {
                    film.finish(p, &mut aovs[i * channels..(i + 1) * channels]);
                    pixels.push(p.value());
                }
                Some((pixels, aovs, sums, stats))
            },
        )
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

/// The paths' reference: [`render_tile`] with every sample traced on its own, one path from
/// the camera to its end after another, or with at most `wave` paths at a time in each row
/// (production renders [`WAVE`](wave::WAVE) at a time). The same bytes every way, which the
/// tests hold it to; not for production use.
#[doc(hidden)]
pub fn render_tile_reference(
    renderer: &Renderer,
    rect: TileRect,
    wave: Option<usize>,
) -> TileResult {
    let from = TileSums::empty(rect, renderer.settings.sums_layout());
    let to = renderer.settings.samples_per_pixel;
    if let Some(wave) = wave {
        return continue_tile_in_waves(renderer, &from, to, wave, &|| false)
            .expect("never stopped")
            .0;
    }
    let film = FilmChannels::new(renderer.settings.gbuffer);
    let channels = film.channels();
    let want = film.gbuffer_space();
    let adaptive = renderer.settings.adaptive;
    let mut result = TileResult {
        rect,
        pixels: Vec::new(),
        aovs: vec![0.0; rect.pixel_count() as usize * channels],
        stats: TileStats::default(),
    };
    for (i, mut p) in from.pixels.into_iter().enumerate() {
        let (x, y) = (
            rect.x0 + i as u32 % rect.width,
            rect.y0 + i as u32 / rect.width,
        );
        for s in 0..to {
            if p.taken < s || adaptive.is_some_and(|a| a.converged(&p)) {
                break;
            }
            let sample = sample::render_sample_seeing(renderer, x, y, s, &mut result.stats, want);
            sample::accumulate(&mut p, s, sample, want.is_some());
        }
        film.finish(&p, &mut result.aovs[i * channels..(i + 1) * channels]);
        result.pixels.push(p.value());
    }
    result
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
                let CameraSample { mut sampler, shot } = camera_sample(renderer, x, y, it);
                let mut work = Work::default();
                let (ray, weight) = shot
                    .ray
                    .map_or((None, 0.0), |(r, w)| (Some(r), w * shot.weight));
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
    // SPPM's pixels are no means of samples: they keep no variance, and no features yet
    // (every pixel's are those of a path that saw nothing), so they are not denoised.
    let film = FilmChannels::new(None);
    let mut nothing = PixelSums {
        weight: 1.0,
        ..PixelSums::default()
    };
    nothing
        .features
        .add(&crate::features::Feature::NOTHING, 1.0);
    let mut aov = vec![0.0; film.channels()];
    film.finish(&nothing, &mut aov);
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
            aovs: aov.repeat(n),
            stats,
        });
        start += n;
    }
    Some(results)
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
    let mut p = [PixelSums::default()];
    let samples = 0..renderer.settings.samples_per_pixel;
    let room = &mut wave::Wave::new(wave::WAVE);
    wave::add_row_samples(
        renderer,
        room,
        (x, y),
        &mut p,
        samples,
        None,
        stats,
        &|| false,
    )
    .expect("never stopped");
    p[0].value()
}
