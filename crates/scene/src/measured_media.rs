//! Measured scattering coefficients of real materials, by name, for pbrt-v4's "subsurface"
//! material's `"string name"`: the twelve of Jensen, Marschner, Levoy and Hanrahan, "A
//! Practical Model for Subsurface Light Transport" (SIGGRAPH 2001), table 2: the reduced
//! scattering coefficient σ's and the absorption coefficient σa in mm⁻¹ for red, green and
//! blue. pbrt-v4 uses σ's as σs with g = 0, and so does Kiln.

/// (name, σ's, σa), per mm.
const JENSEN_2001: [(&str, [f32; 3], [f32; 3]); 12] = [
    ("Apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    ("Chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    ("Chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    ("Cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    ("Ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    ("Marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    ("Potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    ("Skimmilk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    ("Skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    ("Skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    ("Spectralon", [11.6, 20.4, 14.9], [0.0, 0.0, 0.0]),
    ("Wholemilk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
];

/// The (σa, σs) of the measured material `name`, per mm; None if Kiln does not know it.
pub fn measured_medium(name: &str) -> Option<([f32; 3], [f32; 3])> {
    JENSEN_2001
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, sigma_s, sigma_a)| (*sigma_a, *sigma_s))
}

/// The names [`measured_medium`] knows, for error messages.
pub fn measured_medium_names() -> Vec<&'static str> {
    JENSEN_2001.iter().map(|(n, _, _)| *n).collect()
}
