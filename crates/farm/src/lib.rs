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
pub mod worker;

/// A rendered tile as an image of a `frame`-sized frame, with the further channels (a
/// G-buffer's) its settings asked for: what a worker uploads and `kiln render` pastes.
pub fn tile_image(
    result: kiln_render::TileResult,
    frame: (u32, u32),
    settings: &kiln_render::RenderSettings,
) -> kiln_image::RgbBuffer {
    let r = result.rect;
    let mut b = kiln_image::RgbBuffer::new(frame.0, frame.1, r.x0, r.y0, r.width, r.height);
    b.pixels = result.pixels;
    b.aovs = kiln_image::Aovs {
        names: kiln_render::aov_names(settings.gbuffer),
        values: result.aovs,
    };
    b
}
