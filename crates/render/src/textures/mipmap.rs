//! MIP maps: an image and its successively halved copies, looked up with pbrt-v4's filters
//! (point, bilinear, trilinear and EWA) over a footprint given by the derivatives of (s, t).
//!
//! As pbrt-v4 builds them: an image whose sides are not powers of two is first resampled up
//! to the next powers of two with a windowed sinc (radius 2, τ 2); each level is the 2x2
//! box average of the one below, computed in linear floats and stored back in the image's
//! own format (8-bit images stay 8-bit with their encoding, a quarter of the memory of
//! floats). Texel centres sit at (i + 0.5) / resolution.

use super::TexValue;
use glam::Vec2;
use kiln_scene::{ColorEncoding, ImageData, ImageFilter, ImageWrap, TextureImage};

/// At most four channels per texel.
pub type Texel = [f32; 4];

#[derive(Debug, Clone)]
enum Storage {
    /// Encoded bytes, decoded through `MipMap::decode`.
    U8(Vec<u8>),
    F32(Vec<f32>),
}

#[derive(Debug, Clone)]
struct Level {
    width: u32,
    height: u32,
    data: Storage,
}

#[derive(Debug, Clone)]
pub struct MipMap {
    levels: Vec<Level>,
    channels: usize,
    wrap: ImageWrap,
    /// The linear value of each byte, for 8-bit levels.
    decode: Box<[f32; 256]>,
    encoding: Option<ColorEncoding>,
}

