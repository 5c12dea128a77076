//! A grid medium as a spectral path sees it, as pbrt-v4's grid media are: the coefficients
//! per unit density and a constant emission as spectra made once where the scene is built,
//! an "rgbgrid"'s voxel colours as one spectrum per voxel whose values at a path's
//! wavelengths are interpolated between the eight nearest voxels, and a temperature grid's
//! blackbody computed exactly at each wavelength.

use super::{Emission, Field, GridMedium};
use crate::math::Color;
use crate::media::SampledGrid;
use crate::spectral::{LightSpectrum, SigmoidSpectrum, Wavelengths};
use glam::{Vec3A, Vec4};

/// A grid of RGB values made unbounded spectra, one per voxel, on the grid's lattice.
#[derive(Debug, Clone)]
pub(super) struct SpectrumGrid {
    /// Each voxel's largest value over 360–830 nm, on the same lattice: an upper bound of
    /// the interpolated spectrum anywhere its voxels reach (for majorants).
    pub(super) bound: SampledGrid,
    spectra: Vec<SigmoidSpectrum>,
}

impl SpectrumGrid {
    /// The spectra of the colours three channel grids (of one shape) hold.
    pub(super) fn new(rgb: &[SampledGrid; 3]) -> SpectrumGrid {
        let [r, g, b] = rgb.each_ref().map(SampledGrid::values);
        assert!(
            r.len() == g.len() && g.len() == b.len(),
            "channel grids differ"
        );
        let spectra: Vec<SigmoidSpectrum> = (0..r.len())
            .map(|i| SigmoidSpectrum::unbounded([r[i], g[i], b[i]]))
            .collect();
        let bound = rgb[0].with_values(spectra.iter().map(SigmoidSpectrum::max_value).collect());
        SpectrumGrid { bound, spectra }
    }

    /// The spectrum at `p` in the unit box at `waves`' wavelengths.
    fn at(&self, p: Vec3A, waves: &Wavelengths) -> Vec4 {
        self.bound.blend(p, |i| waves.of(&self.spectra[i]))
    }
}

/// What a spectral path reads of a grid medium besides its grids of numbers.
#[derive(Debug, Clone)]
pub(super) struct GridSpectra {
    /// Per unit density (an "rgbgrid": the scale of its voxels' spectra).
    pub(super) sigma_a: SigmoidSpectrum,
    pub(super) sigma_s: SigmoidSpectrum,
    /// An "rgbgrid"'s coefficient voxels (None: 1).
    pub(super) a: Option<SpectrumGrid>,
    pub(super) s: Option<SpectrumGrid>,
    /// A constant emission's spectrum, or an RGB emission grid's.
    le: Option<SpectralLe>,
}

#[derive(Debug, Clone)]
enum SpectralLe {
    Constant(SigmoidSpectrum),
    /// A constant emission the scene gave as a spectrum (a blackbody, its pairs).
    Shape(LightSpectrum),
    Grid(SpectrumGrid),
}

impl GridSpectra {
    /// The spectra of `m`'s RGB inputs, and of its emission where `desc` gave that as a
    /// spectrum.
    pub(super) fn new(m: &GridMedium, desc: &kiln_scene::GridMediumDesc) -> GridSpectra {
        let shape = match &desc.emission {
            kiln_scene::GridEmission::Constant {
                le_spectrum: Some(s),
                ..
            } => LightSpectrum::new(s),
            _ => None,
        };
        let spectrum = |c: Color| SigmoidSpectrum::unbounded([c.x, c.y, c.z]);
        let (a, s) = match &m.field {
            Field::Rgb { a, s } => (
                a.as_deref().map(SpectrumGrid::new),
                s.as_deref().map(SpectrumGrid::new),
            ),
            _ => (None, None),
        };
        let le = match &m.emission {
            Some((Emission::Constant(le), _)) => Some(match shape {
                Some(s) => SpectralLe::Shape(s),
                None => SpectralLe::Constant(spectrum(*le)),
            }),
            Some((Emission::Rgb(grids, _), _)) => Some(SpectralLe::Grid(SpectrumGrid::new(grids))),
            _ => None,
        };
        GridSpectra {
            sigma_a: spectrum(m.sigma_a),
            sigma_s: spectrum(m.sigma_s),
            a,
            s,
            le,
        }
    }

