//! The plain scene description that the parser produces and the renderer consumes.
//!
//! Everything here is data: typed, validated, in world space where that is
//! meaningful, with the file location it came from. Nothing here knows how it
//! will be rendered.

use crate::error::{Diagnostic, Loc};
use crate::textures::{FloatTextureDesc, FloatValue, RgbValue, SpectrumTextureDesc, TextureImage};
use glam::{DMat4, DVec3};
use std::sync::Arc;

pub use crate::spectrum::Rgb;

/// A whole scene: camera and film settings, materials, shapes and lights.
#[derive(Debug, Clone)]
pub struct SceneDescription {
    pub camera: CameraDesc,
    pub film: FilmDesc,
    pub sampler: SamplerDesc,
    pub filter: FilterDesc,
    pub integrator: IntegratorDesc,
    pub materials: Vec<MaterialDesc>,
    /// Textures in definition order; a texture refers only to textures before it.
    pub float_textures: Vec<FloatTextureDesc>,
    pub spectrum_textures: Vec<SpectrumTextureDesc>,
    pub media: Vec<MediumDesc>,
    /// The medium the camera sits in (the outside medium current at the Camera directive).
    pub camera_medium: Option<MediumId>,
    pub shapes: Vec<ShapeDesc>,
    pub lights: Vec<LightDesc>,
    /// Named objects (ObjectBegin/End), referred to by [`InstanceDesc::object`].
    pub objects: Vec<ObjectDesc>,
    pub instances: Vec<InstanceDesc>,
    /// pbrt-v4's TransformTimes: the times of the start and end transforms (0 and 1 by
    /// default); between them a moving transform is interpolated, outside them held.
    pub transform_times: [f64; 2],
    /// Every file the scene read besides its main file (includes, meshes, maps, grids), in order.
    pub files: Vec<std::path::PathBuf>,
    /// Warnings found while loading (errors abort loading instead).
    pub warnings: Vec<Diagnostic>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Projection {
    /// `fov` is the full angle, in degrees, of the shorter image axis.
    Perspective {
        fov_degrees: f64,
    },
    Orthographic,
    /// pbrt-v4's spherical camera: the whole sphere of directions on the film, in the
    /// equal-area square layout or as an equirectangular (latitude-longitude) map.
    Spherical {
        equal_area: bool,
    },
    /// pbrt-v4's realistic camera: rays traced from the film through a lens system.
    Realistic(Arc<RealisticLens>),
}

/// A lens system as pbrt-v4's lens files give it, front (scene side) to back, and how it
/// is set.
#[derive(Debug, Clone, PartialEq)]
pub struct RealisticLens {
    /// Per interface, in millimetres as in the file: curvature radius (0: the aperture
    /// stop), thickness (the distance to the next interface, or to the film for the last),
    /// the index of refraction behind it (0: air), and its aperture diameter.
    pub elements: Vec<[f64; 4]>,
    /// The aperture stop's diameter, in millimetres ("aperturediameter").
    pub aperture_diameter: f64,
    /// The distance in focus, in metres ("focusdistance").
    pub focus_distance: f64,
    /// The aperture's shape as a grey image over the stop's square, looked up at
    /// ((x / r + 1) / 2, (y / r + 1) / 2) for a point (x, y) on a stop of radius r, row 0
    /// first (pbrt-v4's image after its flip), normalised to pass as much light as the round
    /// stop; None: round.
    pub aperture: Option<ApertureImage>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ApertureImage {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

#[derive(Debug, Clone)]
pub struct CameraDesc {
    pub projection: Projection,
    /// Camera space to world space (pbrt's convention: the camera looks down +z, +y up), at
    /// the start of the transform times.
    pub camera_to_world: DMat4,
    /// At their end, where it differs: the camera moves over the shutter.
    pub camera_to_world_end: Option<DMat4>,
    pub lens_radius: f64,
    pub focal_distance: f64,
    /// [xmin, xmax, ymin, ymax] of the screen window; `None` means pbrt's default for the aspect ratio.
    pub screen_window: Option<[f64; 4]>,
    /// The shutter's interval (pbrt-v4's shutteropen, shutterclose); its length is the
    /// exposure time the film's ISO multiplies.
    pub shutter: [f64; 2],
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct FilmDesc {
    pub xresolution: u32,
    pub yresolution: u32,
    pub filename: String,
    /// [x0, x1, y0, y1] in pixels, half-open: the region to render. The whole frame when not cropped.
    pub pixel_bounds: [u32; 4],
    pub sensor: SensorDesc,
    /// The film's diagonal in metres (pbrt-v4's "diagonal", given in millimetres; only the
    /// realistic camera uses it).
    pub diagonal: f64,
    /// pbrt-v4's "gbuffer" film: [`GBUFFER_CHANNELS`] beside R, G and B, in this space.
    pub gbuffer: Option<GBufferSpace>,
    pub loc: Loc,
}

/// The space a G-buffer's positions and normals are given in (pbrt-v4's "coordinatesystem").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GBufferSpace {
    /// The camera's space (pbrt-v4's default): the camera at the origin, looking down +z.
    Camera,
    World,
}

/// The channels a G-buffer film writes beside R, G and B, named as pbrt-v4 names them: the
/// first visible surface's reflectance, position, screen-space depth derivatives, geometric
/// and shading normals and uv, and the per-pixel variance of the samples that saw a surface.
pub const GBUFFER_CHANNELS: [&str; 22] = [
    "Albedo.R",
    "Albedo.G",
    "Albedo.B",
    "P.X",
    "P.Y",
    "P.Z",
    "dzdx",
    "dzdy",
    "N.X",
    "N.Y",
    "N.Z",
    "Ns.X",
    "Ns.Y",
    "Ns.Z",
    "u",
    "v",
    "Variance.R",
    "Variance.G",
    "Variance.B",
    "RelativeVariance.R",
    "RelativeVariance.G",
    "RelativeVariance.B",
];

/// pbrt-v4's pixel sensor: each sample's response (XYZ on the CIE 1931 observer, or a named
/// camera's raw RGB) times the imaging ratio (exposure time · ISO / 100), its largest
/// component clamped to `max_component`, then white balanced from daylight at
/// `white_balance` kelvin (0: none) to the output's white.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorDesc {
    pub iso: f64,
    /// Kelvin; 0 for none (a camera's is never 0: it defaults to 6500).
    pub white_balance: f64,
    pub max_component: f64,
    /// A named camera's response; None for the CIE 1931 observer ("cie1931").
    pub camera: Option<crate::camera_sensor::CameraResponse>,
}

impl Default for SensorDesc {
    fn default() -> SensorDesc {
        SensorDesc {
            iso: 100.0,
            white_balance: 0.0,
            max_component: f64::INFINITY,
            camera: None,
        }
    }
}

#[derive(Debug, Clone)]
pub struct SamplerDesc {
    /// The sampler name in the file; Kiln always uses its own deterministic sampler.
    pub name: String,
    pub pixel_samples: u32,
    pub seed: u32,
    /// Kiln's adaptive sampling (`"float noisethreshold"`): a pixel stops taking samples
    /// once its own estimate's error is below this. None: every pixel takes them all.
    pub noise_threshold: Option<f32>,
    /// The fewest samples a pixel takes before it may stop (`"integer minsamples"`).
    pub min_samples: u32,
    pub loc: Loc,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FilterKind {
    Box,
    Triangle,
    Gaussian {
        sigma: f64,
    },
    /// pbrt-v4's Mitchell-Netravali filter (negative lobes).
    Mitchell {
        b: f64,
        c: f64,
    },
    /// pbrt-v4's "sinc": a Lanczos-windowed sinc (negative lobes).
    Sinc {
        tau: f64,
    },
}

#[derive(Debug, Clone)]
pub struct FilterDesc {
    pub kind: FilterKind,
    pub radius: [f64; 2],
    pub loc: Loc,
}

/// Which estimator of direct lighting the path tracer uses. Only `Mis` is a
/// production setting; the others exist to check that the estimators agree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightStrategy {
    Mis,
    LightOnly,
    BsdfOnly,
}

/// How the path tracer chooses the light to sample at each vertex (pbrt-v4's
/// "lightsampler").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightSamplerKind {
    /// A bounding volume hierarchy over the lights, chosen by an importance that accounts
    /// for each cluster's power, distance and orientation from the shading point (pbrt-v4's
    /// default).
    #[default]
    Bvh,
    /// In proportion to each light's power, wherever the shading point is.
    Power,
    /// Every light equally.
    Uniform,
    /// In proportion to every light's importance from the shading point (the hierarchy's
    /// measure, without the hierarchy: exact, and linear in the number of lights).
    Exhaustive,
}

/// The integrators Kiln has: pbrt-v4's "path" ignores participating media, "volpath"
/// renders them. Integrators Kiln lacks are rendered with "volpath".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IntegratorKind {
    Path,
    VolPath,
    /// pbrt-v4's stochastic progressive photon mapping (surfaces only, as pbrt-v4's).
    Sppm,
}

