//! Materials as described: their kinds and parameters (textured where the scene may vary
//! them), roughness, normal perturbation, layers, conductors' spectra and subsurface
//! interiors.

use crate::error::Loc;
use crate::spectrum::Rgb;
use crate::textures::{FloatValue, RgbValue, TextureImage};
use std::sync::Arc;

/// Microfacet roughness along u and v, as the scene gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roughness {
    pub u: FloatValue,
    pub v: FloatValue,
    /// pbrt-v4's "remaproughness": the microfacet alpha is the square root of the value.
    pub remap: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MaterialKind {
    Diffuse {
        reflectance: RgbValue,
    },
    /// pbrt-v4's "subsurface": a dielectric boundary (`eta`, `roughness`) around a
    /// homogeneous scattering interior, which Kiln renders by random walk (a volumetric
    /// path inside the shape) rather than pbrt-v4's tabulated BSSRDF.
    Subsurface {
        eta: f32,
        roughness: Roughness,
        /// Henyey-Greenstein asymmetry inside.
        g: f32,
        interior: SubsurfaceInterior,
    },
    Dielectric {
        /// The index (a spectrum's at about 550 nm), what RGB rendering refracts by.
        eta: f32,
        roughness: Roughness,
        /// The index as a spectrum, where the scene gave one (inline, a file or a named
        /// glass): spectral rendering refracts each path by its hero wavelength's index.
        dispersion: Option<Arc<Vec<(f32, f32)>>>,
    },
    ThinDielectric {
        eta: f32,
    },
    Conductor {
        eta: RgbValue,
        k: RgbValue,
        roughness: Roughness,
        /// eta and k as the spectra they were given as, when both were sampled spectra
        /// (inline or from files): the renderer then reflects by their spectral Fresnel.
        spectra: Option<Arc<ConductorSpectra>>,
    },
    /// A conductor given by its reflectance at normal incidence instead of eta and k.
    ConductorReflectance {
        reflectance: RgbValue,
        roughness: Roughness,
    },
    /// pbrt-v4's stochastic layered BSDF: a dielectric coat over a diffuse base.
    CoatedDiffuse {
        reflectance: RgbValue,
        roughness: Roughness,
        eta: f32,
        layer: LayerDesc,
    },
    /// pbrt-v4's stochastic layered BSDF: a dielectric coat over a conductor.
    CoatedConductor {
        interface_roughness: Roughness,
        interface_eta: f32,
        /// eta and k, or (if `reflectance` is given) eta 1 and k from it.
        conductor_eta: RgbValue,
        conductor_k: RgbValue,
        /// As [`MaterialKind::Conductor`]'s.
        conductor_spectra: Option<Arc<ConductorSpectra>>,
        reflectance: Option<RgbValue>,
        conductor_roughness: Roughness,
        layer: LayerDesc,
    },
    /// pbrt-v4's "hair": Chiang et al.'s fibre BSDF, for curves.
    Hair {
        absorption: HairAbsorption,
        eta: FloatValue,
        beta_m: FloatValue,
        beta_n: FloatValue,
        /// The cuticle scales' tilt, in degrees.
        alpha: FloatValue,
    },
    /// Lambertian reflection and transmission, each scaled by `scale` and clamped to [0, 1].
    DiffuseTransmission {
        reflectance: RgbValue,
        transmittance: RgbValue,
        scale: f32,
    },
    /// pbrt-v4's "mix": at each intersection one of two materials, the second with
    /// probability `amount`, chosen by a hash of the point.
    Mix {
        materials: [MaterialId; 2],
        amount: FloatValue,
    },
    /// pbrt-v4's "measured": a BRDF tabulated in the RGL format (a `.bsdf` file).
    Measured(Arc<crate::files::measured::MeasuredBrdf>),
    /// Marks a boundary between media; rays pass through it unchanged.
    Interface,
}

#[derive(Debug, Clone)]
pub struct MaterialDesc {
    pub kind: MaterialKind,
    /// How the material perturbs the shading normal (pbrt-v4's "displacement" and
    /// "normalmap", which every material takes).
    pub normal: NormalPerturbationDesc,
    /// The name given by MakeNamedMaterial, if any.
    pub name: Option<String>,
    pub loc: Loc,
}

/// Bump mapping by a displacement texture, or a tangent-space normal map.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum NormalPerturbationDesc {
    #[default]
    None,
    /// Displacement along the normal, in scene units.
    Bump(FloatValue),
    /// A normal map image (linear RGB: 2·rgb − 1 in the surface's tangent frame).
    NormalMap(Arc<TextureImage>),
}

/// The medium between a layered material's coat and base, and how its walks are estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerDesc {
    pub thickness: FloatValue,
    pub albedo: RgbValue,
    pub g: FloatValue,
    pub max_depth: u32,
    pub n_samples: u32,
}

/// Index into [`SceneDescription::materials`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

/// How a hair fibre's absorption is given (pbrt-v4 takes the first given of these).
#[derive(Debug, Clone, PartialEq)]
pub enum HairAbsorption {
    /// Absorption per unit of the fibre's diameter.
    SigmaA(RgbValue),
    /// The colour the fibre should have after multiple scattering ("reflectance" or "color").
    Reflectance(RgbValue),
    /// Eumelanin and pheomelanin concentrations.
    Melanin {
        eumelanin: FloatValue,
        pheomelanin: FloatValue,
    },
}

/// A conductor's eta and k as sampled spectra: (wavelength nm, value) pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct ConductorSpectra {
    pub eta: Vec<(f32, f32)>,
    pub k: Vec<(f32, f32)>,
}

/// How a "subsurface" material gives its interior, `scale` applied (per unit length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SubsurfaceInterior {
    /// `sigma_a` and `sigma_s` (pbrt-v4's defaults, a skin-like medium in mm⁻¹, without them).
    Coefficients { sigma_a: Rgb, sigma_s: Rgb },
    /// `reflectance` (the multiple-scattering albedo to reach, which may be a texture: a
    /// walk then takes its coefficients from where it entered) and `mfp` (mean free path).
    Reflectance {
        reflectance: crate::textures::RgbValue,
        mfp: Rgb,
    },
}
