//! Kiln's denoiser: a clean picture from a render of a few samples per pixel, guided by the
//! feature buffers every Kiln render keeps beside its beauty (`features.albedo`,
//! `features.normal`, `features.depth` and `features.variance`, see
//! `kiln_render::features`).
//!
//! Two denoisers: the built-in one ([`atrous`], a feature- and variance-guided à-trous
//! wavelet filter written for Kiln), in every build and deterministic, the same bytes for
//! the same input on any machine and thread count; and Intel Open Image Denoise behind the
//! `oidn` cargo feature ([`Denoiser::Oidn`]), whose neural network runs in floating point
//! that differs between CPUs, so its output is not bit-reproducible across machines.
//! [`metrics`] holds the figures the denoisers are measured by.
//!
//! The crate knows nothing of scenes, files or the farm: it takes an image in memory, with
//! its feature channels, and gives pixels back.

pub mod atrous;
pub mod metrics;
#[cfg(feature = "oidn")]
mod oidn;
pub mod regression;

use kiln_image::RgbBuffer;

pub use atrous::Settings;
pub use regression::Regression;

/// The feature channels a render keeps, as `kiln_render::features` names them.
pub const ALBEDO: [&str; 3] = [
    "features.albedo.R",
    "features.albedo.G",
    "features.albedo.B",
];
pub const NORMAL: [&str; 3] = [
    "features.normal.X",
    "features.normal.Y",
    "features.normal.Z",
];
pub const DEPTH: &str = "features.depth";
pub const VARIANCE: [&str; 3] = [
    "features.variance.R",
    "features.variance.G",
    "features.variance.B",
];

/// The channel names a denoised image keeps its raw beauty under.
pub const RAW: [&str; 3] = ["raw.R", "raw.G", "raw.B"];

/// Why an image could not be denoised.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    #[error(
        "the image has no channel '{0}': it holds no feature buffers (a render by Kiln before they were kept, by SPPM, or by another renderer)"
    )]
    MissingChannel(String),
    #[error(
        "the image's feature buffers say nothing of its noise (every pixel's variance is zero: SPPM keeps none), so it cannot be denoised"
    )]
    NoVariance,
    #[error("Open Image Denoise failed: {0}")]
    Oidn(String),
    #[error("this kiln was built without Open Image Denoise (cargo feature `oidn`)")]
    NoOidn,
}

/// Which denoiser.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Denoiser {
    /// The built-in filter: deterministic, in every build. Its à-trous stage, then (unless
    /// None) its regression stage.
    BuiltIn(Settings, Option<Regression>),
    /// Intel Open Image Denoise (the `oidn` cargo feature): not bit-reproducible across
    /// CPUs.
    Oidn,
}

impl Denoiser {
    /// The built-in denoiser with its default settings.
    pub fn built_in() -> Denoiser {
        Denoiser::BuiltIn(Settings::default(), Some(Regression::default()))
    }

    /// Whether its output is the same bytes on every machine.
    pub fn reproducible(&self) -> bool {
        matches!(self, Denoiser::BuiltIn(..))
    }

    pub fn name(&self) -> &'static str {
        match self {
            Denoiser::BuiltIn(..) => "kiln",
            Denoiser::Oidn => "oidn",
        }
    }

    /// Whether this build has Open Image Denoise.
    pub fn oidn_available() -> bool {
        cfg!(feature = "oidn")
    }
}

/// A noisy image and its features, pixel by pixel, row-major.
#[derive(Debug, Clone)]
pub struct Noisy<'a> {
    pub width: usize,
    pub height: usize,
    pub color: std::borrow::Cow<'a, [[f32; 3]]>,
    pub albedo: Vec<[f32; 3]>,
    /// Unit shading normals (zero: no surface).
    pub normal: Vec<[f32; 3]>,
    pub depth: Vec<f32>,
    /// The variance of each pixel's value, by channel.
    pub variance: Vec<[f32; 3]>,
}

