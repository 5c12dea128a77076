//! Triangle meshes as a scene describes them, in object space: what the parser makes of an
//! inline `trianglemesh`, what PLY and OBJ files and loop subdivision give.

/// Triangle mesh data in object space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMeshData {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Three per triangle.
    pub indices: Vec<u32>,
    /// pbrt-v4's bilinear patches whose corners are not in one plane: four per patch, in
    /// its corner order p00, p10, p01, p11 (planar quads are two triangles in `indices`).
    pub quads: Vec<u32>,
}

/// How far, relative to its size, a quad's corners may stray from one plane and still be
/// two triangles (exported meshes round their planar quads' corners).
pub const PLANAR_QUAD_TOLERANCE: f64 = 1e-4;

impl TriangleMeshData {
    /// Every face as triangles: the mesh's own, then each bilinear patch as two (split
    /// along p00-p11), for what works on triangles only (displacement).
    pub fn triangulated_indices(&self) -> Vec<u32> {
        let mut all = self.indices.clone();
        for q in self.quads.chunks_exact(4) {
            all.extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
        }
        all
    }

    /// The mesh with `quads` (four indices each, p00 p10 p01 p11) added: planar ones as two
    /// triangles split along p00-p11, the others as bilinear patches.
    pub fn with_quads(mut self, quads: &[u32]) -> TriangleMeshData {
        let at = |i: u32| self.positions[i as usize].map(f64::from);
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let mut kept = Vec::new();
        for q in quads.chunks_exact(4) {
            let [p00, p10, p01, p11] = [at(q[0]), at(q[1]), at(q[2]), at(q[3])];
            let a = cross(sub(p10, p00), sub(p01, p00));
            let b = cross(sub(p11, p10), sub(p11, p01));
            let n = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
            let len = dot(n, n).sqrt();
            let size = dot(sub(p11, p00), sub(p11, p00))
                .max(dot(sub(p10, p01), sub(p10, p01)))
                .sqrt();
            let planar = len == 0.0
                || size == 0.0
                || [p10, p01, p11]
                    .iter()
                    .all(|p| (dot(sub(*p, p00), n) / len).abs() <= PLANAR_QUAD_TOLERANCE * size);
            if planar {
                self.indices
                    .extend_from_slice(&[q[0], q[1], q[3], q[0], q[3], q[2]]);
            } else {
                kept.extend_from_slice(q);
            }
        }
        self.quads.extend(kept);
        self
    }

    /// Whether the mesh clearly faces inward: the volume its faces enclose, oriented as
    /// pbrt-v4 orients them (by their winding, or by the vertex normals where the mesh has
    /// them, which the geometric normals then follow), is negative and at least a quarter of
    /// the unsigned volume its faces sweep from the mesh's centre. A closed mesh facing out
    /// encloses a positive volume; an open sheet rarely passes the quarter. Bilinear patches
    /// count as their two triangles.
    pub fn faces_inward(&self) -> bool {
        let at = |i: u32| glam::DVec3::from(self.positions[i as usize].map(f64::from));
        let (mut lo, mut hi) = (glam::DVec3::INFINITY, glam::DVec3::NEG_INFINITY);
        for p in &self.positions {
            let p = glam::DVec3::from(p.map(f64::from));
            (lo, hi) = (lo.min(p), hi.max(p));
        }
        let centre = (lo + hi) / 2.0;
        let (mut signed, mut swept, mut agreement) = (0.0, 0.0, 0.0);
        for t in self.triangulated_indices().chunks_exact(3) {
            let [a, b, c] = [at(t[0]) - centre, at(t[1]) - centre, at(t[2]) - centre];
            let v = a.dot(b.cross(c));
            signed += v;
            swept += v.abs();
            if let Some(n) = &self.normals {
                let n = t
                    .iter()
                    .map(|&i| glam::DVec3::from(n[i as usize].map(f64::from)))
                    .sum::<glam::DVec3>();
                agreement += (b - a).cross(c - a).dot(n);
            }
        }
        if agreement < 0.0 {
            signed = -signed;
        }
        signed < 0.0 && -signed >= 0.25 * swept
    }
}
