//! The pbrt-v4 directive interpreter: tokens in, [`SceneDescription`] out.
//!
//! It keeps pbrt's graphics state (current transform, material, area light,
//! orientation) on an attribute stack and turns each directive into plain
//! scene entities as soon as it is read, so that every diagnostic can name the
//! file and line of the directive or parameter it is about.
//!
//! One [`Parser`] reads a whole scene; its `impl` is split by directive family, one
//! concept a file as pbrt-v4 keeps them: this file holds the entry points, the parser's
//! state, the directive dispatch and what every family shares (warnings, unused
//! parameters, file resolution, `Include`); `cursor.rs` reads directive arguments and
//! parameter lists; `state.rs` the graphics state (transforms, attributes, named
//! materials and media, object instancing); `options.rs` the rendering options
//! (camera, film, sampler, filter, integrator); `materials.rs`, `lights.rs`,
//! `shapes.rs` and `media.rs` the scene entities.

mod camera;
mod cursor;
mod curves;
mod lights;
mod materials;
mod media;
mod nanovdb;
mod options;
mod shapes;
mod state;
mod textures;

use crate::description::*;
use crate::error::{Diagnostic, Loc, Result, SceneError, Severity};
use crate::files::mesh_cache::MeshCache;
use crate::lexer::{Token, TokenKind, tokenize};
use crate::params::ParamSet;
use crate::textures::*;
use cursor::{Cursor, describe};
use glam::DMat4;
use state::{ActiveTransform, GraphicsState};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Loads a pbrt-v4 scene file and everything it includes or references.
pub fn load_file(path: &Path) -> Result<SceneDescription> {
    let text = crate::files::read_text(path, &Loc::synthetic("command line"))?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    load_str(&text, path, &base_dir)
}

/// Loads scene text; `file` names it in diagnostics, `base_dir` resolves relative paths.
pub fn load_str(text: &str, file: &Path, base_dir: &Path) -> Result<SceneDescription> {
    load(text, file, Parser::new(base_dir))
}

/// Loads a scene file that may read no file outside `root`: every file it names (Include,
/// Import, meshes, grids, images) must resolve inside that folder, or loading fails with
/// the name as written, before the file is opened. What a farm loads from a scene bundle
/// goes through this, so a scene cannot make a coordinator or a worker read, and quote in
/// an error, a file of the machine it runs on.
pub fn load_file_within(path: &Path, root: &Path) -> Result<SceneDescription> {
    load_file_within_sharing(path, root, None)
}

/// [`load_file_within`], taking the meshes it reads from files from `meshes` where they
/// are kept there (a shot's frames that include the same geometry), and keeping them there.
pub fn load_file_within_sharing(
    path: &Path,
    root: &Path,
    meshes: Option<Arc<MeshCache>>,
) -> Result<SceneDescription> {
    let text = crate::files::read_text(path, &Loc::synthetic("command line"))?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut parser = Parser::new(&base_dir);
    parser.root = Some(normalize(root));
    parser.meshes = meshes;
    load(&text, path, parser)
}

fn load(text: &str, file: &Path, mut parser: Parser) -> Result<SceneDescription> {
    let file = Arc::new(file.to_path_buf());
    let tokens = tokenize(text, &file)?;
    parser.parse_tokens(&tokens, &file, 0)?;
    parser.finish(&file)
}

/// `path` with `.` and `..` components resolved lexically (no file system access: a scene
/// bundle holds no links).
fn normalize(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            other => out.push(other),
        }
    }
    out
}

