//! Kiln's scene front end: reads pbrt-v4 scene files (and the PLY, OBJ and EXR
//! files they refer to) into a plain, validated [`SceneDescription`].
//!
//! This crate knows nothing about rendering. Every error names the file and
//! line it comes from; parameters Kiln does not understand are diagnostics,
//! never silently ignored.
//!
//! ```
//! use std::path::Path;
//! let text = r#"
//!     Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 32 ]
//!     Camera "perspective" "float fov" [ 45 ]
//!     WorldBegin
//!     LightSource "point" "rgb I" [ 1 1 1 ]
//!     Shape "sphere" "float radius" [ 2 ]
//! "#;
//! let scene = kiln_scene::load_str(text, Path::new("example.pbrt"), Path::new(".")).unwrap();
//! assert_eq!(scene.film.xresolution, 64);
//! assert_eq!(scene.shapes.len(), 1);
//!
//! let bad = kiln_scene::load_str("WorldBegin\nMaterial \"velvet\"", Path::new("bad.pbrt"), Path::new("."));
//! assert!(bad.unwrap_err().to_string().starts_with("bad.pbrt:2:"));
//! ```

pub mod camera_sensor;
pub mod colorspace;
pub mod description;
pub mod error;
pub mod files;
mod lexer;
pub mod loop_subdiv;
pub mod measured_media;
pub mod mesh;
mod params;
mod parser;
pub mod photometry;
mod rgb_spectrum;
pub mod sigmoid_table;
pub mod spectrum;
pub mod textures;
pub mod voxel_grid;

pub use description::*;
pub use error::{Diagnostic, Loc, SceneError, Severity};
pub use files::mesh_cache::MeshCache;
pub use parser::{load_file, load_file_within, load_file_within_sharing, load_str};
pub use textures::*;
