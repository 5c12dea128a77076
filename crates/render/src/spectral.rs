//! Spectral rendering as pbrt-v4 does it: each camera sample carries four wavelengths, a
//! `Color`'s four lanes are the path's values at them, RGB inputs become spectra where a
//! path meets them, and the film turns each sample back into linear sRGB.
//!
//! This module knows nothing else in the crate: a colour here is the [`Vec4`] that
//! `math::Color` is (an RGB colour's fourth lane repeating green).
//!
//! - Wavelengths: pbrt-v4's visible-wavelength density (peaked near 538 nm, 360–830 nm),
//!   a hero wavelength from one sampler dimension and three more at offsets of a quarter
//!   in that dimension (stratified).
//! - RGB to spectrum (pbrt-v4's three kinds): reflectances are sigmoid-quadratic spectra
//!   bounded by 0 and 1 ([`Wavelengths::albedo`]); unbounded values are twice their
//!   largest component times the spectrum of the colour scaled to a largest component of
//!   ½ ([`Wavelengths::unbounded`]); light is an unbounded spectrum times the sRGB white,
//!   D65 ([`Wavelengths::illuminant`]). The coefficients come from Kiln's own table
//!   (`kiln_scene::sigmoid_table`).
//! - The film: each lane's value over its wavelength's density, times the sRGB response
//!   at that wavelength, averaged over the lanes ([`Wavelengths::to_rgb`]); negative,
//!   out-of-gamut values are kept, as pbrt-v4's film keeps them. A reflectance under D65
//!   light is then, in expectation, exactly the RGB the scene gave it (within the table's
//!   2e-3).

use glam::Vec4;
use kiln_scene::sigmoid_table::{Coefficients, SigmoidTable};
use std::sync::OnceLock;

/// The shortest and longest wavelengths sampled, nm.
const LAMBDA_MIN: f32 = 360.0;
const LAMBDA_MAX: f32 = 830.0;

/// The sRGB response and normalised D65 at every nanometre (see
/// `kiln_scene::spectrum::srgb_response_per_nm`), as lanes (r̄, ḡ, b̄, D65).
fn response() -> &'static [Vec4] {
    static TABLE: OnceLock<Vec<Vec4>> = OnceLock::new();
    TABLE.get_or_init(|| {
        kiln_scene::spectrum::srgb_response_per_nm()
            .iter()
            .map(|v| Vec4::from_array(v.map(|x| x as f32)))
            .collect()
    })
}

/// The response at `lambda` nm, linear between the nanometres.
fn response_at(lambda: f32) -> Vec4 {
    let table = response();
    let (i, u) = per_nm(lambda, table.len());
    table[i] * (1.0 - u) + table[i + 1] * u
}

/// Where `lambda` falls in a table of `len` entries, one per nanometre from 360 nm: the entry
/// below it and the fraction of the way to the next (clamped to the table).
fn per_nm(lambda: f32, len: usize) -> (usize, f32) {
    let x = (lambda - LAMBDA_MIN).clamp(0.0, (len - 1) as f32);
    let i = (x as usize).min(len - 2);
    (i, x - i as f32)
}

/// Entries of each thread's memo of recent lookups.
const MEMO: usize = 32;

thread_local! {
    /// Each thread's last lookups, by colour: a scene's few constant colours (its lights, its
    /// untextured materials) are met again and again. A pure function's memo: it changes
    /// no bit of the result.
    static RECENT: std::cell::RefCell<[([u32; 3], Coefficients); MEMO]> =
        const { std::cell::RefCell::new([([u32::MAX; 3], [0.0; 3]); MEMO]) };
}

/// The sigmoid coefficients of `rgb` (sRGB, clamped to [0, 1]), from the table or the
/// thread's memo of it.
fn coefficients(rgb: [f32; 3]) -> Coefficients {
    let key = rgb.map(f32::to_bits);
    let slot =
        (key[0] ^ key[1].rotate_left(11) ^ key[2].rotate_left(22)).wrapping_mul(0x9E37_79B1) >> 27;
    RECENT.with_borrow_mut(|memo| {
        let entry = &mut memo[slot as usize % MEMO];
        if entry.0 != key {
            *entry = (key, SigmoidTable::srgb().coefficients(rgb));
        }
        entry.1
    })
}