impl MipMap {
    pub fn new(image: &TextureImage, wrap: ImageWrap) -> MipMap {
        let channels = image.channels as usize;
        let encoding = match &image.data {
            ImageData::U8 { encoding, .. } => Some(*encoding),
            ImageData::F32(_) => None,
        };
        let mut decode = Box::new([0.0f32; 256]);
        if let Some(e) = encoding {
            for (i, d) in decode.iter_mut().enumerate() {
                *d = e.to_linear(i as f32 / 255.0);
            }
        }
        let mut map = MipMap {
            levels: Vec::new(),
            channels,
            wrap,
            decode,
            encoding,
        };
        let (w, h) = (image.width, image.height);
        let level0 = if w.is_power_of_two() && h.is_power_of_two() {
            Level {
                width: w,
                height: h,
                data: match &image.data {
                    ImageData::U8 { bytes, .. } => Storage::U8(bytes.clone()),
                    ImageData::F32(v) => Storage::F32(v.clone()),
                },
            }
        } else {
            let floats = map.resample_up(image);
            map.store(w.next_power_of_two(), h.next_power_of_two(), floats)
        };
        map.levels.push(level0);
        while {
            let top = map.levels.last().unwrap();
            top.width > 1 || top.height > 1
        } {
            let next = map.halve(map.levels.last().unwrap());
            map.levels.push(next);
        }
        map
    }

    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    pub fn resolution(&self, level: usize) -> (u32, u32) {
        (self.levels[level].width, self.levels[level].height)
    }

    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes held by every level, for memory reports.
    pub fn memory_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| match &l.data {
                Storage::U8(v) => v.len(),
                Storage::F32(v) => v.len() * 4,
            })
            .sum()
    }

    /// Linear floats in the image's format: bytes encoded back with its encoding.
    fn store(&self, width: u32, height: u32, floats: Vec<f32>) -> Level {
        let data = match self.encoding {
            None => Storage::F32(floats),
            Some(e) => Storage::U8(floats.iter().map(|&v| encode(e, v)).collect()),
        };
        Level {
            width,
            height,
            data,
        }
    }

    fn raw(&self, level: &Level, x: u32, y: u32, c: usize) -> f32 {
        let i = (y as usize * level.width as usize + x as usize) * self.channels + c;
        match &level.data {
            Storage::U8(v) => self.decode[v[i] as usize],
            Storage::F32(v) => v[i],
        }
    }

    /// The next level: 2x2 box averages (a side of 1 stays 1, its texels reused).
    fn halve(&self, l: &Level) -> Level {
        let (w, h) = ((l.width / 2).max(1), (l.height / 2).max(1));
        let mut out = Vec::with_capacity(w as usize * h as usize * self.channels);
        for y in 0..h {
            let (y0, y1) = ((2 * y).min(l.height - 1), (2 * y + 1).min(l.height - 1));
            for x in 0..w {
                let (x0, x1) = ((2 * x).min(l.width - 1), (2 * x + 1).min(l.width - 1));
                for c in 0..self.channels {
                    out.push(
                        (self.raw(l, x0, y0, c)
                            + self.raw(l, x1, y0, c)
                            + self.raw(l, x0, y1, c)
                            + self.raw(l, x1, y1, c))
                            / 4.0,
                    );
                }
            }
        }
        self.store(w, h, out)
    }

    /// The image resampled up to powers of two, separably, with a windowed sinc of radius 2
    /// whose taps outside the image follow the wrap mode.
    fn resample_up(&self, image: &TextureImage) -> Vec<f32> {
        let (w, h) = (image.width as usize, image.height as usize);
        let (nw, nh) = (w.next_power_of_two(), h.next_power_of_two());
        let ch = self.channels;
        let src = |x: usize, y: usize, c: usize| image.channel(x as u32, y as u32, c as u32);
        // Along x.
        let mut wide = vec![0.0f32; nw * h * ch];
        for (i, (first, weights)) in taps(w, nw).into_iter().enumerate() {
            for y in 0..h {
                for c in 0..ch {
                    let mut v = 0.0;
                    for (j, wt) in weights.iter().enumerate() {
                        if let Some((sx, sy)) =
                            wrap_texel(self.wrap, first + j as i64, y as i64, w as i64, h as i64)
                        {
                            v += wt * src(sx as usize, sy as usize, c);
                        }
                    }
                    wide[(y * nw + i) * ch + c] = v;
                }
            }
        }
        // Along y, clamped at zero (the sinc's lobes can undershoot).
        let mut out = vec![0.0f32; nw * nh * ch];
        for (i, (first, weights)) in taps(h, nh).into_iter().enumerate() {
            for x in 0..nw {
                for c in 0..ch {
                    let mut v = 0.0;
                    for (j, wt) in weights.iter().enumerate() {
                        if let Some((sx, sy)) = wrap_texel(
                            self.wrap,
                            x as i64 % w.max(1) as i64,
                            first + j as i64,
                            w as i64,
                            h as i64,
                        ) {
                            let _ = sx;
                            v += wt * wide[(sy as usize * nw + x) * ch + c];
                        }
                    }
                    out[(i * nw + x) * ch + c] = v.max(0.0);
                }
            }
        }
        out
    }

    /// The texel at integer coordinates of a level, after wrapping; zero outside a
    /// black-wrapped image.
    pub fn texel(&self, level: usize, x: i64, y: i64) -> Texel {
        let l = &self.levels[level];
        let mut t = [0.0; 4];
        if let Some((x, y)) = wrap_texel(self.wrap, x, y, l.width as i64, l.height as i64) {
            for (c, v) in t.iter_mut().enumerate().take(self.channels) {
                *v = self.raw(l, x as u32, y as u32, c);
            }
        }
        t
    }

    /// Bilinear interpolation of a level's texels at `st`.
    pub fn bilerp(&self, level: usize, st: Vec2) -> Texel {
        let (w, h) = self.resolution(level);
        let (x, y) = (st.x * w as f32 - 0.5, st.y * h as f32 - 0.5);
        let (fx, fy) = (x.floor(), y.floor());
        let (dx, dy) = (x - fx, y - fy);
        let (xi, yi) = (fx as i64, fy as i64);
        let t00 = self.texel(level, xi, yi);
        let t10 = self.texel(level, xi + 1, yi);
        let t01 = self.texel(level, xi, yi + 1);
        let t11 = self.texel(level, xi + 1, yi + 1);
        let mut out = [0.0; 4];
        for c in 0..self.channels {
            out[c] = (1.0 - dx) * (1.0 - dy) * t00[c]
                + dx * (1.0 - dy) * t10[c]
                + (1.0 - dx) * dy * t01[c]
                + dx * dy * t11[c];
        }
        out
    }

    /// The filtered value over the footprint whose sides are `dst0` and `dst1` (the
    /// derivatives of (s, t) along x and y).
    pub fn filter<V: TexValue>(
        &self,
        filter: ImageFilter,
        max_anisotropy: f32,
        st: Vec2,
        dst0: Vec2,
        dst1: Vec2,
    ) -> V {
        let n = self.channels;
        let texel = |level: usize, x: i64, y: i64| V::from_texel(&self.texel(level, x, y)[..n]);
        let bilerp = |level: usize, st: Vec2| V::from_bilerp(&self.bilerp(level, st)[..n]);
        let top = self.levels.len() - 1;
        if filter == ImageFilter::Ewa {
            return self.ewa_lookup(max_anisotropy, st, dst0, dst1);
        }
        let width = 2.0 * dst0.abs().max_element().max(dst1.abs().max_element());
        let level = top as f32 + libm::log2f(width.max(1e-8));
        if level >= top as f32 {
            return texel(top, 0, 0);
        }
        let il = level.floor().max(0.0) as usize;
        match filter {
            ImageFilter::Point => {
                let (w, h) = self.resolution(il);
                texel(
                    il,
                    (st.x * w as f32 - 0.5).round() as i64,
                    (st.y * h as f32 - 0.5).round() as i64,
                )
            }
            ImageFilter::Bilinear => bilerp(il, st),
            _ => {
                if il == 0 {
                    bilerp(0, st)
                } else {
                    let d = level - il as f32;
                    bilerp(il, st) * (1.0 - d) + bilerp(il + 1, st) * d
                }
            }
        }
    }

    fn ewa_lookup<V: TexValue>(
        &self,
        max_anisotropy: f32,
        st: Vec2,
        mut dst0: Vec2,
        mut dst1: Vec2,
    ) -> V {
        if dst0.length_squared() < dst1.length_squared() {
            std::mem::swap(&mut dst0, &mut dst1);
        }
        let major = dst0.length();
        let mut minor = dst1.length();
        // Lengthen the minor axis of a very eccentric ellipse (blurring a little rather
        // than visiting unboundedly many texels).
        if minor * max_anisotropy < major && minor > 0.0 {
            let k = major / (minor * max_anisotropy);
            dst1 *= k;
            minor *= k;
        }
        if minor == 0.0 {
            return V::from_bilerp(&self.bilerp(0, st)[..self.channels]);
        }
        let lod = (self.levels.len() as f32 - 1.0 + libm::log2f(minor)).max(0.0);
        let il = lod.floor() as usize;
        let d = lod - il as f32;
        self.ewa::<V>(il, st, dst0, dst1) * (1.0 - d) + self.ewa::<V>(il + 1, st, dst0, dst1) * d
    }

    /// The elliptically weighted average of one level's texels under a Gaussian.
    fn ewa<V: TexValue>(&self, level: usize, st: Vec2, a: Vec2, b: Vec2) -> V {
        let n = self.channels;
        if level >= self.levels.len() {
            let top = self.levels.len() - 1;
            return V::from_texel(&self.texel(top, 0, 0)[..n]);
        }
        let (w, h) = self.resolution(level);
        let (w, h) = (w as f32, h as f32);
        let (s, t) = (st.x * w - 0.5, st.y * h - 0.5);
        let (a, b) = (Vec2::new(a.x * w, a.y * h), Vec2::new(b.x * w, b.y * h));
        // The ellipse's implicit equation, A s² + B s t + C t² < 1, widened by a texel.
        let mut ea = a.y * a.y + b.y * b.y + 1.0;
        let mut eb = -2.0 * (a.x * a.y + b.x * b.y);
        let mut ec = a.x * a.x + b.x * b.x + 1.0;
        let f = ea * ec - eb * eb / 4.0;
        ea /= f;
        eb /= f;
        ec /= f;
        let det = -eb * eb + 4.0 * ea * ec;
        let inv_det = 1.0 / det;
        let u_sqrt = (det * ec).max(0.0).sqrt();
        let v_sqrt = (ea * det).max(0.0).sqrt();
        let s0 = (s - 2.0 * inv_det * u_sqrt).ceil() as i64;
        let s1 = (s + 2.0 * inv_det * u_sqrt).floor() as i64;
        let t0 = (t - 2.0 * inv_det * v_sqrt).ceil() as i64;
        let t1 = (t + 2.0 * inv_det * v_sqrt).floor() as i64;
        let mut sum = V::splat(0.0);
        let mut weights = 0.0;
        for it in t0..=t1 {
            let tt = it as f32 - t;
            for is in s0..=s1 {
                let ss = is as f32 - s;
                let r2 = ea * ss * ss + eb * ss * tt + ec * tt * tt;
                if r2 < 1.0 {
                    let wt = gaussian_weight(r2);
                    sum = sum + V::from_texel(&self.texel(level, is, it)[..n]) * wt;
                    weights += wt;
                }
            }
        }
        if weights > 0.0 {
            sum * (1.0 / weights)
        } else {
            V::from_bilerp(&self.bilerp(level, st)[..n])
        }
    }
}

