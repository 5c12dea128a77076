//! Kiln's render farm: a coordinator that keeps jobs durable and lends tiles to workers
//! under leases, the workers that render them through `kiln_render::render_tile`, and the
//! client calls that submit scenes and follow them.
//!
//! The merged image is bit-identical to `kiln render`'s because every tile is the same
//! pure function of (scene, settings, tile), whoever renders it and however often.

pub mod api;
pub mod bundle;
pub mod client;
pub mod coordinator;
pub mod trust;
pub mod worker;