/// How many events a subsurface walk may take unless the Integrator's "walkdepth" says
/// otherwise: enough that a walk in skin-like stuff (single-scattering albedo 0.99) is almost
/// never cut off before Russian roulette or its surface ends it.
pub const DEFAULT_WALK_DEPTH: u32 = 1024;

#[derive(Debug, Clone)]
pub struct IntegratorDesc {
    /// The name in the file ("path", "volpath", or one Kiln mapped onto those).
    pub name: String,
    /// What Kiln renders it with.
    pub kind: IntegratorKind,
    pub max_depth: u32,
    /// Russian roulette may end paths from this bounce on (Kiln's "integer rrdepth").
    pub rr_depth: u32,
    /// The most events one subsurface random walk may take, its scatterings inside and its
    /// reflections off the inside of its surface (Kiln's "integer walkdepth"). A walk counts
    /// as one bounce towards `max_depth`, as pbrt-v4's BSSRDF does.
    pub walk_depth: u32,
    pub strategy: LightStrategy,
    pub light_sampler: LightSamplerKind,
    /// pbrt-v4's "regularize": after the first non-specular bounce, microfacet BSDFs are
    /// roughened (alpha under 0.3 doubled, within [0.1, 0.3]).
    pub regularize: bool,
    /// Clamp the radiance of each path sample to this value (0 disables it).
    pub max_radiance: f32,
    /// Kiln's photon maps (none unless asked for, or Integrator "photonmap").
    pub photons: PhotonDesc,
    /// SPPM's photons per iteration ("integer photonsperiteration"; None: pbrt-v4's default,
    /// the number of pixels rendered).
    pub sppm_photons: Option<u64>,
    /// SPPM's initial search radius ("float radius", default 1).
    pub sppm_radius: f32,
    pub loc: Loc,
}