/// A path's four wavelengths and their densities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wavelengths {
    /// nm.
    pub lambda: Vec4,
    /// One over each wavelength's density.
    pub inv_pdf: Vec4,
    /// Each lane's reduced wavelength t = (λ − 555) / 175, as the sigmoid spectra use it.
    t: Vec4,
    /// D65 at each wavelength, normalised to ∫ D65·ȳ = 1.
    d65: Vec4,
}

/// pbrt-v4's visible-wavelength sampling: the wavelength at `u` in [0, 1), and its density.
/// With x = 0.8569 − 1.8275·u the wavelength is 538 − 138.89·atanh(x), and as
/// 0.0072 · 138.89 = 1, the density 0.0039398 / cosh²(0.0072·(λ − 538)) is 0.0039398·(1 − x²).
fn sample_visible(u: f32) -> (f32, f32) {
    let x = 0.856_910_6 - 1.827_502 * u;
    let lambda = 538.0 - 138.888_89 * 0.5 * libm::logf((1.0 + x) / (1.0 - x));
    (lambda, 0.003_939_804 * (1.0 - x * x))
}

/// Its density at `lambda` (0 outside 360–830 nm).
#[cfg(test)]
fn visible_pdf(lambda: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let c = libm::coshf(0.0072 * (lambda - 538.0));
    0.003_939_804 / (c * c)
}

impl Wavelengths {
    /// Four wavelengths from one uniform number: the hero at `u`, the others at u + ¼,
    /// u + ½ and u + ¾ (wrapped into [0, 1)).
    pub fn sample(u: f32) -> Wavelengths {
        let mut lambda = [0.0; 4];
        let mut pdf = [0.0; 4];
        for i in 0..4 {
            let mut up = u + i as f32 / 4.0;
            if up >= 1.0 {
                up -= 1.0;
            }
            (lambda[i], pdf[i]) = sample_visible(up);
        }
        let lambda =
            Vec4::from_array(lambda).clamp(Vec4::splat(LAMBDA_MIN), Vec4::splat(LAMBDA_MAX));
        let inv_pdf = Vec4::ONE / Vec4::from_array(pdf);
        Wavelengths {
            lambda,
            inv_pdf,
            t: (lambda - Vec4::splat(555.0)) / 175.0,
            d65: Vec4::from_array(lambda.to_array().map(|l| response_at(l).w)),
        }
    }

    /// The spectrum of sigmoid coefficients `c` at these wavelengths.
    pub fn sigmoid(&self, c: Coefficients) -> Vec4 {
        if c[0].is_infinite() {
            return Vec4::splat(if c[0] > 0.0 { 1.0 } else { 0.0 });
        }
        let z = Vec4::splat(c[0]) + self.t * (Vec4::splat(c[1]) + self.t * c[2]);
        let root = Vec4::from_array((Vec4::ONE + z * z).to_array().map(f32::sqrt));
        Vec4::splat(0.5) + z / (2.0 * root)
    }

    /// A reflectance (RGB clamped to [0, 1]) as a spectrum bounded by 0 and 1.
    pub fn albedo(&self, rgb: Vec4) -> Vec4 {
        self.sigmoid(coefficients([rgb.x, rgb.y, rgb.z]))
    }

    /// A value that may exceed 1 (a scattering coefficient, an index of refraction), or
    /// the colour of light before its white: 2·max times the spectrum of rgb / (2·max).
    pub fn unbounded(&self, rgb: Vec4) -> Vec4 {
        let m = rgb.x.max(rgb.y).max(rgb.z);
        if m.is_nan() || m <= 0.0 {
            return Vec4::ZERO;
        }
        let scale = 2.0 * m;
        let scaled = [rgb.x, rgb.y, rgb.z].map(|c| c / scale);
        self.sigmoid(coefficients(scaled)) * scale
    }

    /// Light of RGB colour `rgb`: its unbounded spectrum times D65 (normalised so that
    /// (1, 1, 1) is exactly the sRGB white).
    pub fn illuminant(&self, rgb: Vec4) -> Vec4 {
        self.unbounded(rgb) * self.d65()
    }

    /// Light of RGB colour `rgb` that may lie outside the gamut (a film's estimate from four
    /// wavelengths, such as a stored photon's power): the light of its positive components
    /// less the light of its negative ones, so that the film records `rgb` back (a negative
    /// component made 0 instead would add light in that channel on average).
    pub fn signed_illuminant(&self, rgb: Vec4) -> Vec4 {
        let negative = (-rgb).max(Vec4::ZERO);
        if negative.x == 0.0 && negative.y == 0.0 && negative.z == 0.0 {
            return self.illuminant(rgb);
        }
        self.illuminant(rgb.max(Vec4::ZERO)) - self.illuminant(negative)
    }