    /// The largest sigma_t any wavelength can meet in the unit box's cell `lo`..`hi`.
    pub(super) fn majorant(&self, field: &Field, lo: Vec3A, hi: Vec3A) -> f32 {
        let (a, s) = (self.sigma_a.max_value(), self.sigma_s.max_value());
        match field {
            Field::Scalar(g) => (a + s) * g.max_over(lo, hi),
            Field::Rgb { .. } => {
                let max =
                    |g: &Option<SpectrumGrid>| g.as_ref().map_or(1.0, |g| g.bound.max_over(lo, hi));
                a * max(&self.a) + s * max(&self.s)
            }
            Field::Cloud { .. } => a + s,
        }
    }
}

/// How a walk reads a grid medium's coefficients: in RGB, or at a spectral path's
/// wavelengths, with the coefficients per unit density (an rgbgrid's scale) evaluated once
/// per walk rather than at every tentative collision.
pub(super) enum Lanes<'a> {
    Rgb,
    /// A medium built for RGB, met by a spectral path.
    FromRgb(&'a Wavelengths),
    Spectral {
        waves: &'a Wavelengths,
        spectra: &'a GridSpectra,
        a: Vec4,
        s: Vec4,
    },
}

impl GridMedium {
    /// sigma_a and sigma_s at `p` in the unit box: in RGB, or with `waves` at a spectral
    /// path's wavelengths.
    pub fn coefficients_at(&self, p: Vec3A, waves: Option<&Wavelengths>) -> (Color, Color) {
        self.coefficients_in(p, &self.lanes(waves))
    }

    /// What a walk reads once rather than at every collision (see [`Lanes`]).
    pub(super) fn lanes<'a>(&'a self, waves: Option<&'a Wavelengths>) -> Lanes<'a> {
        match (waves, self.spectra.as_deref()) {
            (None, _) => Lanes::Rgb,
            // Built for RGB (a scene built apart from its settings): the RGB's spectra.
            (Some(w), None) => Lanes::FromRgb(w),
            (Some(w), Some(spectra)) => Lanes::Spectral {
                waves: w,
                spectra,
                a: w.of(&spectra.sigma_a),
                s: w.of(&spectra.sigma_s),
            },
        }
    }

    /// [`GridMedium::coefficients_at`] with the path's [`Lanes`] made already.
    pub(super) fn coefficients_in(&self, p: Vec3A, lanes: &Lanes) -> (Color, Color) {
        let (w, spectra, a, s) = match *lanes {
            Lanes::Rgb => return self.coefficients(p),
            Lanes::FromRgb(w) => {
                let (a, s) = self.coefficients(p);
                return (w.unbounded(a), w.unbounded(s));
            }
            Lanes::Spectral {
                waves,
                spectra,
                a,
                s,
            } => (waves, spectra, a, s),
        };
        match &self.field {
            Field::Scalar(g) => {
                let d = g.lookup(p);
                (a * d, s * d)
            }
            Field::Rgb { .. } => {
                let grid = |g: &Option<SpectrumGrid>| g.as_ref().map_or(Vec4::ONE, |g| g.at(p, w));
                (a * grid(&spectra.a), s * grid(&spectra.s))
            }
            Field::Cloud { cloud, p0, size } => {
                let d = cloud.density_at(*p0 + p * *size);
                (a * d, s * d)
            }
        }
    }