impl<'a> Noisy<'a> {
    /// The beauty of `image` with its feature channels: its raw beauty (`raw.*`) if it was
    /// denoised already, so that denoising again gives the same image, else its R, G and B.
    pub fn from_image(image: &'a RgbBuffer) -> Result<Noisy<'a>, Error> {
        let names = &image.aovs.names;
        let at = |name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| Error::MissingChannel(name.to_string()))
        };
        let at3 =
            |n: [&str; 3]| -> Result<[usize; 3], Error> { Ok([at(n[0])?, at(n[1])?, at(n[2])?]) };
        let (a, n, d, v) = (at3(ALBEDO)?, at3(NORMAL)?, at(DEPTH)?, at3(VARIANCE)?);
        let per = names.len();
        let pixel = |i: usize| &image.aovs.values[i * per..(i + 1) * per];
        let count = image.pixels.len();
        let three = |slots: [usize; 3]| -> Vec<[f32; 3]> {
            (0..count).map(|i| slots.map(|s| pixel(i)[s])).collect()
        };
        let variance = three(v);
        if variance.iter().all(|v| *v == [0.0; 3]) {
            return Err(Error::NoVariance);
        }
        let color = match RAW.map(|n| names.iter().position(|s| s == n)) {
            [Some(r), Some(g), Some(b)] => std::borrow::Cow::Owned(three([r, g, b])),
            _ => std::borrow::Cow::Borrowed(&image.pixels[..]),
        };
        Ok(Noisy {
            width: image.width as usize,
            height: image.height as usize,
            color,
            albedo: three(a),
            normal: three(n),
            depth: (0..count).map(|i| pixel(i)[d]).collect(),
            variance,
        })
    }
}

