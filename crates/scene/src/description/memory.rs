//! How much memory a worker needs to render a scene, estimated from its description when a
//! farm plans a job, so that the job goes only to workers that have it.
//!
//! An estimate, not an account: what a built scene holds per triangle (its records, the
//! wide BVH and the triangles' packs, a light and its share of the light hierarchy for an
//! emitting one), per vertex, per texel of an image (RGB in f32 and its MIP levels), per
//! byte of a grid file, per photon, and the process itself. The figures per item were
//! measured on Kiln's scenes (2026-11-29): the molten-glass snail (124,298 emitting
//! triangles) peaked at 66 MiB where this says 82 MiB, the furnace at 8.6 MiB where this
//! says 16; it errs high, so a worker it clears has the memory.

use super::{SceneDescription, ShapeDesc, ShapeKind};

/// The process, its tables and threads, before any of the scene.
const BASE: u64 = 16 << 20;
/// A triangle's record, BVH share and pack; and a light's more for an emitting one.
const PER_TRIANGLE: u64 = 256;
const PER_EMITTING_TRIANGLE: u64 = 256;
const PER_VERTEX: u64 = 32;
/// A curve segment: its control points, widths and the BVH's pieces.
const PER_CURVE_SEGMENT: u64 = 256;
/// An image texel as RGB f32 with its MIP levels (4/3).
const PER_TEXEL: u64 = 16;
/// A photon in a map, with its share of the map's tree.
const PER_PHOTON: u64 = 48;
/// An instance: its transform and its entry in the top-level hierarchy.
const PER_INSTANCE: u64 = 256;

impl SceneDescription {
    /// The bytes a worker is estimated to need to render this scene (see the module).
    pub fn memory_estimate(&self) -> u64 {
        let shapes = self
            .shapes
            .iter()
            .chain(self.objects.iter().flat_map(|o| &o.shapes));
        let mut bytes = BASE + shapes.map(shape_bytes).sum::<u64>();
        bytes += self.instances.len() as u64 * PER_INSTANCE;
        bytes += self.files.iter().map(|f| file_bytes(f)).sum::<u64>();
        let p = &self.integrator.photons;
        let sppm = self.integrator.sppm_photons.unwrap_or(0);
        bytes += (p.caustic_photons + p.volume_photons + sppm) * PER_PHOTON;
        bytes
    }
}

fn shape_bytes(shape: &ShapeDesc) -> u64 {
    match &shape.kind {
        ShapeKind::Mesh(mesh) => {
            let triangles = (mesh.indices.len() / 3 + mesh.quads.len() / 2) as u64;
            let per = PER_TRIANGLE
                + if shape.area_light.is_some() {
                    PER_EMITTING_TRIANGLE
                } else {
                    0
                };
            triangles * per + mesh.positions.len() as u64 * PER_VERTEX
        }
        ShapeKind::Curve(c) => {
            (c.segments.len() as u64 * PER_CURVE_SEGMENT) << c.split_depth.min(8)
        }
        _ => PER_TRIANGLE,
    }
}

/// What a file the scene read adds: an image's texels, a grid's values (about its size on
/// disk, as f32); meshes and scene files are counted by their shapes.
fn file_bytes(path: &std::path::Path) -> u64 {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "png" | "jpg" | "jpeg" | "tga" | "bmp" | "hdr" | "qoi" => image::image_dimensions(path)
            .map(|(w, h)| u64::from(w) * u64::from(h) * PER_TEXEL)
            // Unreadable here (the build will say why): a guess from its size.
            .unwrap_or_else(|_| size_of(path) * 8),
        // EXR, PFM: at most 32-bit channels, a few of them.
        "exr" | "pfm" => size_of(path) * 2,
        "vol" | "nvdb" | "csv" | "bin" => size_of(path) * 2,
        _ => 0,
    }
}

fn size_of(path: &std::path::Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

#[cfg(test)]
mod tests {
    use crate::load_file;
    use std::path::Path;

    fn estimate(scene: &str) -> u64 {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        load_file(&root.join(scene)).unwrap().memory_estimate()
    }

    /// The headline's snail (124,298 emitting triangles, 66 MiB at its peak) needs several
    /// times the furnace (a sphere), and no less than it was measured to take.
    #[test]
    fn the_estimate_grows_with_the_geometry_and_errs_high() {
        let (snail, furnace) = (
            estimate("molten-glass/scene.pbrt"),
            estimate("furnace/scene.pbrt"),
        );
        assert!(snail >= 66 << 20, "{} MiB", snail >> 20);
        assert!(snail < 160 << 20, "{} MiB", snail >> 20);
        assert!(
            (8 << 20..24 << 20).contains(&furnace),
            "{} MiB",
            furnace >> 20
        );
        // A grid file counts: the fire's two 400 KB grids.
        assert!(estimate("fire/scene.pbrt") >= (16 << 20) + 1_600_000);
    }
}