    /// Emitted radiance Le at `p` in the unit box: in RGB, or with `waves` at a spectral
    /// path's wavelengths (a temperature's blackbody exactly, as pbrt-v4's film sees it).
    pub fn le_at(&self, p: Vec3A, waves: Option<&Wavelengths>) -> Color {
        let Some(w) = waves else {
            return self.le(p);
        };
        let Some((emission, scale)) = &self.emission else {
            return Color::ZERO;
        };
        let Some(spectra) = self.spectra.as_deref() else {
            return w.illuminant(self.le(p));
        };
        let s = scale.as_ref().map_or(1.0, |g| g.lookup(p));
        if s <= 0.0 {
            return Color::ZERO;
        }
        match (emission, &spectra.le) {
            (
                Emission::Temperature {
                    grid,
                    offset,
                    t_scale,
                    table,
                },
                _,
            ) => {
                let kelvin = (grid.lookup(p) - offset) * t_scale;
                if kelvin <= super::BLACKBODY_MIN_K {
                    return Color::ZERO;
                }
                w.blackbody(kelvin) * (table.scale * s)
            }
            (Emission::Rgb(_, scale), Some(SpectralLe::Grid(g))) => {
                g.at(p, w) * w.d65() * (*scale * s)
            }
            (Emission::Constant(_), Some(SpectralLe::Constant(le))) => w.of(le) * w.d65() * s,
            (Emission::Constant(le), Some(SpectralLe::Shape(shape))) => shape.at(w, *le) * s,
            _ => unreachable!("the emission's spectra are made with it"),
        }
    }