/// Kiln's photon maps (seeds 003 and 004): on "path" and "volpath" with
/// "integer causticphotons" or "integer volumephotons", or Integrator "photonmap", which
/// turns both on by default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotonDesc {
    /// Photons traced for the caustic maps ("integer causticphotons"; 0: none).
    pub caustic_photons: u64,
    /// Their search radius, or the k-nearest gather's largest ("float causticradius"; 0:
    /// 1/200 of the scene's radius).
    pub caustic_radius: f32,
    /// Gather the k nearest caustic photons ("integer causticnearest"; 0: all within the
    /// radius).
    pub caustic_nearest: u32,
    /// Photons traced for the volume map of multiply scattered light in media
    /// ("integer volumephotons"; 0: none).
    pub volume_photons: u64,
    /// As `caustic_radius`, for the volume map ("float volumeradius"; 0: 1/50 of the
    /// scene's radius).
    pub volume_radius: f32,
    /// As `caustic_nearest` ("integer volumenearest").
    pub volume_nearest: u32,
    /// Weight-aware Russian roulette while tracing photons ("string photonroulette":
    /// "weight", the default, or "none").
    pub roulette: bool,
}

impl PhotonDesc {
    /// No photon maps.
    pub const NONE: PhotonDesc = PhotonDesc {
        caustic_photons: 0,
        caustic_radius: 0.0,
        caustic_nearest: 0,
        volume_photons: 0,
        volume_radius: 0.0,
        volume_nearest: 0,
        roulette: true,
    };
}

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
        eta: f32,
        roughness: Roughness,
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

