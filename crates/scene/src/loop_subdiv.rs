//! pbrt-v4's `loopsubdiv` shape: Loop subdivision of a triangle mesh, `levels` times, with
//! the vertices then moved to their limit positions and given the limit surface's normals.
//! pbrt-v4 turns the shape into a triangle mesh this way too.
//!
//! Each level rebuilds the edge adjacency: an edge with one face is a boundary. Even
//! (existing) vertices move by the one-ring mask (β = 3/16 for valence 3, else 3/(8n)) or,
//! on the boundary, by (1/8, 3/4, 1/8) along it; odd (edge) vertices are 3/8 of the edge's
//! ends plus 1/8 of the two opposite corners, or the midpoint on the boundary.

use crate::mesh::TriangleMeshData;
use std::collections::HashMap;

/// The most triangles a subdivision may make (16.8 million).
pub const MAX_SUBDIVIDED_TRIANGLES: usize = 1 << 24;

type P = [f64; 3];

fn add(a: P, b: P) -> P {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: P, s: f64) -> P {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn cross(a: P, b: P) -> P {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn beta(valence: usize) -> f64 {
    if valence == 3 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * valence as f64)
    }
}

/// The adjacency of one level.
struct Topology {
    /// Per edge (low, high vertex): the corners opposite it, one per face (1: boundary).
    edges: HashMap<(u32, u32), Vec<u32>>,
    /// Per vertex, its neighbours in order around it (for a boundary vertex, from one
    /// boundary neighbour to the other), and whether it is on the boundary.
    rings: Vec<(Vec<u32>, bool)>,
}

fn topology(n_vertices: usize, tris: &[[u32; 3]]) -> Result<Topology, String> {
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    // Per vertex: for each incident face, (next, previous) around the face.
    let mut fans: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n_vertices];
    for t in tris {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(c);
            fans[a as usize].push((b, c));
        }
    }
    if let Some(((a, b), f)) = edges.iter().find(|(_, f)| f.len() > 2) {
        return Err(format!(
            "the edge between vertices {a} and {b} is shared by {} faces (Loop subdivision needs a manifold mesh)",
            f.len()
        ));
    }
    let rings = fans
        .into_iter()
        .map(|mut fan| {
            if fan.is_empty() {
                return (Vec::new(), false);
            }
            // Chain the faces around the vertex: face (next, prev) is followed by the face
            // whose next is this prev. A boundary vertex's chain starts at a `next` that no
            // face has as its `prev`. Sorted lookups keep a vertex of huge valence (a fan of
            // a million triangles in a file) at n log n.
            fan.sort_unstable();
            let mut prevs: Vec<u32> = fan.iter().map(|f| f.1).collect();
            prevs.sort_unstable();
            let by_next = |n: u32| fan.binary_search_by_key(&n, |f| f.0).ok();
            let start = fan
                .iter()
                .position(|&(n, _)| prevs.binary_search(&n).is_err());
            let boundary = start.is_some();
            let start = start.unwrap_or(0);
            let mut ring = vec![fan[start].0];
            let mut cur = start;
            for _ in 0..fan.len() {
                let prev = fan[cur].1;
                match by_next(prev) {
                    Some(next) if next != start => {
                        ring.push(prev);
                        cur = next;
                    }
                    _ => {
                        if boundary {
                            ring.push(prev);
                        }
                        break;
                    }
                }
            }
            (ring, boundary)
        })
        .collect();
    Ok(Topology { edges, rings })
}

