//! pbrt-v4's RGB colour spaces for the `ColorSpace` directive: RGB values a scene gives
//! after it are in that space, and Kiln, which renders in linear sRGB, converts them as it
//! reads them. Each space is its primaries' and white point's chromaticities; RGB goes to
//! XYZ and from there to sRGB.
//!
//! Reflectances (and other unitless values) keep their white: pbrt-v4 turns (1, 1, 1) in
//! any space into a flat spectrum, which is white in sRGB too, so they are carried to D65
//! by Bradford adaptation first. Emission keeps its colour: pbrt-v4 multiplies an RGB
//! illuminant by its space's white spectrum, so (1, 1, 1) in ACES2065-1 is D60 light,
//! a little warmer than sRGB's white.

use crate::spectrum::{SRGB_TO_XYZ, SpectrumUse, bradford_between, inverse3, mul3};

/// A colour space's conversion into linear sRGB.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColorSpace {
    pub name: &'static str,
    /// For reflectances and other unitless values (white kept white).
    albedo: [[f64; 3]; 3],
    /// For emission (colour kept).
    illuminant: [[f64; 3]; 3],
}

const D65: [f64; 2] = [0.3127, 0.3290];

/// The spaces pbrt-v4 knows: name, red, green, blue and white chromaticities.
const SPACES: [(&str, [[f64; 2]; 4]); 4] = [
    ("srgb", [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], D65]),
    (
        "rec2020",
        [[0.708, 0.292], [0.170, 0.797], [0.131, 0.046], D65],
    ),
    (
        "dci-p3",
        [[0.680, 0.320], [0.265, 0.690], [0.150, 0.060], D65],
    ),
    (
        "aces2065-1",
        [
            [0.7347, 0.2653],
            [0.0, 1.0],
            [0.0001, -0.077],
            [0.32168, 0.33767],
        ],
    ),
];

/// XYZ of chromaticity `xy` at luminance 1.
fn xyz(xy: [f64; 2]) -> [f64; 3] {
    [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]]
}

/// The RGB to XYZ matrix of primaries `p` and white `w` (white maps to Y = 1).
fn rgb_to_xyz(p: [[f64; 2]; 3], w: [f64; 2]) -> [[f64; 3]; 3] {
    let cols = p.map(xyz);
    let m = [
        [cols[0][0], cols[1][0], cols[2][0]],
        [cols[0][1], cols[1][1], cols[2][1]],
        [cols[0][2], cols[1][2], cols[2][2]],
    ];
    let s = mul_vec(&inverse3(&m), xyz(w));
    std::array::from_fn(|r| std::array::from_fn(|c| m[r][c] * s[c]))
}

fn mul_vec(a: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|k| a[r][k] * v[k]).sum())
}

impl ColorSpace {
    /// The names pbrt-v4 knows.
    pub fn names() -> Vec<&'static str> {
        SPACES.iter().map(|s| s.0).collect()
    }

    pub fn by_name(name: &str) -> Option<ColorSpace> {
        let &(name, [r, g, b, w]) = SPACES.iter().find(|s| s.0 == name)?;
        let to_xyz = rgb_to_xyz([r, g, b], w);
        let xyz_to_srgb = inverse3(&SRGB_TO_XYZ);
        let illuminant = mul3(&xyz_to_srgb, &to_xyz);
        let albedo = mul3(
            &xyz_to_srgb,
            &mul3(&bradford_between(xyz(w), xyz(D65)), &to_xyz),
        );
        Some(ColorSpace {
            name,
            albedo,
            illuminant,
        })
    }

    pub fn srgb() -> ColorSpace {
        ColorSpace::by_name("srgb").expect("sRGB is known")
    }

    pub fn is_srgb(&self) -> bool {
        self.name == "srgb"
    }

    /// `rgb` in this space as linear sRGB, for a value used as `usage`, kept non-negative (a
    /// wide-gamut colour outside sRGB is clipped: pbrt-v4's spectra are never negative).
    pub fn to_srgb(&self, rgb: [f32; 3], usage: SpectrumUse) -> [f32; 3] {
        if self.is_srgb() {
            return rgb;
        }
        let m = match usage {
            SpectrumUse::Illuminant => &self.illuminant,
            SpectrumUse::Albedo | SpectrumUse::Unbounded => &self.albedo,
        };
        let v = mul_vec(m, rgb.map(f64::from));
        v.map(|c| c.max(0.0) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// sRGB converts to itself; white stays white as a reflectance in every space, and a
    /// D65 space's white light is sRGB's; ACES white light is warmer (D60); a saturated
    /// Rec. 2020 green is outside sRGB (a negative red, clipped for reflectances).
    #[test]
    fn spaces_convert_as_their_chromaticities_say() {
        let srgb = ColorSpace::srgb();
        let x = [0.2, 0.5, 0.9];
        let y = srgb.to_srgb(x, SpectrumUse::Albedo);
        assert!((0..3).all(|c| (x[c] - y[c]).abs() < 1e-4), "{y:?}");
        // The sRGB matrix from its chromaticities matches the one the spectra use.
        let m = rgb_to_xyz([[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]], D65);
        for r in 0..3 {
            for c in 0..3 {
                assert!((m[r][c] - SRGB_TO_XYZ[r][c]).abs() < 2e-3, "{m:?}");
            }
        }
        for name in ColorSpace::names() {
            let cs = ColorSpace::by_name(name).unwrap();
            let w = cs.to_srgb([1.0; 3], SpectrumUse::Albedo);
            assert!(w.iter().all(|c| (c - 1.0).abs() < 2e-3), "{name}: {w:?}");
        }
        let rec = ColorSpace::by_name("rec2020").unwrap();
        let l = rec.to_srgb([1.0; 3], SpectrumUse::Illuminant);
        assert!(l.iter().all(|c| (c - 1.0).abs() < 2e-3), "{l:?}");
        let g = rec.to_srgb([0.0, 1.0, 0.0], SpectrumUse::Unbounded);
        assert!(g[0] == 0.0 && g[1] > 1.0, "{g:?}");
        assert_eq!(rec.to_srgb([0.0, 1.0, 0.0], SpectrumUse::Albedo)[0], 0.0);
        let aces = ColorSpace::by_name("aces2065-1").unwrap();
        let l = aces.to_srgb([1.0; 3], SpectrumUse::Illuminant);
        assert!(l[0] > l[2] + 0.02, "D60 is warmer than D65: {l:?}");
    }
}