/// pbrt-v4's EWA weights: a Gaussian falling to zero at the ellipse's edge, tabulated at
/// 128 values of r² ∈ [0, 1) (its table is built for r² = i / 127 and read at r² · 128;
/// this reads it the same way).
fn gaussian_weight(r2: f32) -> f32 {
    static TABLE: std::sync::LazyLock<[f32; 128]> = std::sync::LazyLock::new(|| {
        let alpha = 2.0f32;
        std::array::from_fn(|i| libm::expf(-alpha * i as f32 / 127.0) - libm::expf(-alpha))
    });
    TABLE[((r2 * 128.0) as usize).min(127)]
}

/// For each of `new` output samples over `old` input samples: the first input index and the
/// four normalised weights of the windowed sinc.
fn taps(old: usize, new: usize) -> Vec<(i64, [f32; 4])> {
    let sinc = |x: f32| {
        if x.abs() < 1e-5 {
            1.0
        } else {
            let px = std::f32::consts::PI * x;
            libm::sinf(px) / px
        }
    };
    let windowed = |x: f32| {
        if x.abs() > 2.0 {
            0.0
        } else {
            sinc(x) * sinc(x / 2.0)
        }
    };
    let ratio = old as f32 / new as f32;
    (0..new)
        .map(|i| {
            let center = (i as f32 + 0.5) * ratio;
            let first = (center - 2.0 + 0.5).floor();
            let mut w = [0.0f32; 4];
            for (j, wj) in w.iter_mut().enumerate() {
                *wj = windowed(first + j as f32 + 0.5 - center);
            }
            let sum: f32 = w.iter().sum();
            (first as i64, w.map(|v| v / sum))
        })
        .collect()
}

