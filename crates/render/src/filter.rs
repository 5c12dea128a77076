//! Pixel filters (box, triangle, Gaussian, Mitchell, windowed sinc), sampled by importance:
//! each camera sample lands inside its own pixel's filter support and carries a weight, so
//! no sample writes to another pixel and tiles render independently. Filters with negative
//! lobes are sampled by their absolute value and carry negative weights where they are
//! negative, as pbrt-v4's filter sampler does.

use crate::sampling::Distribution1D;
use glam::Vec2;
use kiln_scene::{FilterDesc, FilterKind};

/// A pixel filter sampled by importance: each sample lands inside its own pixel's
/// filter support and carries a weight, so no sample writes to another pixel.
#[derive(Debug, Clone)]
pub struct Filter {
    radius: Vec2,
    kind: FilterSampling,
}

#[derive(Debug, Clone)]
enum FilterSampling {
    Box,
    Triangle,
    /// Tabulated separable filter: per-axis distributions of |f| over [-r, r].
    Tabulated {
        x: Distribution1D,
        y: Distribution1D,
        lobe: Lobe,
        /// The filter's signed integral over its support (so the weights average to 1).
        integral: f32,
    },
}

/// A separable filter's one-dimensional profile.
#[derive(Debug, Clone, Copy)]
enum Lobe {
    Gaussian { sigma: f32 },
    Mitchell { b: f32, c: f32 },
    Sinc { tau: f32 },
}

impl Lobe {
    /// The profile at offset `x` of a filter of radius `r`.
    fn eval(self, x: f32, r: f32) -> f32 {
        match self {
            Lobe::Gaussian { sigma } => gaussian_1d(x, sigma, r),
            Lobe::Mitchell { b, c } => mitchell_1d(2.0 * x / r, b, c),
            Lobe::Sinc { tau } => windowed_sinc(x, r, tau),
        }
    }
}

impl Filter {
    pub fn new(desc: &FilterDesc) -> Filter {
        let radius = Vec2::new(desc.radius[0] as f32, desc.radius[1] as f32);
        let kind = match desc.kind {
            FilterKind::Box => FilterSampling::Box,
            FilterKind::Triangle => FilterSampling::Triangle,
            FilterKind::Gaussian { sigma } => Self::tabulated(
                radius,
                Lobe::Gaussian {
                    sigma: sigma as f32,
                },
            ),
            FilterKind::Mitchell { b, c } => Self::tabulated(
                radius,
                Lobe::Mitchell {
                    b: b as f32,
                    c: c as f32,
                },
            ),
            FilterKind::Sinc { tau } => Self::tabulated(radius, Lobe::Sinc { tau: tau as f32 }),
        };
        Filter { radius, kind }
    }

    fn tabulated(radius: Vec2, lobe: Lobe) -> FilterSampling {
        // 64 bins per unit of radius at least: the lobes of a windowed sinc are one unit wide.
        let table = |r: f32| {
            let n = (64.0 * r.max(1.0)).ceil().min(4096.0) as usize;
            // Each bin's largest |f| (over 8 points across it), so that no bin where the
            // filter is non-zero is sampled with a vanishing density.
            let f: Vec<f32> = (0..n)
                .map(|i| {
                    (0..=8)
                        .map(|k| {
                            let t = (i as f32 + k as f32 / 8.0) / n as f32;
                            lobe.eval((t * 2.0 - 1.0) * r, r).abs()
                        })
                        .fold(0.0f32, f32::max)
                })
                .collect();
            Distribution1D::new(&f)
        };
        // The signed integral per axis, by a fine midpoint rule.
        let signed = |r: f32| {
            let n = 4096;
            (0..n)
                .map(|i| f64::from(lobe.eval(((i as f32 + 0.5) / n as f32 * 2.0 - 1.0) * r, r)))
                .sum::<f64>()
                * f64::from(2.0 * r)
                / f64::from(n)
        };
        FilterSampling::Tabulated {
            x: table(radius.x),
            y: table(radius.y),
            lobe,
            integral: (signed(radius.x) * signed(radius.y)) as f32,
        }
    }

    /// Returns the offset from the pixel centre and the sample's weight.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        match &self.kind {
            FilterSampling::Box => ((2.0 * u - Vec2::ONE) * self.radius, 1.0),
            FilterSampling::Triangle => (
                Vec2::new(
                    sample_tent(u.x, self.radius.x),
                    sample_tent(u.y, self.radius.y),
                ),
                1.0,
            ),
            FilterSampling::Tabulated {
                x,
                y,
                lobe,
                integral,
            } => {
                let (sx, px, _) = x.sample(u.x);
                let (sy, py, _) = y.sample(u.y);
                let offset = Vec2::new(
                    (2.0 * sx - 1.0) * self.radius.x,
                    (2.0 * sy - 1.0) * self.radius.y,
                );
                let f = lobe.eval(offset.x, self.radius.x) * lobe.eval(offset.y, self.radius.y);
                // pdf over the offset, normalised by the tabulated integrals.
                let pdf = px * py / (4.0 * self.radius.x * self.radius.y);
                (offset, if pdf > 0.0 { f / (pdf * integral) } else { 0.0 })
            }
        }
    }
}