    /// A spectrum made once ([`SigmoidSpectrum`]) at these wavelengths.
    pub fn of(&self, s: &SigmoidSpectrum) -> Vec4 {
        if s.scale == 0.0 {
            return Vec4::ZERO;
        }
        self.sigmoid(s.c) * s.scale
    }

    /// A blackbody at `kelvin` divided by its value at its peak wavelength (pbrt-v4's
    /// `BlackbodySpectrum`, which temperature grids emit), exactly: with r = λ_peak / λ it
    /// is r⁵ (e^x − 1) / (e^{x·r} − 1), x = hc / (λ_peak k T). Zero for kelvin <= 0.
    pub fn blackbody(&self, kelvin: f32) -> Vec4 {
        if kelvin.is_nan() || kelvin <= 0.0 {
            return Vec4::ZERO;
        }
        let peak = 2.897_772e6 / kelvin;
        Vec4::from_array(self.lambda.to_array().map(|l| {
            let r = peak / l;
            if WIEN_X * r > 80.0 {
                // Below 1e-28 of the peak (and r⁵ / (e^{x·r} − 1) would be ∞ / ∞).
                return 0.0;
            }
            let r2 = r * r;
            r2 * r2 * r * (libm::expm1f(WIEN_X) / libm::expm1f(WIEN_X * r))
        }))
    }

    /// D65 at these wavelengths, normalised to ∫ D65·ȳ = 1.
    pub fn d65(&self) -> Vec4 {
        self.d65
    }

    /// What the film records of radiance `l` at these wavelengths: linear sRGB (as an RGB
    /// `Color`), negative lanes kept.
    pub fn to_rgb(&self, l: Vec4) -> Vec4 {
        self.through(l, response())
    }

    /// What a sensor whose responses are `curves` (three per nanometre from 360 nm, the
    /// fourth lane ignored) records of radiance `l` at these wavelengths: each lane's value
    /// over its density times the curves there, averaged over the lanes, as an RGB `Color`
    /// (the fourth lane repeating the second).
    pub fn through(&self, l: Vec4, curves: &[Vec4]) -> Vec4 {
        let weighted = l * self.inv_pdf;
        let mut sum = Vec4::ZERO;
        for (i, v) in weighted.to_array().into_iter().enumerate() {
            let (j, u) = per_nm(self.lambda[i], curves.len());
            sum += (curves[j] * (1.0 - u) + curves[j + 1] * u) * v;
        }
        let avg = sum * 0.25;
        Vec4::new(avg.x, avg.y, avg.z, avg.y)
    }
}

/// An RGB value made a spectrum once, where a scene is built: sigmoid coefficients and a
/// scale, read at a path's wavelengths by [`Wavelengths::of`]. What [`Wavelengths::albedo`]
/// and [`Wavelengths::unbounded`] compute per call, for values met at every step of a walk
/// (a grid medium's coefficients, its voxels' colours).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmoidSpectrum {
    c: Coefficients,
    scale: f32,
}

impl SigmoidSpectrum {
    /// Zero at every wavelength.
    pub const ZERO: SigmoidSpectrum = SigmoidSpectrum {
        c: [0.0; 3],
        scale: 0.0,
    };

    /// An unbounded value's spectrum (or a light's before its white), as
    /// [`Wavelengths::unbounded`] makes it.
    pub fn unbounded(rgb: [f32; 3]) -> SigmoidSpectrum {
        let m = rgb[0].max(rgb[1]).max(rgb[2]);
        if m.is_nan() || m <= 0.0 {
            return SigmoidSpectrum::ZERO;
        }
        let scale = 2.0 * m;
        SigmoidSpectrum {
            c: SigmoidTable::srgb().coefficients(rgb.map(|v| v / scale)),
            scale,
        }
    }