struct Parser {
    base_dir: PathBuf,
    /// Where meshes read from files are shared with other scenes, if anywhere.
    meshes: Option<Arc<MeshCache>>,
    /// The folder every file the scene names must lie in, when loading is confined.
    root: Option<PathBuf>,
    warnings: Vec<Diagnostic>,
    gs: GraphicsState,
    stack: Vec<(GraphicsState, Loc, bool)>,
    /// The TransformBegin deprecation has been warned about (once per scene, as pbrt-v4).
    warned_transform_begin: bool,
    /// TransformTimes.
    transform_times: [f64; 2],
    /// pbrt-v4's `Option "seed"`: the sampler's seed where the Sampler gives none.
    option_seed: Option<u32>,
    /// Kiln's `Option "kiln.spectral"`.
    option_spectral: bool,
    /// The Sampler directive gave a "seed".
    sampler_seed_given: bool,
    /// Named coordinate systems: the transforms at the shutter's start and end.
    named_coordinate_systems: HashMap<String, (DMat4, DMat4)>,
    in_world: bool,
    camera: Option<CameraDesc>,
    film: Option<FilmDesc>,
    sampler: Option<SamplerDesc>,
    filter: Option<FilterDesc>,
    integrator: Option<IntegratorDesc>,
    materials: Vec<MaterialDesc>,
    named_materials: HashMap<String, MaterialId>,
    float_textures: Vec<FloatTextureDesc>,
    float_texture_names: HashMap<String, FloatTextureId>,
    spectrum_textures: Vec<SpectrumTextureDesc>,
    spectrum_texture_names: HashMap<String, SpectrumTextureId>,
    /// Texture images by file and encoding: each is read once however many textures use it.
    images: HashMap<(PathBuf, String), Arc<TextureImage>>,
    /// Measured BRDFs by file, each read once however many materials use it.
    measured: HashMap<PathBuf, Arc<crate::files::measured::MeasuredBrdf>>,
    shapes: Vec<ShapeDesc>,
    lights: Vec<LightDesc>,
    objects: Vec<ObjectDesc>,
    object_names: HashMap<String, usize>,
    current_object: Option<ObjectDesc>,
    instances: Vec<InstanceDesc>,
    files: Vec<PathBuf>,
    media: Vec<MediumDesc>,
    named_media: HashMap<String, MediumId>,
    camera_medium: Option<MediumId>,
}

impl Parser {
    fn new(base_dir: &Path) -> Parser {
        let default_material = MaterialDesc {
            normal: NormalPerturbationDesc::None,
            kind: MaterialKind::Diffuse {
                reflectance: RgbValue::Constant([0.5, 0.5, 0.5]),
            },
            name: None,
            loc: Loc::synthetic("default material"),
        };
        Parser {
            base_dir: base_dir.to_path_buf(),
            meshes: None,
            root: None,
            warnings: Vec::new(),
            gs: GraphicsState {
                ctm: DMat4::IDENTITY,
                ctm_end: DMat4::IDENTITY,
                active: ActiveTransform::All,
                reverse_orientation: false,
                material: MaterialId(0),
                area_light: None,
                media: (String::new(), String::new()),
                attributes: Default::default(),
                color_space: crate::colorspace::ColorSpace::srgb(),
            },
            stack: Vec::new(),
            warned_transform_begin: false,
            transform_times: [0.0, 1.0],
            option_seed: None,
            option_spectral: true,
            sampler_seed_given: false,
            named_coordinate_systems: HashMap::new(),
            in_world: false,
            camera: None,
            film: None,
            sampler: None,
            filter: None,
            integrator: None,
            materials: vec![default_material],
            named_materials: HashMap::new(),
            float_textures: Vec::new(),
            float_texture_names: HashMap::new(),
            spectrum_textures: Vec::new(),
            spectrum_texture_names: HashMap::new(),
            images: HashMap::new(),
            measured: HashMap::new(),
            shapes: Vec::new(),
            lights: Vec::new(),
            objects: Vec::new(),
            object_names: HashMap::new(),
            current_object: None,
            instances: Vec::new(),
            files: Vec::new(),
            media: Vec::new(),
            named_media: HashMap::new(),
            camera_medium: None,
        }
    }

    fn warn(&mut self, loc: &Loc, message: impl Into<String>) {
        self.warnings.push(Diagnostic {
            severity: Severity::Warning,
            loc: loc.clone(),
            message: message.into(),
        });
    }

    /// Reports the parameters a directive did not use: an error unless listed as harmless.
    fn check_unused(&mut self, params: &ParamSet, what: &str, harmless: &[&str]) -> Result<()> {
        let mut errors = Vec::new();
        let mut warnings = Vec::new();
        for p in params.unused() {
            if harmless.contains(&p.name.as_str()) {
                warnings.push((
                    p.loc.clone(),
                    format!("{what}: parameter \"{} {}\" is not used by Kiln and does not change its image; ignored", p.ty, p.name),
                ));
            } else {
                errors.push(Diagnostic {
                    severity: Severity::Error,
                    loc: p.loc.clone(),
                    message: format!(
                        "{what}: unknown or unsupported parameter \"{} {}\"",
                        p.ty, p.name
                    ),
                });
            }
        }
        for (loc, m) in warnings {
            self.warn(&loc, m);
        }
        match errors.len() {
            0 => Ok(()),
            1 => Err(SceneError::At {
                loc: errors[0].loc.clone(),
                message: errors[0].message.clone(),
            }),
            _ => Err(SceneError::Many(errors)),
        }
    }

