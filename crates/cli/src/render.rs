//! `kiln render`: load a scene, render it tile by tile, write the EXR.

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use kiln_image::RgbBuffer;
use kiln_render::{Renderer, TileStats, render_tiles, split_into_tiles};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The pbrt-v4 scene file.
    scene: PathBuf,
    /// Output EXR (default: the Film's filename with an .exr extension, beside the current directory).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per pixel (default: the scene's Sampler "pixelsamples").
    #[arg(long)]
    spp: Option<u32>,
    /// Filter textures as a render of this many samples per pixel does (pbrt-v4 narrows the
    /// filter footprint with the sample count, down to 64). The image is then the first
    /// --spp samples of that longer render: what a farm job in passes holds after a pass
    /// of fewer than 64 samples, the footprint being that of its last pass.
    #[arg(long)]
    footprint_spp: Option<u32>,
    /// Adaptive sampling: a pixel stops taking samples once its estimate's error is below
    /// this (default: the scene's Sampler "noisethreshold"; 0 turns it off).
    #[arg(long, allow_hyphen_values = true)]
    noise_threshold: Option<f32>,
    /// Render spectrally: four wavelengths per camera sample, colours as spectra, as
    /// pbrt-v4 renders. This is the default unless the scene says
    /// Option "kiln.spectral" false (as Kiln's own scenes do).
    #[arg(long, conflicts_with = "rgb")]
    spectral: bool,
    /// Render in RGB (three colour channels per sample): faster, but off where light
    /// bounces many times through colour.
    #[arg(long)]
    rgb: bool,
    /// Resolution as WIDTHxHEIGHT (default: the scene's Film).
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<(u32, u32)>,
    /// Tile size in pixels.
    #[arg(long, default_value_t = 32)]
    tile: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of the sampler (default: the scene's Sampler "seed", or 0).
    #[arg(long)]
    seed: Option<u32>,
    /// Also write an sRGB PNG preview.
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Exposure of the preview in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// Denoise the image with its feature buffers: the denoised beauty as the EXR's R, G
    /// and B (and the preview), the raw beauty as raw.R, raw.G and raw.B.
    #[arg(long)]
    denoise: bool,
    /// Which denoiser --denoise uses.
    #[arg(long, value_enum, default_value_t = crate::denoise::Choice::Kiln, requires = "denoise")]
    denoiser: crate::denoise::Choice,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// The most pixels the rendered frame may hold (it is kept in memory).
    #[arg(long, default_value_t = kiln_image::MAX_PIXELS)]
    max_frame_pixels: u64,
}

pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in '{s}'"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in '{s}'"))?;
    if w == 0 || h == 0 || w > 65536 || h > 65536 {
        return Err(format!("resolution '{s}' is out of range"));
    }
    Ok((w, h))
}

pub fn run(args: RenderArgs) -> Result<()> {
    let start = Instant::now();
    let output = check_output(&args)?;
    if args.denoise {
        args.denoiser.check_available()?;
    }
    let (desc, renderer) = load(&args)?;
    let load_time = start.elapsed();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()
        .context("cannot start the worker threads")?;
    let film = &desc.film;
    let tiles = split_into_tiles(film.pixel_bounds, args.tile);
    let output = output.unwrap_or_else(|| {
        let mut p = PathBuf::from(&film.filename);
        p.set_extension("exr");
        p
    });
    announce(
        &args,
        &desc,
        &renderer,
        tiles.len(),
        pool.current_num_threads(),
    );
    let progress = progress_bar(&args, &renderer, tiles.len());
    let render_start = Instant::now();
    let results = pool.install(|| render_tiles(&renderer, &tiles, &|| progress.inc(1)));
    progress.finish_and_clear();
    let render_time = render_start.elapsed();
    let [x0, x1, y0, y1] = film.pixel_bounds;
    let mut frame = RgbBuffer::new(film.xresolution, film.yresolution, x0, y0, x1 - x0, y1 - y0)
        .with_aovs(kiln_render::aov_names(film.gbuffer));
    let mut stats = TileStats::default();
    for r in results {
        stats.merge(&r.stats);
        let t = r.rect;
        let aovs = kiln_image::Aovs {
            names: kiln_render::aov_names(renderer.settings().gbuffer),
            values: r.aovs,
        };
        let tile = RgbBuffer::new(
            film.xresolution,
            film.yresolution,
            t.x0,
            t.y0,
            t.width,
            t.height,
        )
        .holding(r.pixels, aovs);
        frame.paste(&tile)?;
    }
    if let Some(why) = stats.cut_off_error() {
        bail!("{}: {why}; no image was written", args.scene.display());
    }
    if args.denoise {
        // The raw render is kept if denoising fails: nothing rendered is lost.
        match crate::denoise::denoise_frame(&frame, args.denoiser, args.quiet) {
            Ok(denoised) => frame = denoised,
            Err(e) => {
                kiln_image::write_exr(&output, &frame)
                    .with_context(|| format!("cannot write {}", output.display()))?;
                return Err(e.context(format!(
                    "the raw render was written to {}, not denoised",
                    output.display()
                )));
            }
        }
    }
    kiln_image::write_exr(&output, &frame)
        .with_context(|| format!("cannot write {}", output.display()))?;
    if let Some(preview) = &args.preview {
        kiln_image::write_png(preview, &frame, args.exposure)
            .with_context(|| format!("cannot write {}", preview.display()))?;
    }
    let times = Times {
        total: start.elapsed().as_secs_f64(),
        load: load_time.as_secs_f64(),
        render: render_time.as_secs_f64().max(1e-9),
    };
    summarise(&output, &frame, &stats, &renderer, times);
    Ok(())
}