/// Subdivides the triangles `indices` over `positions` `levels` times: the limit positions,
/// the limit normals (oriented as the faces around each vertex) and the triangles.
pub fn loop_subdivide(
    positions: &[[f32; 3]],
    indices: &[u32],
    levels: u32,
) -> Result<TriangleMeshData, String> {
    let mut p: Vec<P> = positions.iter().map(|v| v.map(f64::from)).collect();
    let mut tris: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    if (tris.len() as u128) << (2 * levels.min(32)) > MAX_SUBDIVIDED_TRIANGLES as u128 {
        return Err(format!(
            "{levels} levels of subdivision of {} triangles would make more than {MAX_SUBDIVIDED_TRIANGLES}",
            tris.len()
        ));
    }
    for _ in 0..levels {
        let topo = topology(p.len(), &tris)?;
        // Even vertices.
        let mut next: Vec<P> = topo
            .rings
            .iter()
            .enumerate()
            .map(|(v, (ring, boundary))| {
                let here = p[v];
                if ring.is_empty() {
                    here
                } else if *boundary {
                    let ends = add(p[ring[0] as usize], p[*ring.last().unwrap() as usize]);
                    add(scale(here, 0.75), scale(ends, 0.125))
                } else {
                    let b = beta(ring.len());
                    let sum = ring.iter().fold([0.0; 3], |s, &r| add(s, p[r as usize]));
                    add(scale(here, 1.0 - ring.len() as f64 * b), scale(sum, b))
                }
            })
            .collect();
        // Odd vertices, one per edge.
        let mut edge_vertex: HashMap<(u32, u32), u32> = HashMap::with_capacity(topo.edges.len());
        let mut keys: Vec<&(u32, u32)> = topo.edges.keys().collect();
        keys.sort_unstable();
        for &(a, b) in keys {
            let opposite = &topo.edges[&(a, b)];
            let ends = add(p[a as usize], p[b as usize]);
            let v = if opposite.len() == 2 {
                add(
                    scale(ends, 3.0 / 8.0),
                    scale(
                        add(p[opposite[0] as usize], p[opposite[1] as usize]),
                        1.0 / 8.0,
                    ),
                )
            } else {
                scale(ends, 0.5)
            };
            edge_vertex.insert((a, b), next.len() as u32);
            next.push(v);
        }
        let mid = |a: u32, b: u32| edge_vertex[&(a.min(b), a.max(b))];
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
        p = next;
    }
    // Limit positions and normals.
    let topo = topology(p.len(), &tris)?;
    let mut face_normal = vec![[0.0; 3]; p.len()];
    for t in &tris {
        let n = cross(
            sub(p[t[1] as usize], p[t[0] as usize]),
            sub(p[t[2] as usize], p[t[0] as usize]),
        );
        for &v in t {
            face_normal[v as usize] = add(face_normal[v as usize], n);
        }
    }
    let mut limit = Vec::with_capacity(p.len());
    let mut normals = Vec::with_capacity(p.len());
    for (v, (ring, boundary)) in topo.rings.iter().enumerate() {
        let here = p[v];
        let n = ring.len();
        let r = |k: usize| p[ring[k] as usize];
        if n == 0 {
            limit.push(here);
            normals.push([0.0; 3]);
            continue;
        }
        let (pos, s, t) = if *boundary {
            let ends = add(r(0), r(n - 1));
            let pos = add(scale(here, 0.6), scale(ends, 0.2));
            let s = sub(r(n - 1), r(0));
            let t = match n {
                2 => sub(add(r(0), r(1)), scale(here, 2.0)),
                3 => sub(r(1), here),
                4 => add(
                    add(scale(r(0), -1.0), scale(r(1), 2.0)),
                    add(scale(r(2), 2.0), add(scale(r(3), -1.0), scale(here, -2.0))),
                ),
                _ => {
                    let theta = std::f64::consts::PI / (n - 1) as f64;
                    let mut t = scale(add(r(0), r(n - 1)), libm::sin(theta));
                    for k in 1..n - 1 {
                        let w = (2.0 * libm::cos(theta) - 2.0) * libm::sin(k as f64 * theta);
                        t = add(t, scale(r(k), w));
                    }
                    scale(t, -1.0)
                }
            };
            (pos, s, t)
        } else {
            let gamma = 1.0 / (n as f64 + 3.0 / (8.0 * beta(n)));
            let sum = ring.iter().fold([0.0; 3], |s, &k| add(s, p[k as usize]));
            let pos = add(scale(here, 1.0 - n as f64 * gamma), scale(sum, gamma));
            let (mut s, mut t) = ([0.0; 3], [0.0; 3]);
            for k in 0..n {
                let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
                s = add(s, scale(r(k), libm::cos(a)));
                t = add(t, scale(r(k), libm::sin(a)));
            }
            (pos, s, t)
        };
        let mut nn = cross(s, t);
        // The ring's direction decides the sign; the faces around the vertex decide it here.
        if dot(nn, face_normal[v]) < 0.0 {
            nn = scale(nn, -1.0);
        }
        let len = dot(nn, nn).sqrt();
        limit.push(pos);
        normals.push(if len > 0.0 {
            scale(nn, 1.0 / len)
        } else {
            [0.0; 3]
        });
    }
    let to32 = |v: &P| v.map(|c| c as f32);
    Ok(TriangleMeshData {
        positions: limit.iter().map(to32).collect(),
        normals: Some(normals.iter().map(to32).collect()),
        uvs: None,
        indices: tris.iter().flatten().copied().collect(),
        quads: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular octahedron: closed, every vertex of valence 4.
    fn octahedron() -> (Vec<[f32; 3]>, Vec<u32>) {
        let p = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let i = vec![
            0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5,
        ];
        (p, i)
    }

    #[test]
    fn a_closed_mesh_stays_closed_smooth_and_symmetric() {
        let (p, i) = octahedron();
        let m = loop_subdivide(&p, &i, 3).unwrap();
        let (q, n, t) = (m.positions, m.normals.unwrap(), m.indices);
        assert_eq!(t.len() / 3, 8 * 64);
        // Closed: every edge has two faces.
        let topo = topology(
            q.len(),
            &t.chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect::<Vec<_>>(),
        )
        .unwrap();
        assert!(topo.edges.values().all(|f| f.len() == 2));
        // The limit of an original vertex is known in closed form: (1 − nγ)v + γΣ ring with
        // γ = 1/8 for valence 4, so (1, 0, 0) goes to (0.5, 0, 0). The surface is a rounded
        // octahedron: between its faces' centres (r ≈ 0.42) and its vertices (0.5), its
        // normals pointing outwards.
        assert!(
            q.iter()
                .any(|v| (v[0] - 0.5).abs() < 1e-6 && v[1] == 0.0 && v[2] == 0.0)
        );
        for (v, nv) in q.iter().zip(&n) {
            let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!(r > 0.4 && r < 0.501, "{v:?} at {r}");
            let radial = (v[0] * nv[0] + v[1] * nv[1] + v[2] * nv[2]) / r;
            assert!(radial > 0.9, "{v:?} {nv:?}");
        }
    }

    #[test]
    fn a_flat_patch_stays_flat_and_keeps_its_boundary_corners() {
        // Two triangles of the unit square in z = 0, boundary everywhere.
        let p = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let i = vec![0, 1, 2, 0, 2, 3];
        let m = loop_subdivide(&p, &i, 2).unwrap();
        let (q, n, t) = (m.positions, m.normals.unwrap(), m.indices);
        assert_eq!(t.len() / 3, 32);
        assert!(q.iter().all(|v| v[2] == 0.0));
        assert!(n.iter().all(|v| (v[2] - 1.0).abs() < 1e-6), "{n:?}");
        // Everything stays inside the square.
        assert!(
            q.iter()
                .all(|v| (0.0..=1.0).contains(&v[0]) && (0.0..=1.0).contains(&v[1]))
        );
    }

    #[test]
    fn non_manifold_and_huge_subdivisions_are_errors() {
        let p = vec![
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let fin = vec![0, 1, 2, 1, 0, 3, 0, 1, 4];
        assert!(
            loop_subdivide(&p, &fin, 1)
                .unwrap_err()
                .contains("shared by 3 faces")
        );
        let (p, i) = octahedron();
        assert!(
            loop_subdivide(&p, &i, 12)
                .unwrap_err()
                .contains("more than")
        );
    }
}
