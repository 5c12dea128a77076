//! pbrt-v4's plymesh displacement: the mesh is refined until every edge is shorter than
//! `edgelength` in world space (splitting each triangle's longest edge at its midpoint, a
//! split shared by the triangles on both sides), each vertex moves along its normal by the
//! displacement texture evaluated at its object-space position and uv, and the normals are
//! recomputed from the displaced faces.

use crate::textures::{FloatTexture, TextureEvalContext};
use glam::{DMat4, Vec2, Vec3, Vec3A};
use kiln_scene::TriangleMeshData;
use std::collections::HashMap;

/// The most triangles a displaced mesh may have (16.8 million, about 1.3 GB of geometry): a
/// tiny `edgelength` would otherwise refine without end.
pub const MAX_DISPLACED_TRIANGLES: usize = 1 << 24;

/// Refines and displaces `mesh` (in object space; `to_world` measures its edges).
pub fn displace(
    mesh: &TriangleMeshData,
    to_world: DMat4,
    edge_length: f32,
    texture: &FloatTexture,
) -> Result<TriangleMeshData, String> {
    let Some(uvs) = &mesh.uvs else {
        return Err(
            "displacement needs per-vertex uv coordinates in the mesh (pbrt-v4 requires them too)"
                .into(),
        );
    };
    // Displacement refines triangles: bilinear patches are split into two first.
    let triangles = mesh.triangulated_indices();
    let mut p: Vec<Vec3> = mesh.positions.iter().map(|v| Vec3::from(*v)).collect();
    let mut uv: Vec<Vec2> = uvs.iter().map(|v| Vec2::from(*v)).collect();
    let mut n: Vec<Vec3> = match &mesh.normals {
        Some(n) => n.iter().map(|v| Vec3::from(*v)).collect(),
        None => vertex_normals(&p, &triangles),
    };
    let world = |v: Vec3| to_world.transform_point3(v.as_dvec3());
    let distance = |a: Vec3, b: Vec3| (world(a) - world(b)).length();
    let max = f64::from(edge_length);
    // Before any work: a triangle whose edges are all shorter than L has an area under
    // √3/4·L², so the refined mesh has at least area / (√3/4·L²) triangles.
    let area: f64 = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| world(p[i as usize]));
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    let at_least = area / (3f64.sqrt() / 4.0 * max * max);
    // (NaN, from a non-finite vertex, is refused too.)
    if at_least.is_nan() || at_least >= MAX_DISPLACED_TRIANGLES as f64 {
        return Err(format!(
            "refining its {area:.3e} square units to edges shorter than {edge_length} would make more than {MAX_DISPLACED_TRIANGLES} triangles; raise \"edgelength\""
        ));
    }
    let mut split: HashMap<(u32, u32), u32> = HashMap::new();
    let mut indices: Vec<u32> = Vec::with_capacity(triangles.len());
    let mut stack: Vec<[u32; 3]> = Vec::new();
    for t in triangles.chunks_exact(3) {
        stack.push([t[0], t[1], t[2]]);
        while let Some([v0, v1, v2]) = stack.pop() {
            let (a, b, c) = (p[v0 as usize], p[v1 as usize], p[v2 as usize]);
            let (d01, d12, d20) = (distance(a, b), distance(b, c), distance(c, a));
            if !(d01.is_finite() && d12.is_finite() && d20.is_finite()) {
                return Err("a vertex of the mesh is not finite in world space".into());
            }
            if d01 < max && d12 < max && d20 < max {
                indices.extend([v0, v1, v2]);
                continue;
            }
            if indices.len() / 3 + stack.len() + 1 >= MAX_DISPLACED_TRIANGLES {
                return Err(format!(
                    "refining it to edges shorter than {edge_length} would make more than {MAX_DISPLACED_TRIANGLES} triangles; raise \"edgelength\""
                ));
            }
            // The first two vertices bound the longest edge.
            let v = if d01 > d12 {
                if d01 > d20 {
                    [v0, v1, v2]
                } else {
                    [v2, v0, v1]
                }
            } else if d12 > d20 {
                [v1, v2, v0]
            } else {
                [v2, v0, v1]
            };
            let edge = (v[0].min(v[1]), v[0].max(v[1]));
            let mid = *split.entry(edge).or_insert_with(|| {
                let (i, j) = (v[0] as usize, v[1] as usize);
                p.push((p[i] + p[j]) * 0.5);
                n.push((n[i] + n[j]).normalize_or_zero());
                uv.push((uv[i] + uv[j]) * 0.5);
                (p.len() - 1) as u32
            });
            // Processed in pbrt-v4's order: the half at v[0] first.
            stack.push([mid, v[1], v[2]]);
            stack.push([v[0], mid, v[2]]);
        }
    }
    for ((p, n), uv) in p.iter_mut().zip(&n).zip(&uv) {
        let ctx = TextureEvalContext {
            p: Vec3A::from(*p),
            uv: *uv,
            ..Default::default()
        };
        *p += texture.evaluate(&ctx) * *n;
    }
    let n = vertex_normals(&p, &indices);
    Ok(TriangleMeshData {
        positions: p.iter().map(|v| v.to_array()).collect(),
        normals: Some(n.iter().map(|v| v.to_array()).collect()),
        uvs: Some(uv.iter().map(|v| v.to_array()).collect()),
        indices,
        quads: Vec::new(),
    })
}

