//! Pixel filters (box, triangle, Gaussian), sampled by importance: each camera sample lands
//! inside its own pixel's filter support and carries a weight, so no sample writes to
//! another pixel and tiles render independently.

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
    /// Tabulated separable filter: per-axis distributions over [-r, r].
    Tabulated {
        x: Distribution1D,
        y: Distribution1D,
        sigma: f32,
    },
}

impl Filter {
    pub fn new(desc: &FilterDesc) -> Filter {
        let radius = Vec2::new(desc.radius[0] as f32, desc.radius[1] as f32);
        let kind = match desc.kind {
            FilterKind::Box => FilterSampling::Box,
            FilterKind::Triangle => FilterSampling::Triangle,
            FilterKind::Gaussian { sigma } => {
                let sigma = sigma as f32;
                let table = |r: f32| {
                    let n = 64;
                    let f: Vec<f32> = (0..n)
                        .map(|i| {
                            gaussian_1d(((i as f32 + 0.5) / n as f32 * 2.0 - 1.0) * r, sigma, r)
                        })
                        .collect();
                    Distribution1D::new(&f)
                };
                FilterSampling::Tabulated {
                    x: table(radius.x),
                    y: table(radius.y),
                    sigma,
                }
            }
        };
        Filter { radius, kind }
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
            FilterSampling::Tabulated { x, y, sigma } => {
                let (sx, px, _) = x.sample(u.x);
                let (sy, py, _) = y.sample(u.y);
                let offset = Vec2::new(
                    (2.0 * sx - 1.0) * self.radius.x,
                    (2.0 * sy - 1.0) * self.radius.y,
                );
                let f = gaussian_1d(offset.x, *sigma, self.radius.x)
                    * gaussian_1d(offset.y, *sigma, self.radius.y);
                // pdf over the offset, normalised by the tabulated integrals.
                let pdf = px * py / (4.0 * self.radius.x * self.radius.y);
                let norm = x.integral() * y.integral() * 4.0 * self.radius.x * self.radius.y;
                (offset, if pdf > 0.0 { f / (pdf * norm) } else { 0.0 })
            }
        }
    }
}

fn gaussian_1d(x: f32, sigma: f32, radius: f32) -> f32 {
    let g = |v: f32| (-v * v / (2.0 * sigma * sigma)).exp();
    (g(x) - g(radius)).max(0.0)
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
                assert!(w > 0.0 && w.is_finite());
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