/// Denoises `image`'s beauty with `denoiser`, calling `progress(done, of)` as it goes.
pub fn denoise(
    image: &RgbBuffer,
    denoiser: Denoiser,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<Vec<[f32; 3]>, Error> {
    let noisy = Noisy::from_image(image)?;
    match denoiser {
        Denoiser::BuiltIn(settings, regression) => {
            let (color, variance) = atrous::denoise(&noisy, &settings, progress);
            let Some(r) = regression else {
                return Ok(color);
            };
            let smooth = regression::Smooth {
                color: &color,
                variance: &variance,
            };
            let out = regression::refine(&noisy, &smooth, &r);
            progress(settings.iterations + 1, settings.iterations + 1);
            Ok(out)
        }
        #[cfg(feature = "oidn")]
        Denoiser::Oidn => oidn::denoise(&noisy),
        #[cfg(not(feature = "oidn"))]
        Denoiser::Oidn => Err(Error::NoOidn),
    }
}

/// `image` with `denoised` as its beauty and its raw beauty kept beside it as the `raw.R`,
/// `raw.G` and `raw.B` channels (its features and other channels kept as they were; an
/// image denoised before keeps the raw channels it has).
pub fn with_denoised(image: &RgbBuffer, denoised: Vec<[f32; 3]>) -> RgbBuffer {
    let mut out = image.clone();
    let old = &image.aovs.names;
    let had_raw = RAW.iter().all(|n| old.iter().any(|o| o == n));
    let mut names: Vec<String> = old.iter().cloned().chain(RAW.map(String::from)).collect();
    names.sort();
    names.dedup();
    let per = names.len();
    let slot_of_old: Vec<usize> = old
        .iter()
        .map(|n| names.iter().position(|s| s == n).expect("kept"))
        .collect();
    let raw = RAW.map(|n| names.iter().position(|s| s == n).expect("added"));
    let mut values = vec![0.0f32; per * image.pixels.len()];
    for (i, px) in image.pixels.iter().enumerate() {
        let row = &mut values[i * per..(i + 1) * per];
        for (k, &slot) in slot_of_old.iter().enumerate() {
            row[slot] = image.aovs.values[i * old.len() + k];
        }
        if !had_raw {
            for c in 0..3 {
                row[raw[c]] = px[c];
            }
        }
    }
    out.aovs.names = names;
    out.aovs.values = values;
    out.pixels = denoised;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 48x32 flat grey wall with noise of a known variance, and a darker square of
    /// another albedo in it: its features and its clean picture.
    fn wall() -> (RgbBuffer, Vec<[f32; 3]>) {
        let (w, h) = (48u32, 32u32);
        let names = [ALBEDO, NORMAL, VARIANCE]
            .concat()
            .into_iter()
            .chain([DEPTH])
            .collect::<Vec<_>>();
        let mut image = RgbBuffer::new(w, h, 0, 0, w, h).with_aovs(names);
        let mut clean = Vec::new();
        let per = image.aovs.names.len();
        let mut state = 0x2545_f491_u32;
        for i in 0..(w * h) as usize {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let albedo = if (16..32).contains(&x) && (8..24).contains(&y) {
                0.2
            } else {
                0.6
            };
            let truth = albedo * 0.8;
            // xorshift32: noise of variance 1/12 * 0.09, uniform.
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let u = state as f32 / u32::MAX as f32 - 0.5;
            image.pixels[i] = [truth + 0.3 * u; 3];
            clean.push([truth; 3]);
            for (k, name) in image.aovs.names.clone().iter().enumerate() {
                image.aovs.values[i * per + k] = match name.as_str() {
                    n if n.starts_with("features.albedo") => albedo,
                    "features.normal.Z" | "features.depth" => 1.0,
                    n if n.starts_with("features.variance") => 0.09 / 12.0,
                    _ => 0.0,
                };
            }
        }
        (image, clean)
    }

    #[test]
    fn the_built_in_denoiser_removes_noise_keeps_the_edge_and_is_the_same_on_any_thread_count() {
        let (image, clean) = wall();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| denoise(&image, Denoiser::built_in(), &|_, _| {}).unwrap())
        };
        let one = run(1);
        assert_eq!(
            one.iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            run(3)
                .iter()
                .flatten()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        );
        let raw = metrics::rel_mse(&image.pixels, &clean, None);
        let denoised = metrics::rel_mse(&one, &clean, None);
        assert!(denoised < raw / 10.0, "{denoised} against {raw}");
        // Denoising the denoised image again starts from its raw beauty: the same image.
        let again = with_denoised(&with_denoised(&image, one.clone()), one.clone());
        let twice = denoise(&again, Denoiser::built_in(), &|_, _| {}).unwrap();
        assert_eq!(twice, one);
        assert_eq!(
            again
                .aovs
                .names
                .iter()
                .filter(|n| n.starts_with("raw."))
                .count(),
            3
        );
        // The square's edge stays: its pixels stay dark, the wall's light.
        assert!(
            (one[16 * 48 + 24][0] - 0.16).abs() < 0.03,
            "{:?}",
            one[16 * 48 + 24]
        );
        assert!(
            (one[16 * 48 + 14][0] - 0.48).abs() < 0.03,
            "{:?}",
            one[16 * 48 + 14]
        );
    }

    #[test]
    fn an_image_without_features_or_variance_is_refused_by_name() {
        let bare = RgbBuffer::new(4, 4, 0, 0, 4, 4);
        assert_eq!(
            denoise(&bare, Denoiser::built_in(), &|_, _| {}).unwrap_err(),
            Error::MissingChannel("features.albedo.R".into())
        );
        let (mut image, _) = wall();
        let per = image.aovs.names.len();
        for (k, name) in image.aovs.names.clone().iter().enumerate() {
            if name.starts_with("features.variance") {
                image
                    .aovs
                    .values
                    .iter_mut()
                    .skip(k)
                    .step_by(per)
                    .for_each(|v| *v = 0.0);
            }
        }
        assert_eq!(
            denoise(&image, Denoiser::built_in(), &|_, _| {}).unwrap_err(),
            Error::NoVariance
        );
    }

    /// With the `oidn` feature (CI builds it against the PyPI wheel's library), Open Image
    /// Denoise runs on the features and removes most of the noise.
    #[cfg(feature = "oidn")]
    #[test]
    fn open_image_denoise_removes_noise() {
        let (image, clean) = wall();
        let out = denoise(&image, Denoiser::Oidn, &|_, _| {}).unwrap();
        let raw = metrics::rel_mse(&image.pixels, &clean, None);
        let denoised = metrics::rel_mse(&out, &clean, None);
        assert!(denoised < raw / 4.0, "{denoised} against {raw}");
    }

    #[cfg(not(feature = "oidn"))]
    #[test]
    fn without_the_feature_open_image_denoise_says_so() {
        let (image, _) = wall();
        assert_eq!(
            denoise(&image, Denoiser::Oidn, &|_, _| {}).unwrap_err(),
            Error::NoOidn
        );
    }
}