/// Triangle mesh data in object space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMeshData {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Three per triangle.
    pub indices: Vec<u32>,
    /// pbrt-v4's bilinear patches whose corners are not in one plane: four per patch, in
    /// its corner order p00, p10, p01, p11 (planar quads are two triangles in `indices`).
    pub quads: Vec<u32>,
}

/// How far, relative to its size, a quad's corners may stray from one plane and still be
/// two triangles (exported meshes round their planar quads' corners).
pub const PLANAR_QUAD_TOLERANCE: f64 = 1e-4;

impl TriangleMeshData {
    /// Every face as triangles: the mesh's own, then each bilinear patch as two (split
    /// along p00-p11), for what works on triangles only (displacement).
    pub fn triangulated_indices(&self) -> Vec<u32> {
        let mut all = self.indices.clone();
        for q in self.quads.chunks_exact(4) {
            all.extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
        }
        all
    }

    /// The mesh with `quads` (four indices each, p00 p10 p01 p11) added: planar ones as two
    /// triangles split along p00-p11, the others as bilinear patches.
    pub fn with_quads(mut self, quads: &[u32]) -> TriangleMeshData {
        let at = |i: u32| self.positions[i as usize].map(f64::from);
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let mut kept = Vec::new();
        for q in quads.chunks_exact(4) {
            let [p00, p10, p01, p11] = [at(q[0]), at(q[1]), at(q[2]), at(q[3])];
            let a = cross(sub(p10, p00), sub(p01, p00));
            let b = cross(sub(p11, p10), sub(p11, p01));
            let n = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
            let len = dot(n, n).sqrt();
            let size = dot(sub(p11, p00), sub(p11, p00))
                .max(dot(sub(p10, p01), sub(p10, p01)))
                .sqrt();
            let planar = len == 0.0
                || size == 0.0
                || [p10, p01, p11]
                    .iter()
                    .all(|p| (dot(sub(*p, p00), n) / len).abs() <= PLANAR_QUAD_TOLERANCE * size);
            if planar {
                self.indices
                    .extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
            } else {
                kept.extend_from_slice(q);
            }
        }
        self.quads.extend(kept);
        self
    }

    /// Whether the mesh clearly faces inward: the volume its faces enclose, oriented as
    /// pbrt-v4 orients them (by their winding, or by the vertex normals where the mesh has
    /// them, which the geometric normals then follow), is negative and at least a quarter of
    /// the unsigned volume its faces sweep from the mesh's centre. A closed mesh facing out
    /// encloses a positive volume; an open sheet rarely passes the quarter. Bilinear patches
    /// count as their two triangles.
    pub fn faces_inward(&self) -> bool {
        let at = |i: u32| glam::DVec3::from(self.positions[i as usize].map(f64::from));
        let (mut lo, mut hi) = (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY);
        for p in &self.positions {
            let p = glam::DVec3::from(p.map(f64::from));
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        let centre = (lo + hi) / 2.0;
        let (mut signed, mut swept, mut agreement) = (0.0, 0.0, 0.0);
        for t in self.triangulated_indices().chunks_exact(3) {
            let [a, b, c] = [at(t[0]) - centre, at(t[1]) - centre, at(t[2]) - centre];
            let v = a.dot(b.cross(c));
            signed += v;
            swept += v.abs();
            if let Some(n) = &self.normals {
                let n = t
                    .iter()
                    .map(|&i| glam::DVec3::from(n[i as usize].map(f64::from)))
                    .sum::<glam::DVec3>();
                agreement += (b - a).cross(c - a).dot(n);
            }
        }
        if agreement < 0.0 {
            signed = -signed;
        }
        signed < 0.0 && -signed >= 0.25 * swept
    }
}

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

/// How a curve is drawn (pbrt-v4's "type").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurveType {
    /// A ribbon that always faces the ray.
    Flat,
    /// A flat ribbon shaded as if it were a cylinder (its normal turns across the width).
    Cylinder,
    /// A ribbon oriented by normals given at the segments' ends.
    Ribbon,
}

/// A curve in object space: cubic Bézier segments, each with its widths at its two ends
/// (the curve's "width0" to "width1" spread evenly over the segments) and, for ribbons,
/// its normals there.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveData {
    pub segments: Vec<[[f32; 3]; 4]>,
    pub widths: Vec<[f32; 2]>,
    pub normals: Option<Vec<[[f32; 3]; 2]>>,
    pub kind: CurveType,
    /// Each segment is split into 2^split_depth pieces for the BVH (pbrt-v4's "splitdepth").
    pub split_depth: u32,
}

