//! A film's further channels beside R, G and B: the denoiser's features
//! ([`crate::features`]) and a G-buffer's if it has one ([`crate::gbuffer`]), their names
//! sorted together as images hold them, each pixel's made from its running sums.

use crate::features::{FEATURE_CHANNELS, finish};
use crate::gbuffer::{GBufferLayout, GBufferPixel};
use crate::sums::PixelSums;

/// Where a film's further channels (a G-buffer's, if any, and the features) sit among a
/// pixel's values: their names sorted together.
#[derive(Debug, Clone)]
pub struct FilmChannels {
    gbuffer: Option<GBufferLayout>,
    names: Vec<String>,
    /// For each of the G-buffer's sorted names, then each feature channel, its place.
    slots: Vec<usize>,
}

impl FilmChannels {
    pub fn new(gbuffer: Option<kiln_scene::GBufferSpace>) -> FilmChannels {
        let gbuffer = gbuffer.map(GBufferLayout::new);
        let own: Vec<String> = gbuffer
            .as_ref()
            .map_or_else(Vec::new, GBufferLayout::names)
            .into_iter()
            .chain(FEATURE_CHANNELS.map(String::from))
            .collect();
        let mut names = own.clone();
        names.sort();
        let slots = own
            .iter()
            .map(|n| {
                names
                    .iter()
                    .position(|s| s == n)
                    .expect("a name of its own")
            })
            .collect();
        FilmChannels {
            gbuffer,
            names,
            slots,
        }
    }

    /// The channel names, sorted.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    pub fn channels(&self) -> usize {
        self.names.len()
    }

    /// Whether the film keeps a G-buffer's sums, and in which space it writes them.
    pub fn gbuffer_space(&self) -> Option<kiln_scene::GBufferSpace> {
        self.gbuffer.as_ref().map(|l| l.space)
    }

    /// A pixel's further channels from its sums, into `out` (of [`FilmChannels::channels`]).
    pub fn finish(&self, p: &PixelSums, out: &mut [f32]) {
        let mut at = 0;
        if let Some(layout) = &self.gbuffer {
            let mut g = vec![0.0f32; layout.channels()];
            GBufferPixel::finish(&p.gbuffer, layout, &mut g);
            for v in g {
                out[self.slots[at]] = v;
                at += 1;
            }
        }
        for v in finish(&p.features, p.weight, p.value_variance()) {
            out[self.slots[at]] = v;
            at += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::Feature;
    use glam::Vec3A;

    /// The variance of a pixel's value is the samples' variance over their count, for
    /// unit weights; features average by weight, normals come out unit length.
    #[test]
    fn a_pixel_gives_its_features_and_variance() {
        let mut p = PixelSums::default();
        let values = [1.0f64, 3.0, 8.0, 4.0];
        for (i, v) in values.iter().enumerate() {
            p.sum = p.sum.map(|s| s + v);
            p.squares = p.squares.map(|s| s + v * v);
            p.weight += 1.0;
            p.taken = i as u32 + 1;
            let seen = Feature {
                albedo: crate::math::rgb3(0.5, 0.25, i as f32),
                normal: Vec3A::new(0.0, 0.0, 2.0),
                depth: 2.0,
            };
            p.features.add(&seen, 1.0);
        }
        let out = finish(&p.features, p.weight, p.value_variance());
        let mean = 4.0;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 3.0 / 4.0;
        assert!((out[9] as f64 - var).abs() < 1e-6, "{} {var}", out[9]);
        assert_eq!(out[2], 0.5);
        assert_eq!(out[0], 1.5);
        assert_eq!(out[3], 2.0);
        assert_eq!(&out[4..7], &[0.0, 0.0, 1.0]);
    }

    #[test]
    fn channels_interleave_with_a_gbuffer_by_name() {
        let plain = FilmChannels::new(None);
        assert_eq!(plain.names(), FEATURE_CHANNELS.map(String::from));
        let with = FilmChannels::new(Some(kiln_scene::GBufferSpace::Camera));
        let mut sorted = with.names().to_vec();
        sorted.sort();
        assert_eq!(with.names(), sorted);
        assert_eq!(with.channels(), 22 + FEATURE_CHANNELS.len());
        // Each channel lands under its own name.
        let mut p = PixelSums {
            weight: 1.0,
            taken: 1,
            ..PixelSums::default()
        };
        p.features.add(
            &Feature {
                albedo: crate::math::rgb3(0.1, 0.2, 0.3),
                normal: Vec3A::X,
                depth: 7.0,
            },
            1.0,
        );
        let mut out = vec![f32::NAN; with.channels()];
        with.finish(&p, &mut out);
        let at = |n: &str| out[with.names().iter().position(|s| s == n).unwrap()];
        assert_eq!(at("features.depth"), 7.0);
        assert_eq!(at("features.albedo.G"), 0.2);
        assert_eq!(at("features.normal.X"), 1.0);
        assert!(out.iter().all(|v| !v.is_nan()));
    }
}
