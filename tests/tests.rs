//! Kiln's integration tests: they run the `kiln` binary as a user would.

mod util;

mod analytic;
mod architecture;
mod cli;
mod dashboard;
mod denoise;
mod determinism;
mod errors;
mod estimators;
mod farm;
mod gbuffer;
mod media;
mod motion;
mod nested;
mod passes;
mod photons;
mod reference;
mod revolution;
mod sensor;
mod shapes;
mod spectral;
mod subsurface;
mod textures;
mod volume_light;
mod wavefront;