    /// The source term sigma_a * Le at `p` in the unit box, in RGB or at `waves`.
    pub fn source_at(&self, p: Vec3A, waves: Option<&Wavelengths>) -> Color {
        if self.emission.is_none() {
            return Color::ZERO;
        }
        let (sigma_a, _) = self.coefficients_at(p, waves);
        if sigma_a == Color::ZERO {
            return Color::ZERO;
        }
        sigma_a * self.le_at(p, waves)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::media::voxel_grid::grid_from_fn as grid;
    use crate::sampling::TrackingRng;
    use glam::Affine3A;

    fn medium(
        density: kiln_scene::GridDensity,
        sigma_a: [f32; 3],
        sigma_s: [f32; 3],
    ) -> GridMedium {
        GridMedium::new(
            &kiln_scene::GridMediumDesc {
                sigma_a,
                sigma_s,
                phase: kiln_scene::PhaseDesc::HenyeyGreenstein { g: 0.0 },
                density,
                emission: kiln_scene::GridEmission::None,
                p0: [-1.0, -1.0, -1.0],
                p1: [1.0, 1.0, 3.0],
                medium_to_world: glam::DMat4::from_rotation_y(0.3),
                lattice: kiln_scene::Lattice::Centred,
            },
            true,
        )
    }

    /// Ratio tracking at a spectral path's wavelengths gives each wavelength's own
    /// transmittance, through a coloured medium whose spectra peak above its RGB.
    #[test]
    fn spectral_ratio_tracking_matches_each_wavelength() {
        let n = 8;
        let (sigma_a, sigma_s) = ([0.2, 0.9, 0.1], [1.6, 0.2, 0.05]);
        let m = medium(
            kiln_scene::GridDensity::Scalar(grid([n, 4, 4], |x, _, _| 0.2 + 0.1 * x as f32)),
            sigma_a,
            sigma_s,
        );
        let to_world = Affine3A::from_rotation_y(0.3);
        let o = to_world.transform_point3a(Vec3A::new(-0.75, 0.0, 1.0));
        let d = to_world.transform_vector3a(Vec3A::X);
        let waves = Wavelengths::sample(0.37);
        let sigma_t =
            waves.unbounded(crate::math::rgb(sigma_a)) + waves.unbounded(crate::math::rgb(sigma_s));
        // The optical depth's mean density is 0.55 over the 1.5 crossed (see grid's test).
        let exact = (-sigma_t * 0.55 * 1.5).exp();
        let runs = 20_000;
        let mut sum = Vec4::ZERO;
        for i in 0..runs {
            let mut rng = TrackingRng::new(i);
            sum += m.transmittance(o, d, 1.5, &mut rng, Some(&waves)).unwrap();
        }
        let mean = sum / runs as f32;
        for l in 0..4 {
            assert!(
                (mean[l] - exact[l]).abs() < 0.015,
                "{} nm: {} vs {}",
                waves.lambda[l],
                mean[l],
                exact[l]
            );
        }
        // The majorant bounds every wavelength's extinction.
        let mut rng = TrackingRng::new(3);
        for _ in 0..500 {
            m.walk(o - d * 5.0, d, 100.0, &mut rng, |_, p, sigma_maj| {
                let (a, s) = m.coefficients_at(p, Some(&waves));
                assert!(
                    sigma_maj >= (a + s).max_element(),
                    "{sigma_maj} < {}",
                    a + s
                );
                true
            });
        }
    }

    /// An "rgbgrid" holds one spectrum per voxel: at a voxel's centre the coefficients are
    /// that voxel's spectrum times the scale, between centres the blend of their values.
    #[test]
    fn rgb_grid_voxels_are_spectra() {
        let n = [4, 3, 2];
        let channel = |c: usize| {
            grid(n, move |x, y, z| {
                [0.5 + x as f32, 2.0 * y as f32, 0.3 + 0.2 * z as f32][c]
            })
        };
        let voxels = || Box::new([channel(0), channel(1), channel(2)]);
        let m = medium(
            kiln_scene::GridDensity::Rgb {
                sigma_a: Some(voxels()),
                sigma_s: None,
            },
            [2.0; 3],
            [0.5; 3],
        );
        let waves = Wavelengths::sample(0.81);
        let centre = |x: usize, y: usize, z: usize| {
            Vec3A::new(
                (x as f32 + 0.5) / n[0] as f32,
                (y as f32 + 0.5) / n[1] as f32,
                (z as f32 + 0.5) / n[2] as f32,
            )
        };
        let voxel = |x: usize, y: usize, z: usize| {
            let rgb = [0.5 + x as f32, 2.0 * y as f32, 0.3 + 0.2 * z as f32];
            waves.unbounded(crate::math::rgb(rgb)) * 2.0
        };
        for (x, y, z) in [(1, 1, 0), (2, 2, 1), (0, 0, 0)] {
            let (a, s) = m.coefficients_at(centre(x, y, z), Some(&waves));
            let want = voxel(x, y, z);
            assert!(
                (a - want).abs().max_element() <= 1e-5 * want.max_element(),
                "{a} vs {want}"
            );
            // No sigma_s grid: the scale alone (a grey, flat spectrum).
            assert!((s - Vec4::splat(0.5)).abs().max_element() < 1e-5, "{s}");
        }
        let mid = (centre(1, 1, 0) + centre(2, 1, 0)) * 0.5;
        let (a, _) = m.coefficients_at(mid, Some(&waves));
        let want = (voxel(1, 1, 0) + voxel(2, 1, 0)) * 0.5;
        assert!(
            (a - want).abs().max_element() <= 1e-5 * want.max_element(),
            "{a} vs {want}"
        );
        // The majorant bounds every wavelength's extinction on rays through the grid.
        let mut rng = TrackingRng::new(5);
        let mut collisions = 0;
        for i in 0..200 {
            let o = Vec3A::new(-3.0, 0.1 * (i % 7) as f32, 0.9 + 0.1 * (i % 5) as f32);
            let d = Vec3A::new(1.0, 0.05 * (i % 3) as f32, 0.0).normalize();
            m.walk(o, d, 100.0, &mut rng, |_, p, sigma_maj| {
                let (a, s) = m.coefficients_at(p, Some(&waves));
                assert!(
                    sigma_maj >= (a + s).max_element(),
                    "{sigma_maj} < {}",
                    a + s
                );
                collisions += 1;
                true
            });
        }
        assert!(collisions > 1000, "{collisions}");
    }
}