    /// Resolves a file the scene refers to, and records it (a farm bundle must carry it).
    /// The path of a file the scene names at `loc`, recorded among the files it reads; an
    /// error if loading is confined and the path leaves the root.
    fn resolve_file(&mut self, name: &str, loc: &Loc) -> Result<PathBuf> {
        let path = self.resolve(name);
        if let Some(root) = &self.root
            && (Path::new(name).is_absolute() || !normalize(&path).starts_with(root))
        {
            return Err(SceneError::at(
                loc,
                format!(
                    "'{name}' is outside the scene's folder: a scene sent to a farm may name only files beside it"
                ),
            ));
        }
        if !self.files.contains(&path) {
            self.files.push(path.clone());
        }
        Ok(path)
    }

    /// `params` with every spectrum given as a file name (pbrt-v4's `"spectrum eta"
    /// "spds/Au.eta.spd"`: whitespace-separated wavelength and value pairs, `#` comments)
    /// replaced by the pairs the file holds.
    fn with_spectrum_files(&mut self, params: &ParamSet) -> Result<ParamSet> {
        use crate::files::spectrum_data::{carried_to_ends, named_spectrum_file, spd_values};
        let files = params.spectrum_files();
        let measured: Vec<_> = params
            .named_spectra()
            .into_iter()
            .filter_map(|(name, spectrum, loc)| {
                named_spectrum_file(&spectrum).map(|path| (name, path, loc))
            })
            .collect();
        if files.is_empty() && measured.is_empty() {
            return Ok(params.clone());
        }
        let mut out = params.clone();
        for (name, file, loc) in files {
            let path = self.resolve_file(&file, &loc)?;
            if !path.is_file() {
                return Err(SceneError::at(
                    &loc,
                    format!(
                        "spectrum '{file}' is neither a named spectrum (Kiln knows: {}) nor a spectrum file beside the scene",
                        crate::spectrum::named_spectrum_names().join(", ")
                    ),
                ));
            }
            let text = crate::files::read_text(&path, &loc)?;
            let values = spd_values(&text, &file, &loc)?;
            out.set_values(&name, crate::params::ParamValues::Numbers(values));
        }
        // A named spectrum the user measured (KILN_SPECTRUM_DATA) is read as its table.
        for (name, path, loc) in measured {
            let text = crate::files::read_text(&path, &loc)?;
            let values = spd_values(&text, &path.display().to_string(), &loc)?;
            out.set_values(
                &name,
                crate::params::ParamValues::Numbers(carried_to_ends(values)),
            );
        }
        Ok(out)
    }