fn gaussian_1d(x: f32, sigma: f32, radius: f32) -> f32 {
    let g = |v: f32| libm::expf(-v * v / (2.0 * sigma * sigma));
    (g(x) - g(radius)).max(0.0)
}

/// pbrt-v4's Mitchell-Netravali profile at `x` in units of half the radius.
fn mitchell_1d(x: f32, b: f32, c: f32) -> f32 {
    let x = x.abs();
    if x <= 1.0 {
        ((12.0 - 9.0 * b - 6.0 * c) * x * x * x
            + (-18.0 + 12.0 * b + 6.0 * c) * x * x
            + (6.0 - 2.0 * b))
            / 6.0
    } else if x <= 2.0 {
        ((-b - 6.0 * c) * x * x * x
            + (6.0 * b + 30.0 * c) * x * x
            + (-12.0 * b - 48.0 * c) * x
            + (8.0 * b + 24.0 * c))
            / 6.0
    } else {
        0.0
    }
}

/// sin(πx)/(πx).
fn sinc(x: f32) -> f32 {
    let px = std::f32::consts::PI * x;
    if px.abs() < 1e-5 {
        1.0
    } else {
        libm::sinf(px) / px
    }
}

/// pbrt-v4's Lanczos-windowed sinc of radius `r` and `tau` lobes.
fn windowed_sinc(x: f32, r: f32, tau: f32) -> f32 {
    if x.abs() > r {
        0.0
    } else {
        sinc(x) * sinc(x / tau)
    }
}

/// Inverts the CDF of a tent of half-width `r`.
fn sample_tent(u: f32, r: f32) -> f32 {
    if u < 0.5 {
        let v = 2.0 * u;
        r * (v.sqrt() - 1.0)
    } else {
        let v = 2.0 * u - 1.0;
        r * (1.0 - (1.0 - v).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kiln_scene::Loc;

    #[test]
    fn filter_offsets_stay_inside_the_radius() {
        for kind in [
            FilterKind::Box,
            FilterKind::Triangle,
            FilterKind::Gaussian { sigma: 0.5 },
            FilterKind::Mitchell {
                b: 1.0 / 3.0,
                c: 1.0 / 3.0,
            },
            FilterKind::Sinc { tau: 3.0 },
        ] {
            let f = Filter::new(&FilterDesc {
                kind,
                radius: [1.5, 1.5],
                loc: Loc::synthetic("t"),
            });
            for i in 0..256 {
                let u = Vec2::new((i % 16) as f32 / 16.0 + 0.01, (i / 16) as f32 / 16.0 + 0.02);
                let (o, w) = f.sample(u);
                assert!(o.x.abs() <= 1.5 && o.y.abs() <= 1.5, "{kind:?} {o}");
                assert!(w.is_finite() && w != 0.0, "{kind:?} {w}");
            }
        }
    }

    /// The weights are f / pdf: their mean over many samples is the filter's integral over
    /// its integral, 1, negative lobes included; and a Mitchell filter does give some
    /// negative weights.
    #[test]
    fn filter_weights_average_to_one() {
        for kind in [
            FilterKind::Gaussian { sigma: 0.5 },
            FilterKind::Mitchell {
                b: 1.0 / 3.0,
                c: 1.0 / 3.0,
            },
            FilterKind::Sinc { tau: 3.0 },
        ] {
            let f = Filter::new(&FilterDesc {
                kind,
                radius: [2.0, 2.0],
                loc: Loc::synthetic("t"),
            });
            let n = 512;
            let (mut sum, mut negative) = (0.0f64, 0);
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    let w = f.sample(u).1;
                    sum += f64::from(w);
                    negative += usize::from(w < 0.0);
                }
            }
            let mean = sum / (n * n) as f64;
            assert!((mean - 1.0).abs() < 0.01, "{kind:?}: {mean}");
            if !matches!(kind, FilterKind::Gaussian { .. }) {
                assert!(negative > 0, "{kind:?} has negative lobes");
            }
        }
    }

    #[test]
    fn tent_sampling_inverts_its_cdf() {
        assert!((sample_tent(0.5, 2.0)).abs() < 1e-6);
        assert!((sample_tent(0.125, 1.0) + 0.5).abs() < 1e-6);
        assert!((sample_tent(0.875, 1.0) - 0.5).abs() < 1e-6);
    }
}