/// The output file the flags name, refused before any work unless it is an EXR.
fn check_output(args: &RenderArgs) -> Result<Option<PathBuf>> {
    if args.tile == 0 {
        bail!("--tile must be at least 1");
    }
    // An image named otherwise would still be an EXR: refuse it before any work is done.
    if let Some(out) = &args.output
        && !out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        bail!(
            "--output {}: Kiln writes OpenEXR; name it .exr (add --preview FILE.png for an sRGB PNG)",
            out.display()
        );
    }
    Ok(args.output.clone())
}

/// Loads the scene with the flags' overrides and builds its renderer.
fn load(args: &RenderArgs) -> Result<(kiln_scene::SceneDescription, Renderer)> {
    let mut desc = kiln_scene::load_file(&args.scene)?;
    for w in &desc.warnings {
        eprintln!("{w}");
    }
    desc.apply_overrides(&kiln_scene::Overrides {
        resolution: args.resolution,
        spp: args.spp,
        seed: args.seed,
        noise_threshold: args.noise_threshold,
        spectral: if args.spectral {
            Some(true)
        } else if args.rgb {
            Some(false)
        } else {
            None
        },
    })
    .map_err(anyhow::Error::msg)?;
    desc.check_frame_size(args.max_frame_pixels)
        .map_err(anyhow::Error::msg)?;
    let mut renderer = Renderer::build(&desc)?;
    if let Some(spp) = args.footprint_spp {
        if spp == 0 {
            bail!("--footprint-spp must be at least 1");
        }
        renderer = renderer.with_footprint_spp(spp);
    }
    Ok((desc, renderer))
}

/// The line that says what is about to be rendered.
fn announce(
    args: &RenderArgs,
    desc: &kiln_scene::SceneDescription,
    renderer: &Renderer,
    tiles: usize,
    threads: usize,
) {
    let scene = renderer.scene();
    let film = &desc.film;
    let [x0, x1, y0, y1] = film.pixel_bounds;
    eprintln!(
        "kiln: {} ({} triangles, {} spheres, {} other quadrics, {} lights), {}x{} ({}x{} rendered), {} spp, {} tiles, {} threads{}",
        args.scene.display(),
        scene.geometry.triangle_count(),
        scene.geometry.prims.spheres.len(),
        scene.geometry.prims.quadrics.len(),
        scene.lights.len(),
        film.xresolution,
        film.yresolution,
        x1 - x0,
        y1 - y0,
        renderer.settings().samples_per_pixel,
        tiles,
        threads,
        scene
            .geometry
            .bvh_kernel()
            .map_or(String::new(), |k| format!(", BVH kernel {k:?}")),
    );
}

/// A progress bar over tiles (over iterations for SPPM), hidden with --quiet.
fn progress_bar(args: &RenderArgs, renderer: &Renderer, tiles: usize) -> ProgressBar {
    if args.quiet {
        return ProgressBar::hidden();
    }
    let units = kiln_render::progress_units(renderer, tiles);
    let bar = ProgressBar::new(units);
    // SPPM renders every tile together, an iteration at a time.
    let what = if units == tiles as u64 {
        "tiles"
    } else {
        "iterations"
    };
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} [{{elapsed_precise}}] [{{wide_bar}}] {{pos}}/{{len}} {what} ({{eta}} left)"
        ))
        .expect("the template is valid")
        .progress_chars("=> "),
    );
    bar
}

/// Seconds the whole command, the scene's loading and the rendering took.
struct Times {
    total: f64,
    load: f64,
    render: f64,
}

/// The summary after the image is written: samples that were not finite, speed, the mean
/// colour and what adaptive sampling took.
fn summarise(
    output: &std::path::Path,
    frame: &RgbBuffer,
    stats: &TileStats,
    renderer: &Renderer,
    times: Times,
) {
    if stats.nonfinite > 0 {
        eprintln!(
            "warning: {} samples had NaN or infinite radiance and were counted as black; first ones (pixel x, y, sample):",
            stats.nonfinite
        );
        for e in &stats.nonfinite_examples {
            eprintln!("  {} {} {}", e.x, e.y, e.sample);
        }
    }
    let secs = times.render;
    let mean = frame.mean();
    eprintln!(
        "kiln: wrote {} in {:.2} s (scene {:.2} s, render {:.2} s): {:.3} M samples/s, {:.3} M rays/s, mean RGB {:.5} {:.5} {:.5}",
        output.display(),
        times.total,
        times.load,
        secs,
        stats.samples as f64 / secs / 1e6,
        stats.rays as f64 / secs / 1e6,
        mean[0],
        mean[1],
        mean[2],
    );
    if let Some(a) = renderer.settings().adaptive
        && !matches!(
            renderer.settings().integrator,
            kiln_render::Integrator::Sppm(_)
        )
    {
        let pixels = u64::from(frame.width) * u64::from(frame.height);
        let spp = renderer.settings().samples_per_pixel;
        eprintln!(
            "kiln: adaptive sampling (noise threshold {}, from {} samples): {:.1} samples per pixel on average, of {spp}",
            a.threshold,
            a.min_samples,
            stats.samples as f64 / pixels.max(1) as f64,
        );
    }
}