/// A conductor's eta and k as sampled spectra: (wavelength nm, value) pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct ConductorSpectra {
    pub eta: Vec<(f32, f32)>,
    pub k: Vec<(f32, f32)>,
}

/// A plymesh's displacement: a float texture and the longest edge to refine to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshDisplacement {
    pub texture: FloatValue,
    pub edge_length: f32,
}

#[derive(Debug, Clone)]
pub enum ShapeKind {
    Mesh(Arc<TriangleMeshData>),
    /// pbrt-v4's sphere about the object-space origin, cut to `z_min ≤ z ≤ z_max` and
    /// `0 ≤ φ ≤ phi_max` (radians; a whole sphere has `z_min = -radius`, `z_max = radius`,
    /// `phi_max = 2π`).
    Sphere {
        radius: f64,
        z_min: f64,
        z_max: f64,
        phi_max: f64,
    },
    /// pbrt-v4's disk: the annulus `inner_radius ≤ r ≤ radius` in the plane `z = height`,
    /// facing +z, cut to `0 ≤ φ ≤ phi_max` (radians).
    Disk {
        height: f64,
        radius: f64,
        inner_radius: f64,
        phi_max: f64,
    },
    /// pbrt-v4's "curve": cubic Bézier segments (b-splines and quadratics converted).
    Curve(Arc<CurveData>),
    /// pbrt-v4's cylinder about the z axis, open at both ends, facing outwards.
    Cylinder {
        radius: f64,
        z_min: f64,
        z_max: f64,
        phi_max: f64,
    },
    /// Kiln's surface of revolution: a contour in the (r, z) half-plane turned about z.
    Revolution(Arc<RevolutionDesc>),
}

/// `Shape "revolution"`: the contour `"point2 contour" [r z ...]` swept about the object's
/// z axis through `phi_max` radians. Its normal faces to the right of the contour's
/// direction of travel in the (r, z) plane; a contour whose last point is its first is closed.
#[derive(Debug, Clone, PartialEq)]
pub struct RevolutionDesc {
    pub contour: Vec<[f32; 2]>,
    /// `"vector2 normals"`: a shading normal (nr, nz) per point; without them, neighbouring
    /// strips' normals are averaged where the contour turns by less than `crease`.
    pub normals: Option<Vec<[f32; 2]>>,
    /// `"float creaseangle"` (degrees in the file, radians here; 30° by default).
    pub crease: f64,
    pub phi_max: f64,
}

impl ShapeKind {
    /// A whole sphere of `radius`.
    pub fn sphere(radius: f64) -> ShapeKind {
        ShapeKind::Sphere {
            radius,
            z_min: -radius,
            z_max: radius,
            phi_max: std::f64::consts::TAU,
        }
    }
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

/// Emission attached to a shape by AreaLightSource.
#[derive(Debug, Clone, PartialEq)]
pub enum AreaLightDesc {
    Diffuse {
        /// Radiance, with `scale` already applied; with an image, the scale alone, which
        /// multiplies the image's linear RGB.
        radiance: Rgb,
        /// pbrt-v4's `"string filename"`: radiance from an image at the surface's (u, 1 − v),
        /// bilinearly interpolated, clamped at the edges.
        image: Option<Arc<crate::textures::TextureImage>>,
        two_sided: bool,
        /// pbrt-v4's "power": the lumens each shape (each triangle of a mesh, as in
        /// pbrt-v4) emits; the radiance is then `radiance` · power / (π · area · sides ·
        /// the image's mean luminance, if any).
        power: Option<f32>,
        loc: Loc,
    },
    /// Seed 000's VolumeLight: the shape's interior emits, and the radiance leaving a
    /// surface point integrates that emission along the refracted interior segment.
    Volume(VolumeLightDesc),
}

/// `AreaLightSource "volume"`: emission inside a shape, seen through its surface.
#[derive(Debug, Clone, PartialEq)]
pub struct VolumeLightDesc {
    /// Emitted radiance per unit length inside the shape, `scale` applied.
    pub le: Rgb,
    /// Multipliers of `le` over the shape's object-space bounding box, trilinearly interpolated.
    pub grid: Option<Arc<VoxelGrid>>,
    /// Midpoint-rule steps along each interior segment (a uniform field needs only 1).
    pub steps: u32,
    /// Random interior segments per face for estimating each face's power.
    pub power_samples: u32,
    /// Absorption inside the shape, per unit length (emission-absorption); 0 by default.
    pub sigma_a: Rgb,
    pub loc: Loc,
}

/// A voxel grid of scalar values, x fastest: `values[(z * ny + y) * nx + x]`.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelGrid {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    pub values: Vec<f32>,
}