    /// The largest value over 360–830 nm, exactly: the sigmoid rises with its quadratic,
    /// whose largest value on the range is at an end or at its vertex.
    pub fn max_value(&self) -> f32 {
        if self.scale == 0.0 {
            return 0.0;
        }
        let [c0, c1, c2] = self.c;
        if c0.is_infinite() {
            return if c0 > 0.0 { self.scale } else { 0.0 };
        }
        let t = |l: f32| (l - 555.0) / 175.0;
        let z = |t: f32| c0 + t * (c1 + t * c2);
        let (t0, t1) = (t(LAMBDA_MIN), t(LAMBDA_MAX));
        let mut z_max = z(t0).max(z(t1));
        if c2 < 0.0 {
            let vertex = -c1 / (2.0 * c2);
            if (t0..=t1).contains(&vertex) {
                z_max = z_max.max(z(vertex));
            }
        }
        let s = 0.5 + z_max / (2.0 * (1.0 + z_max * z_max).sqrt());
        // One part in a million above it: a majorant must not fall short by a rounding.
        s * self.scale * (1.0 + 1e-6)
    }
}

/// Planck's c₂/b: the exponent hc/(λkT) at the peak wavelength λ = b/T (Wien), the same
/// for every temperature.
const WIEN_X: f32 = 4.965_114;

/// A spectrum tabulated every nanometre from 360 to 830 nm: a scene's piecewise-linear
/// spectrum resampled (its end values held beyond its ends, as pbrt-v4 extends its named
/// spectra), read at a path's wavelengths by linear interpolation.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseSpectrum(Vec<f32>);

impl DenseSpectrum {
    /// From (wavelength nm, value) pairs in strictly increasing wavelength (at least one),
    /// read as `kiln_scene::spectrum::spectrum_at` reads a scene's spectra.
    pub fn new(pairs: &[(f32, f32)]) -> DenseSpectrum {
        assert!(!pairs.is_empty(), "a spectrum needs a sample");
        let pairs: Vec<(f64, f64)> = pairs
            .iter()
            .map(|&(l, v)| (f64::from(l), f64::from(v)))
            .collect();
        let n = (LAMBDA_MAX - LAMBDA_MIN) as usize;
        DenseSpectrum(
            (0..=n)
                .map(|i| {
                    let lambda = f64::from(LAMBDA_MIN) + i as f64;
                    kiln_scene::spectrum::spectrum_at(&pairs, lambda) as f32
                })
                .collect(),
        )
    }

    /// The spectrum at `waves`' wavelengths.
    pub fn at(&self, waves: &Wavelengths) -> Vec4 {
        Vec4::from_array(waves.lambda.to_array().map(|l| {
            let (i, u) = per_nm(l, self.0.len());
            self.0[i] * (1.0 - u) + self.0[i + 1] * u
        }))
    }
}

/// Emission given as a spectrum (a blackbody, a scene's pairs): its shape, and the linear
/// sRGB the film records of it, so that the emission of RGB `c` (this shape's RGB times a
/// brightness, as the scene built it) is the shape times that brightness at a path's
/// wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub struct LightSpectrum {
    shape: DenseSpectrum,
    /// The channel the brightness is read from (the shape's largest) and the shape's value
    /// in it.
    channel: usize,
    film: f32,
}

impl LightSpectrum {
    /// From a scene's pairs (zero beyond them, as the scene crate gives them); None for a
    /// shape that the film sees as black.
    pub fn new(pairs: &[(f32, f32)]) -> Option<LightSpectrum> {
        let mut pairs = pairs.to_vec();
        // Zero beyond the ends, where the range reaches further than the pairs.
        if let (Some(&(first, _)), Some(&(last, _))) = (pairs.first(), pairs.last()) {
            if first > LAMBDA_MIN {
                pairs.insert(0, (first - 1.0, 0.0));
            }
            if last < LAMBDA_MAX {
                pairs.push((last + 1.0, 0.0));
            }
        }
        let shape = DenseSpectrum::new(&pairs);
        // The film's RGB: the trapezoid rule over the nanometres.
        let table = response();
        let mut rgb = Vec4::ZERO;
        for (i, r) in table.iter().enumerate() {
            let w = if i == 0 || i == table.len() - 1 {
                0.5
            } else {
                1.0
            };
            rgb += *r * (shape.0[i] * w);
        }
        let rgb = [rgb.x, rgb.y, rgb.z];
        let channel = (0..3).fold(0, |m, c| if rgb[c] > rgb[m] { c } else { m });
        (rgb[channel] > 0.0).then_some(LightSpectrum {
            shape,
            channel,
            film: rgb[channel],
        })
    }