/// Integer texel coordinates after the wrap mode; None outside a black-wrapped image.
pub fn wrap_texel(wrap: ImageWrap, mut x: i64, mut y: i64, w: i64, h: i64) -> Option<(i64, i64)> {
    match wrap {
        ImageWrap::Repeat => Some((x.rem_euclid(w), y.rem_euclid(h))),
        ImageWrap::Clamp => Some((x.clamp(0, w - 1), y.clamp(0, h - 1))),
        ImageWrap::Black => (x >= 0 && x < w && y >= 0 && y < h).then_some((x, y)),
        ImageWrap::OctahedralSphere => {
            if x < 0 {
                x = -x;
                y = h - 1 - y;
            } else if x >= w {
                x = 2 * w - 1 - x;
                y = h - 1 - y;
            }
            if y < 0 {
                x = w - 1 - x;
                y = -y;
            } else if y >= h {
                x = w - 1 - x;
                y = 2 * h - 1 - y;
            }
            // Far outside (beyond one reflection), clamp rather than index out of bounds.
            Some((x.clamp(0, w - 1), y.clamp(0, h - 1)))
        }
    }
}

/// A linear value stored back as a byte with `e`, as pbrt-v4 stores 8-bit levels.
fn encode(e: ColorEncoding, v: f32) -> u8 {
    match e {
        ColorEncoding::Linear => (v * 255.0 + 0.5).clamp(0.0, 255.0) as u8,
        ColorEncoding::Srgb => {
            if v <= 0.0 {
                0
            } else if v >= 1.0 {
                255
            } else {
                let s = if v <= 0.003_130_8 {
                    12.92 * v
                } else {
                    1.055 * libm::powf(v, 1.0 / 2.4) - 0.055
                };
                (255.0 * s).round().clamp(0.0, 255.0) as u8
            }
        }
        ColorEncoding::Gamma(g) => {
            (255.0 * libm::powf(v.max(0.0), 1.0 / g) + 0.5).clamp(0.0, 255.0) as u8
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;
    use std::path::PathBuf;

    fn float_image(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> TextureImage {
        let mut v = Vec::new();
        for y in 0..h {
            for x in 0..w {
                v.extend_from_slice(&f(x, y));
            }
        }
        TextureImage {
            width: w,
            height: h,
            channels: 3,
            data: ImageData::F32(v),
            path: PathBuf::from("test"),
        }
    }

    #[test]
    fn levels_halve_down_to_one_texel_and_keep_the_mean() {
        let img = float_image(8, 4, |x, y| [x as f32, y as f32, 1.0]);
        let m = MipMap::new(&img, ImageWrap::Repeat);
        assert_eq!(m.levels(), 4);
        assert_eq!(m.resolution(3), (1, 1));
        let top = m.texel(3, 0, 0);
        assert!((top[0] - 3.5).abs() < 1e-5 && (top[1] - 1.5).abs() < 1e-5 && top[2] == 1.0);
    }

    #[test]
    fn texel_centres_and_point_lookups() {
        let img = float_image(4, 4, |x, y| [(y * 4 + x) as f32, 0.0, 0.0]);
        let m = MipMap::new(&img, ImageWrap::Clamp);
        // The centre of texel (2, 1) is st = (2.5/4, 1.5/4): bilinear returns it exactly.
        let c: Color = m.filter(
            ImageFilter::Bilinear,
            8.0,
            Vec2::new(2.5 / 4.0, 1.5 / 4.0),
            Vec2::ZERO,
            Vec2::ZERO,
        );
        assert_eq!(c.x, 6.0);
        let p: Color = m.filter(
            ImageFilter::Point,
            8.0,
            Vec2::new(0.3, 0.9),
            Vec2::ZERO,
            Vec2::ZERO,
        );
        assert_eq!(p.x, (3 * 4 + 1) as f32);
    }

    #[test]
    fn wide_footprints_read_coarser_levels() {
        // A 2x2 checker of 0 and 1 at level 0; its 1x1 level is 0.5.
        let img = float_image(16, 16, |x, y| [((x + y) % 2) as f32; 3]);
        let m = MipMap::new(&img, ImageWrap::Repeat);
        for filter in [
            ImageFilter::Bilinear,
            ImageFilter::Trilinear,
            ImageFilter::Ewa,
        ] {
            let v: f32 = m.filter(
                filter,
                8.0,
                Vec2::new(0.37, 0.61),
                Vec2::new(0.5, 0.0),
                Vec2::new(0.0, 0.5),
            );
            assert!((v - 0.5).abs() < 1e-3, "{filter:?}: {v}");
        }
        // A footprint of a fraction of a texel reads level 0.
        let v: f32 = m.filter(
            ImageFilter::Trilinear,
            8.0,
            Vec2::new(0.5 / 16.0, 0.5 / 16.0),
            Vec2::new(0.01, 0.0),
            Vec2::new(0.0, 0.01),
        );
        assert_eq!(v, 0.0);
    }

    #[test]
    fn non_power_of_two_images_are_resampled_up() {
        let img = float_image(3, 5, |_, _| [0.25, 0.5, 1.0]);
        let m = MipMap::new(&img, ImageWrap::Clamp);
        assert_eq!(m.resolution(0), (4, 8));
        // A constant image stays constant (the weights are normalised).
        for y in 0..8 {
            for x in 0..4 {
                let t = m.texel(0, x, y);
                assert!(
                    (t[0] - 0.25).abs() < 1e-5 && (t[2] - 1.0).abs() < 1e-5,
                    "{t:?}"
                );
            }
        }
    }

    #[test]
    fn eight_bit_levels_stay_eight_bit_and_round_trip() {
        let bytes: Vec<u8> = (0..16 * 16).flat_map(|i| [(i % 256) as u8; 3]).collect();
        let img = TextureImage {
            width: 16,
            height: 16,
            channels: 3,
            data: ImageData::U8 {
                bytes,
                encoding: ColorEncoding::Srgb,
            },
            path: PathBuf::from("t"),
        };
        let m = MipMap::new(&img, ImageWrap::Repeat);
        assert_eq!(m.memory_bytes(), 3 * (256 + 64 + 16 + 4 + 1));
        for b in 0..=255u8 {
            let lin = ColorEncoding::Srgb.to_linear(b as f32 / 255.0);
            assert_eq!(encode(ColorEncoding::Srgb, lin), b);
        }
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_texel(ImageWrap::Repeat, -1, 5, 4, 4), Some((3, 1)));
        assert_eq!(wrap_texel(ImageWrap::Clamp, -1, 5, 4, 4), Some((0, 3)));
        assert_eq!(wrap_texel(ImageWrap::Black, -1, 2, 4, 4), None);
        assert_eq!(
            wrap_texel(ImageWrap::OctahedralSphere, -1, 0, 4, 4),
            Some((1, 3))
        );
        assert_eq!(
            wrap_texel(ImageWrap::OctahedralSphere, 0, 4, 4, 4),
            Some((3, 3))
        );
    }
}