#[derive(Debug, Clone)]
pub struct ShapeDesc {
    pub kind: ShapeKind,
    /// The transform at the start of the transform times.
    pub object_to_world: DMat4,
    /// The transform at their end, where it differs (ActiveTransform): the shape moves,
    /// and is motion-blurred over the shutter.
    pub object_to_world_end: Option<DMat4>,
    /// ReverseOrientation was in effect when the shape was declared. (Whether the
    /// transform swaps handedness is the renderer's to derive from `object_to_world`.)
    pub reverse_orientation: bool,
    pub material: MaterialId,
    pub area_light: Option<AreaLightDesc>,
    /// The media inside and outside the shape, when they differ (a medium boundary).
    pub media: Option<MediumInterfaceDesc>,
    /// pbrt-v4's "alpha": where it is below 1 rays pass through the surface (stochastically
    /// between 0 and 1). None when the shape is opaque everywhere.
    pub alpha: Option<FloatValue>,
    /// pbrt-v4's plymesh "displacement": the mesh refined to edges shorter than
    /// `edge_length` (world space) and moved along its normals by the texture.
    pub displacement: Option<MeshDisplacement>,
    /// Kiln's `"integer priority"` for nested dielectrics: 0 (the default) for a shape as
    /// pbrt-v4 has it; 1 or more makes it a nested shape, whose boundary is ignored where it
    /// lies inside a shape of higher priority.
    pub priority: u32,
    pub loc: Loc,
}

/// Index into [`SceneDescription::media`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MediumId(pub u32);

/// The media on the two sides of a surface; `None` is vacuum. Outside is the side its normal points to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MediumInterfaceDesc {
    pub inside: Option<MediumId>,
    pub outside: Option<MediumId>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum MediumKind {
    /// Constant coefficients (per unit length, `scale` applied) and emission (`Lescale` applied).
    Homogeneous {
        sigma_a: Rgb,
        sigma_s: Rgb,
        le: Rgb,
        phase: PhaseDesc,
    },
    /// pbrt-v4's "uniformgrid", "rgbgrid" and "cloud": coefficients varying over the box
    /// `p0`..`p1` of the medium's own space (see [`GridDensity`]).
    Grid(Arc<GridMediumDesc>),
}

/// A phase function: Henyey-Greenstein (pbrt's), or Schlick's approximation of it
/// ("string phase" "schlick", a Kiln parameter) with the same asymmetry `g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PhaseDesc {
    HenyeyGreenstein { g: f32 },
    Schlick { g: f32 },
}

/// A heterogeneous medium. Grids are looked up as pbrt-v4's `SampledGrid` does: sample
/// (i, j, k) sits at the centre of voxel (i, j, k) of the box, values are interpolated
/// trilinearly, and samples outside the grid count as zero (so a field falls off over the
/// outer half voxel).
#[derive(Debug, Clone, PartialEq)]
pub struct GridMediumDesc {
    /// Per unit density and length, `scale` applied.
    pub sigma_a: Rgb,
    pub sigma_s: Rgb,
    pub phase: PhaseDesc,
    pub density: GridDensity,
    pub emission: GridEmission,
    pub p0: [f32; 3],
    pub p1: [f32; 3],
    /// The CTM when the medium was defined (pbrt's renderFromMedium).
    pub medium_to_world: DMat4,
    /// Where the grids' samples sit in the box.
    pub lattice: Lattice,
}