    /// The emission whose RGB is `c` at `waves`' wavelengths.
    pub fn at(&self, waves: &Wavelengths, c: Vec4) -> Vec4 {
        self.shape.at(waves) * (c[self.channel] / self.film)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rgb;

    /// The mean of `f`'s film response over many stratified wavelength samples.
    fn film_mean(f: impl Fn(&Wavelengths) -> Vec4) -> [f64; 3] {
        let n = 20_000;
        let mut sum = [0.0f64; 3];
        for i in 0..n {
            let w = Wavelengths::sample((i as f32 + 0.5) / n as f32);
            let c = w.to_rgb(f(&w));
            for k in 0..3 {
                sum[k] += c[k] as f64;
            }
        }
        sum.map(|s| s / n as f64)
    }

    /// The wavelength density integrates to 1 over 360–830 nm and inverts its sampling.
    #[test]
    fn visible_wavelengths_are_sampled_by_their_density() {
        let n = 47_000;
        let integral: f64 = (0..n)
            .map(|i| {
                visible_pdf(360.0 + 470.0 * (i as f32 + 0.5) / n as f32) as f64 * 470.0 / n as f64
            })
            .sum();
        assert!((integral - 1.0).abs() < 2e-3, "{integral}");
        let w = Wavelengths::sample(0.3);
        for i in 1..4 {
            assert!(w.lambda[i] != w.lambda[0]);
        }
        // The density the sampling gives is the density pbrt-v4 states.
        for u in [0.02, 0.1, 0.37, 0.5, 0.81, 0.98] {
            let (l, pdf) = sample_visible(u);
            assert!(
                (pdf - visible_pdf(l)).abs() < 1e-4 * visible_pdf(l),
                "{u}: {pdf} vs {}",
                visible_pdf(l)
            );
            let step = 1e-3;
            let slope = (sample_visible(u + step).0 - sample_visible(u - step).0) / (2.0 * step);
            assert!(
                (slope * pdf - 1.0).abs() < 5e-3,
                "{u}: dλ/du {slope}, pdf {pdf}"
            );
        }
        assert!(
            w.lambda
                .to_array()
                .iter()
                .all(|l| (360.0..=830.0).contains(l))
        );
    }

    /// White light is white; D65 light on a reflectance gives back the reflectance's RGB;
    /// an RGB light is its colour; a flat spectrum 1 (a white furnace's) is (1, 1, 1).
    #[test]
    fn the_film_gives_back_the_colours_spectra_were_made_from() {
        let close = |got: [f64; 3], want: [f32; 3], tol: f64| {
            for k in 0..3 {
                assert!((got[k] - want[k] as f64).abs() < tol, "{got:?} vs {want:?}");
            }
        };
        close(film_mean(|w| w.d65()), [1.0; 3], 2e-3);
        for c in [
            [0.8, 0.4, 0.1],
            [0.1, 0.7, 0.2],
            [0.2, 0.3, 0.9],
            [0.5, 0.5, 0.5],
        ] {
            close(film_mean(|w| w.albedo(rgb(c)) * w.d65()), c, 4e-3);
            close(film_mean(|w| w.illuminant(rgb(c))), c, 4e-3);
            let big = c.map(|v| 7.0 * v);
            close(film_mean(|w| w.illuminant(rgb(big))), big, 3e-2);
        }
        close(film_mean(|w| w.illuminant(rgb([1.0; 3]))), [1.0; 3], 2e-3);
        // Out of gamut: the film gives back the negative component too (made 0, the light
        // of [0.6, 0.3, 0] would come back), and in gamut it is the illuminant.
        let outside = [0.6, 0.3, -0.08];
        close(
            film_mean(|w| w.signed_illuminant(rgb(outside))),
            outside,
            4e-3,
        );
        let w = Wavelengths::sample(0.37);
        assert_eq!(
            w.signed_illuminant(rgb([0.8, 0.4, 0.1])),
            w.illuminant(rgb([0.8, 0.4, 0.1]))
        );
    }

    /// A spectrum made once is the one made per call; its largest value bounds it at every
    /// wavelength and is reached (within the sampling of the check).
    #[test]
    fn sigmoid_spectra_made_once_and_their_maxima() {
        for c in [
            [0.8, 0.4, 0.1],
            [0.1, 0.7, 0.2],
            [3.0, 0.2, 9.0],
            [0.5, 0.5, 0.5],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
        ] {
            let s = SigmoidSpectrum::unbounded(c);
            let mut seen = 0.0f32;
            for i in 0..=4700 {
                let lambda = LAMBDA_MIN + i as f32 * 0.1;
                let w = Wavelengths {
                    lambda: Vec4::splat(lambda),
                    t: Vec4::splat((lambda - 555.0) / 175.0),
                    ..Wavelengths::sample(0.5)
                };
                let v = w.of(&s);
                assert_eq!(v, w.unbounded(rgb(c)), "{c:?} at {lambda} nm");
                seen = seen.max(v.x);
            }
            let max = s.max_value();
            assert!(
                max >= seen && max <= seen * 1.0001,
                "{c:?}: max {max}, largest seen {seen}"
            );
        }
        assert_eq!(SigmoidSpectrum::unbounded([0.0; 3]).max_value(), 0.0);
    }

    /// The exact blackbody, through the film, is the RGB of pbrt-v4's peak-normalised
    /// blackbody that RGB rendering uses, where that RGB is in gamut; below about 1900 K its
    /// blue is out of gamut, negative, and kept.
    #[test]
    fn the_exact_blackbody_gives_its_rgb() {
        for kelvin in [2500.0, 4000.0, 6500.0, 12000.0] {
            let want = kiln_scene::spectrum::blackbody_peak_rgb(kelvin);
            let got = film_mean(|w| w.blackbody(kelvin));
            for k in 0..3 {
                assert!(
                    (got[k] / want[k] as f64 - 1.0).abs() < 2e-3,
                    "{kelvin} K: {got:?} vs {want:?}"
                );
            }
        }
        let cold = film_mean(|w| w.blackbody(1500.0));
        let want = kiln_scene::spectrum::blackbody_peak_rgb(1500.0);
        assert!((cold[0] / want[0] as f64 - 1.0).abs() < 2e-3, "{cold:?}");
        assert!(cold[2] < 0.0 && want[2] == 0.0, "{cold:?}");
        assert_eq!(Wavelengths::sample(0.3).blackbody(0.0), Vec4::ZERO);
        assert_eq!(Wavelengths::sample(0.3).blackbody(5.0), Vec4::ZERO);
    }

    /// Emission given as a spectrum keeps its RGB brightness and colour through the film:
    /// a blackbody whose RGB the scene crate computed, and a narrow band of a scene's pairs
    /// (zero beyond them) whose film RGB is its own.
    #[test]
    fn light_spectra_give_back_their_rgb() {
        let blackbody = kiln_scene::spectrum::blackbody_spectrum(3000.0);
        let s = LightSpectrum::new(&blackbody).unwrap();
        let c = kiln_scene::spectrum::blackbody_rgb(3000.0)
            .unwrap()
            .map(|v| 2.5 * v);
        let got = film_mean(|w| s.at(w, rgb(c)));
        for k in 0..3 {
            assert!(
                (got[k] / c[k] as f64 - 1.0).abs() < 3e-3,
                "{got:?} vs {c:?}"
            );
        }
        let band = LightSpectrum::new(&[(480.0, 0.0), (510.0, 2.0), (540.0, 0.0)]).unwrap();
        let film = film_mean(|w| band.at(w, Vec4::splat(band.film)));
        // Green's the band's largest channel; the film gives the shape's own RGB, whose
        // red is negative (out of gamut).
        assert_eq!(band.channel, 1);
        assert!((film[1] / band.film as f64 - 1.0).abs() < 3e-3, "{film:?}");
        assert!(film[0] < 0.0, "{film:?}");
        let outside = Wavelengths::sample(0.0);
        assert!(outside.lambda.x < 400.0 && band.at(&outside, Vec4::ONE).x == 0.0);
        assert!(LightSpectrum::new(&[(500.0, 0.0), (510.0, 0.0)]).is_none());
    }

    /// Spectra are lane-wise: the four wavelengths' values are each a function of their
    /// own wavelength, and reflectances stay within [0, 1].
    #[test]
    fn albedo_spectra_are_bounded_and_lane_wise() {
        let w = Wavelengths::sample(0.61);
        let c = rgb([0.9, 0.05, 0.3]);
        let s = w.albedo(c);
        assert!(s.cmpge(Vec4::ZERO).all() && s.cmple(Vec4::ONE).all(), "{s}");
        let coeffs = SigmoidTable::srgb().coefficients([0.9, 0.05, 0.3]);
        for i in 0..4 {
            let one = kiln_scene::sigmoid_table::evaluate(coeffs, w.lambda[i]);
            assert!((s[i] - one).abs() < 1e-5, "{} vs {one}", s[i]);
        }
    }
}