    fn resolve(&self, name: &str) -> PathBuf {
        let p = Path::new(name);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    fn require_world(&self, loc: &Loc, what: &str) -> Result<()> {
        if !self.in_world {
            return Err(SceneError::at(
                loc,
                format!("{what} must come after WorldBegin"),
            ));
        }
        Ok(())
    }

    fn require_options(&self, loc: &Loc, what: &str) -> Result<()> {
        if self.in_world {
            return Err(SceneError::at(
                loc,
                format!("{what} must come before WorldBegin"),
            ));
        }
        Ok(())
    }

    fn parse_tokens(&mut self, tokens: &[Token], file: &Arc<PathBuf>, depth: u32) -> Result<()> {
        let mut c = Cursor {
            tokens,
            pos: 0,
            file,
        };
        while let Some(tok) = c.peek() {
            let loc = c.loc(tok.line);
            let TokenKind::Word(directive) = &tok.kind else {
                return Err(SceneError::at(
                    &loc,
                    format!("expected a directive, found {}", describe(&tok.kind)),
                ));
            };
            c.pos += 1;
            self.directive(directive, &mut c, &loc, depth)?;
        }
        Ok(())
    }

    /// Interprets one directive; `c` stands just after its name. Each family's file parses
    /// and applies its own directives; this table routes them.
    fn directive(&mut self, directive: &str, c: &mut Cursor, loc: &Loc, depth: u32) -> Result<()> {
        match directive {
            // The graphics state (state.rs).
            "Identity" => self.identity(),
            "Translate" => self.translate(c)?,
            "Scale" => self.scale(c)?,
            "Rotate" => self.rotate(c, loc)?,
            "LookAt" => self.look_at(c, loc)?,
            "Transform" | "ConcatTransform" => self.transform(directive, c)?,
            "CoordinateSystem" => self.coordinate_system(c)?,
            "CoordSysTransform" => self.coord_sys_transform(c, loc)?,
            "ActiveTransform" => self.active_transform(c, loc)?,
            "TransformTimes" => self.transform_times(c, loc)?,
            "ReverseOrientation" => self.reverse_orientation(),
            "AttributeBegin" | "TransformBegin" => self.attribute_begin(directive, loc),
            "AttributeEnd" | "TransformEnd" => self.attribute_end(directive, loc)?,
            "MediumInterface" => self.medium_interface(c, loc)?,
            "NamedMaterial" => self.named_material(c, loc)?,
            "ObjectBegin" => self.object_begin(c, loc)?,
            "ObjectEnd" => self.object_end(loc)?,
            "ObjectInstance" => self.object_instance(c, loc)?,
            // Rendering options, before WorldBegin (options.rs).
            "Option" => self.option(c, loc)?,
            "ColorSpace" => self.color_space(c, loc)?,
            "Camera" => {
                let ty = c.string(directive, "type")?;
                let params = c.params()?;
                self.camera(&ty, &params, loc)?;
            }
            "Film" => {
                let ty = c.string(directive, "type")?;
                let params = c.params()?;
                self.film(&ty, &params, loc)?;
            }
            "Sampler" => {
                let ty = c.string(directive, "type")?;
                let params = c.params()?;
                self.sampler(&ty, &params, loc)?;
            }
            "PixelFilter" => {
                let ty = c.string(directive, "type")?;
                let params = c.params()?;
                self.filter(&ty, &params, loc)?;
            }
            "Integrator" => {
                let ty = c.string(directive, "type")?;
                let params = c.params()?;
                self.integrator(&ty, &params, loc)?;
            }
            "Accelerator" => self.accelerator(c, loc)?,
            "WorldBegin" => self.world_begin(loc)?,
            "WorldEnd" => self.world_end(loc),
            // Scene entities (media.rs, materials.rs, lights.rs, shapes.rs).
            "MakeNamedMedium" => {
                let name = c.string(directive, "medium name")?;
                let params = self.with_attributes("medium", c.params()?);
                self.medium(name, &params, loc)?;
            }
            "Material" => {
                let ty = c.string(directive, "material type")?;
                let params = self.with_attributes("material", c.params()?);
                let id = self.material(&ty, &params, None, loc)?;
                self.gs.material = id;
            }
            "MakeNamedMaterial" => {
                let name = c.string(directive, "material name")?;
                let params = self.with_attributes("material", c.params()?);
                self.make_named_material(name, &params, loc)?;
            }
            "Texture" => {
                let name = c.string(directive, "texture name")?;
                let ty = c.string(directive, "texture type")?;
                let class = c.string(directive, "texture class")?;
                let params = self.with_attributes("texture", c.params()?);
                self.texture(name, &ty, &class, &params, loc)?;
            }
            "LightSource" => {
                let ty = c.string(directive, "light type")?;
                let params = self.with_attributes("light", c.params()?);
                self.light(&ty, &params, loc)?;
            }
            "AreaLightSource" => {
                let ty = c.string(directive, "area light type")?;
                let params = self.with_attributes("light", c.params()?);
                self.area_light(&ty, &params, loc)?;
            }
            "Shape" => {
                let ty = c.string(directive, "shape type")?;
                let params = self.with_attributes("shape", c.params()?);
                self.shape(&ty, &params, loc)?;
            }
            "Include" | "Import" => self.include(directive, c, loc, depth)?,
            "Attribute" => self.attribute(c, loc)?,
            other => {
                return Err(SceneError::at(loc, format!("unknown directive '{other}'")));
            }
        }
        Ok(())
    }

    /// `Include` and `Import`: reads another scene file here, with the current state.
    fn include(&mut self, directive: &str, c: &mut Cursor, loc: &Loc, depth: u32) -> Result<()> {
        let name = c.string(directive, "file name")?;
        if depth > 32 {
            return Err(SceneError::at(
                loc,
                "Include nested more than 32 deep (a cycle?)",
            ));
        }
        let path = self.resolve_file(&name, loc)?;
        let text = crate::files::read_text(&path, loc)?;
        let inner = Arc::new(path);
        let tokens = tokenize(&text, &inner)?;
        self.parse_tokens(&tokens, &inner, depth + 1)?;
        Ok(())
    }

    fn finish(mut self, file: &Arc<PathBuf>) -> Result<SceneDescription> {
        let end = Loc::new(file, 0);
        if let Some(i) = &self.integrator
            && matches!(i.kind, IntegratorKind::Path | IntegratorKind::Sppm)
            && !self.media.is_empty()
        {
            let loc = i.loc.clone();
            let name = i.name.clone();
            self.warn(
                &loc,
                format!("Integrator '{name}' ignores participating media, as pbrt-v4's does; 'volpath' renders them"),
            );
        }
        if let (Some(i), Some(s)) = (&self.integrator, &self.sampler)
            && i.kind == IntegratorKind::Sppm
            && s.noise_threshold.is_some()
        {
            let loc = s.loc.clone();
            self.warn(
                &loc,
                "Sampler: \"float noisethreshold\" does not apply to SPPM, whose pixels take every iteration (its photon radius shrinks over all of them together)",
            );
        }
        if let Some((_, loc, _)) = self.stack.last() {
            return Err(SceneError::at(
                loc,
                "this AttributeBegin (or ObjectBegin) is never closed",
            ));
        }
        if !self.in_world {
            return Err(SceneError::at(&end, "the scene has no WorldBegin"));
        }
        let camera = self.camera.unwrap_or_else(|| CameraDesc {
            projection: Projection::Perspective { fov_degrees: 90.0 },
            camera_to_world: DMat4::IDENTITY,
            camera_to_world_end: None,
            lens_radius: 0.0,
            focal_distance: 1e6,
            screen_window: None,
            shutter: [0.0, 1.0],
            loc: Loc::synthetic("default camera"),
        });
        let film = self.film.unwrap_or_else(|| FilmDesc {
            xresolution: 1280,
            yresolution: 720,
            filename: "kiln.exr".into(),
            pixel_bounds: [0, 1280, 0, 720],
            sensor: SensorDesc::default(),
            diagonal: 0.035,
            gbuffer: None,
            loc: Loc::synthetic("default film"),
        });
        let mut integrator = self.integrator.unwrap_or_else(|| IntegratorDesc {
            name: "volpath".into(),
            kind: IntegratorKind::VolPath,
            max_depth: 5,
            rr_depth: 5,
            rr_depth_given: false,
            pbrt_estimator: false,
            walk_depth: DEFAULT_WALK_DEPTH,
            strategy: LightStrategy::Mis,
            light_sampler: LightSamplerKind::Bvh,
            regularize: false,
            max_radiance: 0.0,
            photons: PhotonDesc::NONE,
            sppm_photons: None,
            sppm_radius: 1.0,
            loc: Loc::synthetic("default integrator"),
        });
        if film.sensor.max_component.is_finite() && !integrator.rr_depth_given {
            integrator.pbrt_estimator = true;
            integrator.rr_depth = 2;
        }
        Ok(SceneDescription {
            spectral: self.option_spectral,
            camera,
            film,
            sampler: {
                let mut s = self.sampler.unwrap_or_else(|| SamplerDesc {
                    name: "zsobol".into(),
                    pixel_samples: 16,
                    seed: 0,
                    noise_threshold: None,
                    min_samples: 256,
                    loc: Loc::synthetic("default sampler"),
                });
                if let Some(seed) = self.option_seed.filter(|_| !self.sampler_seed_given) {
                    s.seed = seed;
                }
                s
            },
            filter: self.filter.unwrap_or_else(|| FilterDesc {
                kind: FilterKind::Gaussian { sigma: 0.5 },
                radius: [1.5, 1.5],
                loc: Loc::synthetic("default filter"),
            }),
            integrator,
            materials: self.materials,
            float_textures: self.float_textures,
            spectrum_textures: self.spectrum_textures,
            media: self.media,
            camera_medium: self.camera_medium,
            shapes: self.shapes,
            lights: self.lights,
            objects: self.objects,
            instances: self.instances,
            transform_times: self.transform_times,
            files: self.files,
            warnings: self.warnings,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn load(text: &str) -> SceneDescription {
        load_str(text, Path::new("t.pbrt"), Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
    }

    pub(super) fn load_err(text: &str) -> String {
        load_str(text, Path::new("t.pbrt"), Path::new("."))
            .unwrap_err()
            .to_string()
    }

    /// Confined loading accepts any path that stays inside the root, `..` included, and
    /// refuses one that leaves it before opening it.
    /// A subsurface material on a closed mesh that faces inward (its interior would fill the
    /// space around it) is warned about, with the shape's line; facing out, reversed by
    /// ReverseOrientation, or turned out by its vertex normals, it is not.
    #[test]
    fn an_inward_subsurface_mesh_is_warned_about() {
        let cube = |indices: &str, extra: &str| {
            format!(
                "WorldBegin\nMaterial \"subsurface\"\n{extra}Shape \"trianglemesh\" \"point3 P\" [ 0 0 0  1 0 0  1 1 0  0 1 0  0 0 1  1 0 1  1 1 1  0 1 1 ] {indices}\n"
            )
        };
        let out = "\"integer indices\" [ 0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7 ]";
        let inward = "\"integer indices\" [ 0 1 2  0 2 3  4 6 5  4 7 6  0 5 1  0 4 5  1 6 2  1 5 6  2 7 3  2 6 7  3 4 0  3 7 4 ]";
        let warned = |text: String| {
            load(&text)
                .warnings
                .iter()
                .any(|w| w.message.contains("this mesh faces inward"))
        };
        assert!(!warned(cube(out, "")));
        assert!(warned(cube(inward, "")));
        let w = load(&cube(inward, "")).warnings;
        assert_eq!(w[0].loc.to_string(), "t.pbrt:3", "{w:?}");
        assert!(warned(cube(out, "ReverseOrientation\n")));
        assert!(!warned(cube(inward, "ReverseOrientation\n")));
        // Vertex normals pointing out from the cube's centre turn the inward winding out.
        let normals =
            "\"normal N\" [ -1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1 ] ";
        assert!(!warned(cube(&format!("{normals}{inward}"), "")));
        // Only subsurface materials care.
        assert!(!warned(
            cube(inward, "").replace("\"subsurface\"", "\"diffuse\"")
        ));
    }

    /// A bilinearmesh's planar quads become two triangles (split along p00-p11); a quad
    /// whose corners leave the plane stays a bilinear patch.
    #[test]
    fn planar_quads_are_triangles_and_saddles_patches() {
        let s = load(
            "WorldBegin\nShape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0  0 0 1  1 0 1  0 1 1  1 1 1.5 ] \"integer indices\" [ 0 1 2 3  4 5 6 7 ]",
        );
        let ShapeKind::Mesh(m) = &s.shapes[0].kind else {
            panic!("a mesh");
        };
        assert_eq!(m.indices, vec![0, 1, 3, 0, 3, 2]);
        assert_eq!(m.quads, vec![4, 5, 6, 7]);
        assert_eq!(m.triangulated_indices().len(), 12);
    }

    #[test]
    fn confined_loading_keeps_every_file_inside_its_root() {
        let root = std::env::temp_dir().join(format!("kiln-confined-{}", std::process::id()));
        std::fs::create_dir_all(root.join("models")).unwrap();
        std::fs::write(root.join("inner.pbrt"), "LightSource \"infinite\"\n").unwrap();
        let scene = root.join("scene.pbrt");
        let load = |include: &str| {
            std::fs::write(&scene, format!("WorldBegin\nInclude \"{include}\"\n")).unwrap();
            load_file_within(&scene, &root)
        };
        assert!(load("inner.pbrt").is_ok());
        assert!(load("models/../inner.pbrt").is_ok());
        for outside in ["../inner.pbrt", "/etc/hostname", "models/../../inner.pbrt"] {
            let e = load(outside).unwrap_err().to_string();
            assert!(
                e.contains(":2: '") && e.contains("outside the scene's folder"),
                "{e}"
            );
        }
        // Unconfined loading (kiln render on a user's own file) still reads them.
        assert!(load_file(&scene).is_err_and(|e| !e.to_string().contains("outside")));
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn diagnostics_name_file_and_line() {
        assert!(
            load_err("WorldBegin\n\nShape \"sphere\" \"float radius\" [ 1 2 ]")
                .starts_with("t.pbrt:3:")
        );
        assert!(load_err("WorldBegin\nAttributeBegin\n").contains("t.pbrt:2: this AttributeBegin"));
        assert!(load_err("Shape \"sphere\"").contains("must come after WorldBegin"));
        assert!(
            load_err("WorldBegin\nNamedMaterial \"nope\"")
                .contains("t.pbrt:2: NamedMaterial: no material named 'nope'")
        );
        assert!(
            load_err("WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"metal-Xx-eta\"")
                .contains("spectrum 'metal-Xx-eta' is neither a named spectrum")
        );
        assert!(
            load_err("Film \"rgb\" \"integer xresolution\" [ 1.5 ]\nWorldBegin")
                .contains("t.pbrt:1:")
        );
        assert!(load_err("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ] \"integer indices\" [ 0 1 3 ]").contains("index 3 is out of range"));
    }
}