/// Where a grid medium's samples sit in its box `p0`..`p1`. Either way values are trilinear
/// between samples and zero beyond the grid's outermost ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lattice {
    /// pbrt-v4's `SampledGrid`: sample (i, j, k) of an nx·ny·nz grid at the centre of voxel
    /// (i, j, k) when the box is cut into nx·ny·nz voxels.
    Centred,
    /// At the integer points of a space the box maps into affinely (a NanoVDB grid's index
    /// space, shifted to put sample (0, 0, 0) at its origin): `to_samples` takes a point of
    /// the unit box (0..1 across `p0`..`p1`) there.
    Affine { to_samples: DMat4 },
}

/// What multiplies a grid medium's `sigma_a` and `sigma_s` at each point of its box.
#[derive(Debug, Clone, PartialEq)]
pub enum GridDensity {
    /// pbrt-v4's "uniformgrid": one density per voxel, for both coefficients.
    Scalar(VoxelGrid),
    /// pbrt-v4's "rgbgrid": an RGB value per voxel for each coefficient (the three grids
    /// are the channels); a coefficient without a grid is 1 everywhere, as in pbrt-v4.
    Rgb {
        sigma_a: Option<Box<[VoxelGrid; 3]>>,
        sigma_s: Option<Box<[VoxelGrid; 3]>>,
    },
    /// pbrt-v4's "cloud": a procedural density in [0, 1] from fractal noise, thinning with
    /// height (`density` scales the noise, `wispiness` perturbs its lookup, `frequency` is
    /// its scale).
    Cloud {
        density: f32,
        wispiness: f32,
        frequency: f32,
    },
}

/// Where a grid medium's emitted radiance Le comes from; the source term is sigma_a · Le.
#[derive(Debug, Clone, PartialEq)]
pub enum GridEmission {
    None,
    /// A constant colour times the `scale` grid ("Lescale": nx·ny·nz values, or one value
    /// as a 1x1x1 grid, pbrt's default).
    Constant {
        le: Rgb,
        scale: VoxelGrid,
    },
    /// The peak-normalised blackbody at (T − offset) · t_scale (none at or below 100 K),
    /// times `le_scale` and the `scale` grid where there is one (pbrt-v4's "uniformgrid" has
    /// a grid, its "nanovdb" a constant).
    Temperature {
        temperature: VoxelGrid,
        offset: f32,
        t_scale: f32,
        scale: Option<VoxelGrid>,
        le_scale: f32,
    },
    /// An RGB value per voxel (pbrt-v4's "rgbgrid" `Le`, the three grids its channels),
    /// times `scale`.
    Rgb {
        le: [VoxelGrid; 3],
        scale: f32,
    },
}

#[derive(Debug, Clone)]
pub struct MediumDesc {
    pub name: String,
    pub kind: MediumKind,
    pub loc: Loc,
}

/// A linear-RGB image (an environment map): row-major, top row first.
pub use kiln_image::ImageRgb;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvironmentLayout {
    /// pbrt-v4's equal-area octahedral square.
    EqualArea,
    /// Latitude-longitude (equirectangular), +z up in light space.
    LatLong,
}

#[derive(Debug, Clone)]
pub enum LightKind {
    Point {
        position: DVec3,
        intensity: Rgb,
    },
    Spot {
        position: DVec3,
        direction: DVec3,
        intensity: Rgb,
        cos_falloff_start: f64,
        cos_falloff_end: f64,
    },
    /// Light arriving from one direction; `direction` points from the scene towards the light.
    Distant {
        direction: DVec3,
        radiance: Rgb,
    },
    /// Constant radiance from every direction.
    UniformInfinite {
        radiance: Rgb,
    },
    /// Radiance from an environment map; `light_to_world` orients it.
    ImageInfinite {
        image: Arc<ImageRgb>,
        layout: EnvironmentLayout,
        scale: f32,
        light_to_world: DMat4,
        /// pbrt-v4's "portal": a world-space rectangle (a window); light arrives only from
        /// the side its normal (p3 − p0) × (p1 − p0) faces.
        portal: Option<[[f64; 3]; 4]>,
    },
    /// pbrt-v4's "goniometric": a point light whose intensity over directions is an
    /// equal-area square image's (the mean of its RGB), times `intensity`. The light looks
    /// along its space's y axis (pbrt-v4 swaps y and z).
    Goniometric {
        light_to_world: DMat4,
        intensity: Rgb,
        image: Arc<ImageRgb>,
    },
    /// pbrt-v4's "projection": a point light casting an image through a frustum of `fov`
    /// degrees along its space's +z, `scale` times the image's RGB as intensity.
    Projection {
        light_to_world: DMat4,
        scale: f32,
        fov: f64,
        image: Arc<ImageRgb>,
    },
    /// Constant radiance from the hemisphere around `up` only (seed 003's dome light).
    Dome {
        radiance: Rgb,
        up: DVec3,
    },
}

