//! Kiln's renderer: a path tracer over a [`Scene`] built from a
//! [`kiln_scene::SceneDescription`], and [`render_tile`], the pure function
//! from (scene, settings, tile) to pixels that both `kiln render` and the
//! farm's workers call.
//!
//! This crate knows nothing about files, HTTP, serde or async runtimes: it
//! takes a description in memory and returns pixels in memory.
//!
//! ```
//! use kiln_render::{Renderer, TileRect, render_tile};
//! let text = r#"
//!     Option "kiln.spectral" false
//!     Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
//!     Sampler "sobol" "integer pixelsamples" [ 4 ]
//!     Camera "perspective" "float fov" [ 60 ]
//!     WorldBegin
//!     LightSource "infinite" "rgb L" [ 1 1 1 ]
//! "#;
//! let desc = kiln_scene::load_str(text, "doc.pbrt".as_ref(), ".".as_ref()).unwrap();
//! let renderer = Renderer::build(&desc).unwrap();
//! let tile = render_tile(&renderer, TileRect { x0: 0, y0: 0, width: 8, height: 8 });
//! // An empty scene under a uniform sky of radiance 1 is 1 everywhere (in RGB exactly; a
//! // spectral render's four wavelengths per sample only estimate the white).
//! assert!(tile.pixels.iter().all(|p| p.iter().all(|&c| (c - 1.0).abs() < 1e-6)));
//! ```
//!
//! The modules, one concept each (ARCHITECTURE.md draws the map): [`shapes`] (geometry and
//! its BVHs), [`lights`], [`materials`] and the [`bsdfs`] they make, [`textures`], [`media`], [`nesting`] (nested
//! dielectrics by priority), [`integrators`] (path tracing, photon maps), [`sampling`], [`camera`] and [`filter`], [`scene`] (the
//! built scene) and [`tile`] (the tile function).

pub mod adaptive;
pub mod bsdfs;
pub mod camera;
pub mod features;
pub mod film;
pub mod filter;
pub mod gbuffer;
pub mod integrators;
pub mod lens;
pub mod lights;
pub mod materials;
pub mod math;
pub mod media;
pub mod motion;
pub mod nesting;
pub mod phase;
pub mod rect;
pub mod sampling;
pub mod scene;
pub mod sensor;
pub mod shapes;
pub mod shared;
pub(crate) mod simd;
pub mod spectral;
pub mod sums;
pub mod textures;
pub mod tile;
pub mod work;

pub use adaptive::Adaptive;
pub use integrators::{Integrator, PathSettings};
pub use rect::{TileRect, split_into_tiles};
pub use scene::{BuildError, MediaPolicy, Scene};
pub use sums::{SumsError, SumsLayout, TileSums};
pub use tile::{
    PassError, RenderSettings, Renderer, SampleId, TileResult, TileStats, aov_names,
    progress_units, render_pixel, render_tile, render_tile_pass, render_tile_until, render_tiles,
    texture_footprint,
};
