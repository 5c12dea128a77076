//! `kiln denoise` and `kiln render --denoise`: a render's beauty denoised with its feature
//! buffers, the raw beauty kept beside it.

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use kiln_denoise::Denoiser;
use kiln_image::RgbBuffer;
use std::path::PathBuf;
use std::time::Instant;

/// Which denoiser a command uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Choice {
    /// Kiln's own filter: the same bytes on every machine.
    Kiln,
    /// Intel Open Image Denoise (a build with the `oidn` feature): not bit-reproducible
    /// across CPUs.
    Oidn,
}

impl Choice {
    /// Refuses, before any work, a denoiser this build does not have.
    pub fn check_available(self) -> Result<()> {
        if self == Choice::Oidn && !Denoiser::oidn_available() {
            anyhow::bail!(
                "--denoiser oidn: this kiln was built without Open Image Denoise (build with --features oidn and OIDN_DIR)"
            );
        }
        Ok(())
    }

    pub fn denoiser(self) -> Denoiser {
        match self {
            Choice::Kiln => Denoiser::built_in(),
            Choice::Oidn => Denoiser::Oidn,
        }
    }
}

#[derive(clap::Args)]
pub struct DenoiseArgs {
    /// A Kiln render's EXR (it holds the feature buffers).
    input: PathBuf,
    /// The denoised EXR: the denoised beauty as R, G and B, the raw beauty as raw.R, raw.G
    /// and raw.B, the features as they were.
    #[arg(short, long)]
    output: PathBuf,
    /// Which denoiser.
    #[arg(long, value_enum, default_value_t = Choice::Kiln)]
    denoiser: Choice,
    /// Also write an sRGB PNG preview of the denoised beauty.
    #[arg(long)]
    preview: Option<PathBuf>,
    /// Exposure of the preview in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

pub fn run(args: DenoiseArgs) -> Result<()> {
    args.denoiser.check_available()?;
    let bytes = std::fs::read(&args.input)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let image = kiln_image::decode_exr(&bytes)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let out = denoise_frame(&image, args.denoiser, args.quiet)
        .with_context(|| format!("cannot denoise {}", args.input.display()))?;
    kiln_image::write_exr(&args.output, &out)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Some(preview) = &args.preview {
        kiln_image::write_png(preview, &out, args.exposure)
            .with_context(|| format!("cannot write {}", preview.display()))?;
    }
    eprintln!("kiln: wrote {}", args.output.display());
    Ok(())
}

/// `frame` denoised with `choice` (its raw beauty kept as the raw.* channels), with a
/// progress bar unless `quiet`, and a line saying how long it took.
pub fn denoise_frame(frame: &RgbBuffer, choice: Choice, quiet: bool) -> Result<RgbBuffer> {
    let denoiser = choice.denoiser();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::new(0);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] [{wide_bar}] {pos}/{len} denoising passes",
            )
            .expect("the template is valid")
            .progress_chars("=> "),
        );
        bar
    };
    let start = Instant::now();
    let denoised = kiln_denoise::denoise(frame, denoiser, &|done, of| {
        bar.set_length(u64::from(of));
        bar.set_position(u64::from(done));
    })?;
    bar.finish_and_clear();
    eprintln!(
        "kiln: denoised {}x{} with {} in {:.2} s{}",
        frame.width,
        frame.height,
        denoiser.name(),
        start.elapsed().as_secs_f64(),
        if denoiser.reproducible() {
            ""
        } else {
            " (not bit-reproducible across CPUs)"
        }
    );
    Ok(kiln_denoise::with_denoised(frame, denoised))
}