#[derive(Debug, Clone)]
pub struct LightDesc {
    pub kind: LightKind,
    /// The outside medium current at the LightSource directive: where photons from the light
    /// start (pbrt-v4 records it the same way).
    pub medium: Option<MediumId>,
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct ObjectDesc {
    pub name: String,
    /// Shapes in the object's own space.
    pub shapes: Vec<ShapeDesc>,
    pub loc: Loc,
}

#[derive(Debug, Clone)]
pub struct InstanceDesc {
    pub object: usize,
    pub instance_to_world: DMat4,
    /// As [`ShapeDesc::object_to_world_end`].
    pub instance_to_world_end: Option<DMat4>,
    pub loc: Loc,
}

/// Command-line and job overrides of a scene's own settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    pub resolution: Option<(u32, u32)>,
    pub spp: Option<u32>,
    pub seed: Option<u32>,
    /// Adaptive sampling's threshold; 0 turns it off.
    pub noise_threshold: Option<f32>,
}

impl SceneDescription {
    /// Applies overrides; a crop window keeps its fractions of the frame.
    /// The pixels a render of this scene holds: the film's crop window (the whole frame
    /// without one).
    pub fn rendered_pixels(&self) -> u64 {
        let [x0, x1, y0, y1] = self.film.pixel_bounds;
        u64::from(x1 - x0) * u64::from(y1 - y0)
    }

    /// Refuses a render of more than `max_pixels` pixels before anything is allocated for
    /// it, saying how large it would be.
    pub fn check_frame_size(&self, max_pixels: u64) -> Result<(), String> {
        let n = self.rendered_pixels();
        if n <= max_pixels {
            return Ok(());
        }
        let [x0, x1, y0, y1] = self.film.pixel_bounds;
        Err(format!(
            "a {}x{} render is {n} pixels, {:.1} GB of float RGB: more than the {max_pixels} pixels allowed (raise --max-frame-pixels on a machine with the memory)",
            x1 - x0,
            y1 - y0,
            n as f64 * 12.0 / 1e9
        ))
    }

    pub fn apply_overrides(&mut self, o: &Overrides) -> Result<(), String> {
        if let Some((w, h)) = o.resolution {
            if w == 0 || h == 0 || w > 65536 || h > 65536 {
                return Err(format!("resolution {w}x{h} is out of range"));
            }
            let f = &mut self.film;
            let [x0, x1, y0, y1] = f.pixel_bounds;
            let sx = |v: u32| (v as u64 * w as u64).div_ceil(f.xresolution as u64) as u32;
            let sy = |v: u32| (v as u64 * h as u64).div_ceil(f.yresolution as u64) as u32;
            let bounds = [sx(x0), sx(x1).min(w), sy(y0), sy(y1).min(h)];
            if bounds[0] >= bounds[1] || bounds[2] >= bounds[3] {
                return Err(format!("the crop window covers no pixel at {w}x{h}"));
            }
            f.pixel_bounds = bounds;
            f.xresolution = w;
            f.yresolution = h;
        }
        if let Some(spp) = o.spp {
            if spp == 0 || spp > 65536 {
                return Err(format!(
                    "{spp} samples per pixel is out of range (1 to 65536)"
                ));
            }
            self.sampler.pixel_samples = spp;
        }
        if let Some(seed) = o.seed {
            self.sampler.seed = seed;
        }
        if let Some(t) = o.noise_threshold {
            if !(t.is_finite() && t >= 0.0) {
                return Err(format!(
                    "a noise threshold is a number from 0 (off) up, not {t}"
                ));
            }
            self.sampler.noise_threshold = (t > 0.0).then_some(t);
        }
        Ok(())
    }
}