/// Vertex normals as pbrt-v4 computes them: the sum of the unit normals of the faces around
/// each vertex, normalised (zero where no face has an area).
fn vertex_normals(p: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        let face = (p[b] - p[a]).cross(p[c] - p[b]).normalize_or_zero();
        n[a] += face;
        n[b] += face;
        n[c] += face;
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::textures::Texture;

    fn quad() -> TriangleMeshData {
        TriangleMeshData {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            normals: None,
            uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
            indices: vec![0, 1, 2, 0, 2, 3],
            quads: Vec::new(),
        }
    }

    #[test]
    fn refines_to_the_edge_length_and_moves_along_the_normal() {
        let out = displace(&quad(), DMat4::IDENTITY, 0.3, &Texture::Constant(0.25)).unwrap();
        let p: Vec<Vec3> = out.positions.iter().map(|v| Vec3::from(*v)).collect();
        for t in out.indices.chunks_exact(3) {
            for k in 0..3 {
                let (a, b) = (p[t[k] as usize], p[t[(k + 1) % 3] as usize]);
                assert!((a - b).length() < 0.3, "edge {a} {b}");
            }
        }
        // Every vertex moved by 0.25 along +z; the area is still 1, and no vertex is
        // duplicated along shared edges (the mesh stays watertight).
        assert!(p.iter().all(|v| (v.z - 0.25).abs() < 1e-6));
        let area: f32 = out
            .indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| p[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        assert!((area - 1.0).abs() < 1e-5, "{area}");
        let mut unique: Vec<[i64; 2]> = p
            .iter()
            .map(|v| [(v.x * 1e5).round() as i64, (v.y * 1e5).round() as i64])
            .collect();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), p.len());
        // A scale makes edges longer in world space: more triangles.
        let scaled = displace(
            &quad(),
            DMat4::from_scale(glam::DVec3::splat(2.0)),
            0.3,
            &Texture::Constant(0.0),
        )
        .unwrap();
        assert!(scaled.indices.len() > out.indices.len());
    }

    #[test]
    fn a_tiny_edge_length_or_a_mesh_without_uvs_is_an_error() {
        let err = displace(&quad(), DMat4::IDENTITY, 1e-6, &Texture::Constant(0.0)).unwrap_err();
        assert!(err.contains("raise \"edgelength\""), "{err}");
        let mut no_uv = quad();
        no_uv.uvs = None;
        assert!(
            displace(&no_uv, DMat4::IDENTITY, 0.3, &Texture::Constant(0.0))
                .unwrap_err()
                .contains("uv")
        );
    }
}
