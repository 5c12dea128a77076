//! Kiln's renderer: a path tracer over a [`Scene`] built from a
//! [`kiln_scene::SceneDescription`], and [`render_tile`], the pure function
//! from (scene, settings, tile) to pixels that both `kiln render` and the
//! farm's workers call.
//!
//! This crate knows nothing about files, HTTP, serde or async runtimes: it
//! takes a description in memory and returns pixels in memory.
//!
//! ```
//! use kiln_render::{Integrator, PathSettings, RenderSettings, Scene, TileRect, render_tile};
//! let text = r#"
//!     Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
//!     Camera "perspective" "float fov" [ 60 ]
//!     WorldBegin
//!     LightSource "infinite" "rgb L" [ 1 1 1 ]
//! "#;
//! let desc = kiln_scene::load_str(text, "doc.pbrt".as_ref(), ".".as_ref()).unwrap();
//! let scene = Scene::build(&desc).unwrap();
//! let settings = RenderSettings {
//!     samples_per_pixel: 4,
//!     seed: 0,
//!     integrator: Integrator::Path(PathSettings { max_depth: 5, rr_depth: 5, strategy: desc.integrator.strategy, max_radiance: 0.0 }),
//!     max_radiance: 0.0,
//! };
//! let tile = render_tile(&scene, &settings, TileRect { x0: 0, y0: 0, width: 8, height: 8 });
//! // An empty scene under a uniform sky of radiance 1 is 1 everywhere.
//! assert!(tile.pixels.iter().all(|p| p.iter().all(|&c| (c - 1.0).abs() < 1e-6)));
//! ```

pub mod bsdf;
pub mod camera;
pub mod geometry;
pub mod integrator;
pub mod lights;
pub mod materials;
pub mod math;
pub mod media;
pub mod photons;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod tile;
pub mod volume;

pub use integrator::{Integrator, PathSettings};
pub use scene::{BuildError, Scene};
pub use tile::{
    NonFiniteSample, RenderSettings, TileRect, TileResult, TileStats, render_pixel, render_tile,
    split_into_tiles,
};

impl RenderSettings {
    /// Settings as the scene file gives them.
    pub fn from_description(desc: &kiln_scene::SceneDescription) -> RenderSettings {
        let i = &desc.integrator;
        RenderSettings {
            samples_per_pixel: desc.sampler.pixel_samples,
            seed: desc.sampler.seed,
            integrator: Integrator::Path(PathSettings {
                max_depth: i.max_depth,
                rr_depth: i.rr_depth,
                strategy: i.strategy,
                max_radiance: i.max_radiance,
            }),
            max_radiance: i.max_radiance,
        }
    }
}
