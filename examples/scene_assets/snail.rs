//! The headline frame's glass snail (seed 000): one gather of glass drawn out into a coiled
//! shell, a body with its foot flat on the bench, a raised head and its feelers.
//!
//! The snail is a signed distance field: a logarithmic helico-spiral tube whose whorls overlap
//! and fuse, a chain of ellipsoids for the body, capsules for the feelers, joined by smooth
//! unions so that no seam is left. Marching tetrahedra over a grid turn the field's zero set
//! into one closed surface: every edge is shared by exactly two triangles, wound oppositely,
//! facing out. Shading normals are the field's gradient. The emission grid that makes the
//! glass hotter at its foot and where it is thick comes from the same field.

use crate::vec3::{cross, len, sub};
use std::collections::HashMap;
use std::f32::consts::PI;
use std::io::Write;
use std::path::Path;

/// What a reader may change: the shell's coil, the body's size, and how finely the surface
/// is meshed.
#[derive(Clone, Copy, Debug)]
pub struct SnailParams {
    /// Turns of the shell's coil.
    pub turns: f32,
    /// How much the coil's tube grows over all its turns.
    pub growth: f32,
    /// The tube's radius as a fraction of the coil's size where it is: above ~0.17 the
    /// whorls overlap and fuse.
    pub tube: f32,
    /// How far (world units) the smooth unions blend.
    pub blend: f32,
    /// The body's length along x.
    pub length: f32,
    /// Grid step of the mesher (world units): smaller gives more triangles.
    pub step: f32,
}

impl Default for SnailParams {
    fn default() -> Self {
        SnailParams {
            turns: 3.0,
            growth: 6.0,
            tube: 0.235,
            blend: 0.06,
            length: 3.0,
            step: 0.0275,
        }
    }
}

/// Smooth minimum (polynomial, blending over `k`); either may be infinite.
fn smin(a: f32, b: f32, k: f32) -> f32 {
    if (a - b).abs() >= k {
        return a.min(b);
    }
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Distance to an ellipsoid of radii `r` centred at `c` (Quilez's bound, exact on the axes).
fn ellipsoid(p: [f32; 3], c: [f32; 3], r: [f32; 3]) -> f32 {
    let q = sub(p, c);
    let k0 = len([q[0] / r[0], q[1] / r[1], q[2] / r[2]]);
    let k1 = len([
        q[0] / (r[0] * r[0]),
        q[1] / (r[1] * r[1]),
        q[2] / (r[2] * r[2]),
    ]);
    if k1 == 0.0 {
        -r[0].min(r[1]).min(r[2])
    } else {
        k0 * (k0 - 1.0) / k1
    }
}

/// Distance to a capsule from `a` (radius `ra`) to `b` (radius `rb`).
fn capsule(p: [f32; 3], a: [f32; 3], b: [f32; 3], ra: f32, rb: f32) -> f32 {
    let (pa, ba) = (sub(p, a), sub(b, a));
    let h = ((pa[0] * ba[0] + pa[1] * ba[1] + pa[2] * ba[2])
        / (ba[0] * ba[0] + ba[1] * ba[1] + ba[2] * ba[2]))
        .clamp(0.0, 1.0);
    len(sub(pa, [ba[0] * h, ba[1] * h, ba[2] * h])) - (ra + (rb - ra) * h)
}

/// The snail's field: negative inside the glass.
pub struct Snail {
    pub params: SnailParams,
    /// The coil's growth rate per radian.
    rate: f32,
    t_max: f32,
    /// The coil's turn about its axis.
    phase: f32,
    /// The coil's placement: rotated about x by `tilt`, then moved by `offset`.
    tilt: (f32, f32),
    offset: [f32; 3],
    body: Vec<([f32; 3], [f32; 3])>,
    feelers: Vec<([f32; 3], [f32; 3], f32, f32)>,
}

impl Snail {
    pub fn new(params: SnailParams) -> Snail {
        let t_max = 2.0 * PI * params.turns;
        let rate = libm::logf(params.growth) / t_max;
        let mut snail = Snail {
            params,
            rate,
            t_max,
            // The aperture straight down once tilted: at angle pi/2 in the coil's plane.
            phase: (PI / 2.0 - t_max).rem_euclid(2.0 * PI),
            tilt: libm::sincosf(1.15f32),
            offset: [0.0; 3],
            body: Vec::new(),
            feelers: Vec::new(),
        };
        // The body: ellipsoids along the foot from tail (u 0) to head (u 1), flattened
        // underneath, the head end rising.
        let l = params.length;
        let n = 36;
        for i in 0..=n {
            let u = i as f32 / n as f32;
            let x = -0.52 * l + l * u;
            let swell = libm::powf(libm::sinf(PI * u).max(0.0), 0.55);
            let w = 0.07 + 0.27 * swell * (1.0 - 0.25 * u);
            let h = 0.06 + 0.2 * swell;
            let rise = 0.42 * libm::powf((u - 0.68).max(0.0) / 0.32, 1.4);
            snail
                .body
                .push(([x, h * 0.75 + rise, 0.0], [1.3 * l / n as f32, h, w]));
        }
        // The head: the front ellipsoid, raised; feelers out of its top and front.
        let head = [0.47 * l, 0.5, 0.0];
        snail.body.push((head, [0.2, 0.17, 0.19]));
        for side in [-1.0f32, 1.0] {
            snail.feelers.push((
                [head[0] + 0.02, head[1] + 0.08, 0.07 * side],
                [head[0] + 0.28, head[1] + 0.6, 0.24 * side],
                0.05,
                0.028,
            ));
            snail.feelers.push((
                [head[0] + 0.1, head[1] - 0.06, 0.08 * side],
                [head[0] + 0.36, head[1] - 0.2, 0.2 * side],
                0.04,
                0.022,
            ));
        }
        // The shell sits on the body's back, behind its middle, its lowest point sunk into it.
        let low = (0..2000)
            .map(|i| {
                let t = snail.t_max * i as f32 / 1999.0;
                let c = snail.coil_centre(t);
                let r = snail.tube_radius(t);
                let (s, co) = snail.tilt;
                c[1] * co - c[2] * s - r
            })
            .fold(f32::INFINITY, f32::min);
        snail.offset = [-0.1 * l, 0.24 - low, -0.02];
        snail
    }

    fn size(&self, t: f32) -> f32 {
        0.22 * libm::expf(self.rate * t)
    }

    /// The coil's centre line in its own frame (axis along y), turned so that its widest
    /// end, the aperture, comes down into the body.
    fn coil_centre(&self, t: f32) -> [f32; 3] {
        let s = self.size(t);
        let a = t + self.phase;
        [0.5 * s * libm::cosf(a), -0.42 * s, 0.5 * s * libm::sinf(a)]
    }

    fn tube_radius(&self, t: f32) -> f32 {
        self.params.tube * self.size(t)
    }

    /// Distance to the shell: the coiled tube, its whorls fused by smooth unions.
    pub fn shell(&self, p: [f32; 3]) -> f32 {
        // Into the coil's frame.
        let q = sub(p, self.offset);
        let (s, c) = self.tilt;
        let q = [q[0], q[1] * c + q[2] * s, -q[1] * s + q[2] * c];
        let tube = |t: f32| {
            let t = t.clamp(0.0, self.t_max);
            len(sub(q, self.coil_centre(t))) - self.tube_radius(t)
        };
        // The distance along the whole centre line, sampled finely: each local minimum is
        // the nearest point of one whorl, refined by a golden-section search between its
        // neighbouring samples; the whorls are then joined by a smooth union.
        let step = 0.04f32;
        let n = (self.t_max / step).ceil() as usize;
        let f: Vec<f32> = (0..=n).map(|i| tube(i as f32 * step)).collect();
        let mut d = f32::INFINITY;
        for i in 0..=n {
            let left = if i > 0 { f[i - 1] } else { f32::INFINITY };
            let right = if i < n { f[i + 1] } else { f32::INFINITY };
            if f[i] > left || f[i] > right {
                continue;
            }
            let (mut a, mut b) = ((i as f32 - 1.0) * step, (i as f32 + 1.0) * step);
            let g = 0.618_034f32;
            let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
            let (mut f1, mut f2) = (tube(x1), tube(x2));
            for _ in 0..8 {
                if f1 < f2 {
                    b = x2;
                    (x2, f2) = (x1, f1);
                    x1 = b - g * (b - a);
                    f1 = tube(x1);
                } else {
                    a = x1;
                    (x1, f1) = (x2, f2);
                    x2 = a + g * (b - a);
                    f2 = tube(x2);
                }
            }
            d = smin(d, f1.min(f2).min(f[i]), self.params.blend);
        }
        d
    }

    pub fn body(&self, p: [f32; 3]) -> f32 {
        let k = self.params.blend;
        let mut d = f32::INFINITY;
        for (c, r) in &self.body {
            d = smin(d, ellipsoid(p, *c, *r), 1.5 * k);
        }
        for (a, b, ra, rb) in &self.feelers {
            d = smin(d, capsule(p, *a, *b, *ra, *rb), 0.6 * k);
        }
        // Eye bulbs at the upper feelers' tips.
        for (_, b, _, rb) in self.feelers.iter().step_by(2) {
            d = smin(d, len(sub(p, *b)) - 1.6 * rb, 0.3 * k);
        }
        d
    }

    /// The field: negative inside. The foot is cut flat just above the bench (y = 0), its
    /// edge rounded.
    pub fn distance(&self, p: [f32; 3]) -> f32 {
        let d = smin(self.shell(p), self.body(p), 3.5 * self.params.blend);
        -smin(-d, p[1] - 0.004, 0.5 * self.params.blend)
    }

    /// The gradient of the field, normalised (the outward normal on the surface).
    pub fn normal(&self, p: [f32; 3]) -> [f32; 3] {
        let e = 0.25 * self.params.step;
        let g = [0, 1, 2].map(|i| {
            let (mut a, mut b) = (p, p);
            a[i] += e;
            b[i] -= e;
            self.distance(a) - self.distance(b)
        });
        let l = len(g);
        if l > 0.0 {
            g.map(|c| c / l)
        } else {
            [0.0, 1.0, 0.0]
        }
    }

    /// The box the snail lies in, with a margin of two grid steps.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let l = self.params.length;
        let m = 2.0 * self.params.step;
        let shell_r = self.size(self.t_max) * (0.5 + self.params.tube) + 0.05;
        let lo = [
            (-0.55 * l).min(self.offset[0] - shell_r) - m,
            -m,
            -shell_r.max(0.45) - m,
        ];
        let hi = [
            0.47 * l + 0.5 + m,
            (self.offset[1] + 0.8 * shell_r + shell_r).max(1.3) + m,
            shell_r.max(0.45) + m,
        ];
        (lo, hi)
    }

    /// How hot the glass is at `p` (a factor on the emission): hottest at the foot and where
    /// the glass is thick, cooling up the shell towards its apex and at thin edges.
    pub fn heat(&self, p: [f32; 3]) -> f32 {
        let depth = (-self.distance(p)).max(0.0);
        let thick = (0.35 + depth / 0.12).min(1.6);
        let foot = 1.0 + 2.2 * libm::expf(-p[1] / 0.3);
        // Up the shell, the glass has cooled most towards the apex (which sits high).
        let height = (p[1] / 1.6).clamp(0.0, 1.0);
        let cool = 1.0 - 0.7 * height;
        thick * foot * cool
    }
}

/// A closed triangle mesh with a normal at every vertex.
pub struct IsoMesh {
    pub v: Vec<[f32; 3]>,
    pub n: Vec<[f32; 3]>,
    pub f: Vec<[u32; 3]>,
}

/// The six tetrahedra of a grid cube (corners numbered x + 2y + 4z) around its diagonal
/// 0-7, each listed so that its orientation is positive. Neighbouring cubes cut their shared
/// faces along the same diagonal, so together they tile the grid.
fn cube_tetrahedra() -> Vec<[usize; 4]> {
    let corner = |i: usize| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32];
    let mut tets = Vec::new();
    for order in [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ] {
        let a = 0usize;
        let b = a | (1 << order[0]);
        let c = b | (1 << order[1]);
        let d = 7usize;
        let [pa, pb, pc, pd] = [a, b, c, d].map(corner);
        let (u, v, w) = (sub(pb, pa), sub(pc, pa), sub(pd, pa));
        let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0]);
        tets.push(if det > 0.0 {
            [a, b, c, d]
        } else {
            [a, c, b, d]
        });
    }
    tets
}

/// Whether the permutation `p` of 0..4 is even.
fn even(p: [usize; 4]) -> bool {
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            if p[i] > p[j] {
                inversions += 1;
            }
        }
    }
    inversions % 2 == 0
}

/// The zero set of `snail`'s field by marching tetrahedra on a grid of its step.
pub fn mesh(snail: &Snail) -> IsoMesh {
    let (lo, hi) = snail.bounds();
    let h = snail.params.step;
    let dims = [0, 1, 2].map(|i| ((hi[i] - lo[i]) / h).ceil() as usize + 1);
    let at = |i: usize, j: usize, k: usize| {
        [
            lo[0] + i as f32 * h,
            lo[1] + j as f32 * h,
            lo[2] + k as f32 * h,
        ]
    };
    let index = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
    // The field at every grid point (zero counts as outside, so no vertex sits on a point).
    let values: Vec<f32> = (0..dims[2])
        .flat_map(|k| (0..dims[1]).flat_map(move |j| (0..dims[0]).map(move |i| (i, j, k))))
        .map(|(i, j, k)| snail.distance(at(i, j, k)))
        .collect();
    let tets = cube_tetrahedra();
    let mut mesh = IsoMesh {
        v: Vec::new(),
        n: Vec::new(),
        f: Vec::new(),
    };
    let mut on_edge: HashMap<(usize, usize), u32> = HashMap::new();
    let point = |g: usize| {
        let i = g % dims[0];
        let j = (g / dims[0]) % dims[1];
        let k = g / (dims[0] * dims[1]);
        at(i, j, k)
    };
    let mut vertex = |a: usize, b: usize, mesh: &mut IsoMesh| -> u32 {
        let key = (a.min(b), a.max(b));
        *on_edge.entry(key).or_insert_with(|| {
            let (va, vb) = (values[key.0], values[key.1]);
            let t = (va / (va - vb)).clamp(0.0, 1.0);
            let (pa, pb) = (point(key.0), point(key.1));
            let p = [0, 1, 2].map(|c| pa[c] + (pb[c] - pa[c]) * t);
            mesh.v.push(p);
            mesh.n.push(snail.normal(p));
            (mesh.v.len() - 1) as u32
        })
    };
    for k in 0..dims[2] - 1 {
        for j in 0..dims[1] - 1 {
            for i in 0..dims[0] - 1 {
                let corners: [usize; 8] = std::array::from_fn(|c| {
                    index(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))
                });
                let inside = corners.map(|g| values[g] < 0.0);
                if inside.iter().all(|&x| x) || inside.iter().all(|&x| !x) {
                    continue;
                }
                for tet in &tets {
                    let g = tet.map(|c| corners[c]);
                    let ins: Vec<usize> = (0..4).filter(|&v| values[g[v]] < 0.0).collect();
                    let outs: Vec<usize> = (0..4).filter(|&v| values[g[v]] >= 0.0).collect();
                    match ins.len() {
                        1 | 3 => {
                            // One vertex apart: cut off its corner, facing away from the
                            // inside. Order the tetrahedron (evenly) with that vertex first.
                            let lone = if ins.len() == 1 { ins[0] } else { outs[0] };
                            let rest: Vec<usize> = (0..4).filter(|&v| v != lone).collect();
                            let mut p = [lone, rest[0], rest[1], rest[2]];
                            if !even(p) {
                                p.swap(2, 3);
                            }
                            let e = [1, 2, 3].map(|m| vertex(g[p[0]], g[p[m]], &mut mesh));
                            // Wound (e1, e2, e3) the triangle faces away from the lone vertex.
                            mesh.f.push(if ins.len() == 1 {
                                e
                            } else {
                                [e[0], e[2], e[1]]
                            });
                        }
                        2 => {
                            let mut p = [ins[0], ins[1], outs[0], outs[1]];
                            if !even(p) {
                                p.swap(2, 3);
                            }
                            let [a, b, c, d] = p.map(|v| g[v]);
                            let (ac, ad, bd, bc) = (
                                vertex(a, c, &mut mesh),
                                vertex(a, d, &mut mesh),
                                vertex(b, d, &mut mesh),
                                vertex(b, c, &mut mesh),
                            );
                            mesh.f.push([ac, ad, bd]);
                            mesh.f.push([ac, bd, bc]);
                        }
                        _ => {}
                    }
                }
            }
        }
    }
    mesh.settle_normals();
    mesh
}

impl IsoMesh {
    /// Where the field's gradient disagrees with the surface around a vertex (at a crease the
    /// smooth unions leave, central differences straddle it), the vertex takes the
    /// area-weighted normal of its faces instead, so that every face's normals agree with
    /// its winding (pbrt-v4 turns a face's geometric normal to its vertex normals).
    fn settle_normals(&mut self) {
        let mut around = vec![[0.0f32; 3]; self.v.len()];
        for t in &self.f {
            let [a, b, c] = t.map(|i| self.v[i as usize]);
            let n = cross(sub(a, c), sub(b, c));
            for &i in t {
                for k in 0..3 {
                    around[i as usize][k] += n[k];
                }
            }
        }
        let unit = |v: [f32; 3]| {
            let l = len(v);
            if l > 0.0 { v.map(|c| c / l) } else { v }
        };
        for (n, a) in self.n.iter_mut().zip(&around) {
            let a = unit(*a);
            if n[0] * a[0] + n[1] * a[1] + n[2] * a[2] < 0.5 {
                *n = a;
            }
        }
        // A face still at odds with its vertices' normals gives them its own.
        for _ in 0..4 {
            let mut changed = false;
            for t in &self.f {
                let [a, b, c] = t.map(|i| self.v[i as usize]);
                let face = cross(sub(a, c), sub(b, c));
                let sum = t.iter().fold([0.0f32; 3], |s, &i| {
                    let n = self.n[i as usize];
                    [s[0] + n[0], s[1] + n[1], s[2] + n[2]]
                });
                if face[0] * sum[0] + face[1] * sum[1] + face[2] * sum[2] <= 0.0 {
                    for &i in t {
                        let n = &mut self.n[i as usize];
                        *n = unit([0, 1, 2].map(|k| n[k] + 2.0 * unit(face)[k]));
                    }
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
    }

    pub fn write_ply(&self, path: &Path) {
        let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        write!(
            out,
            "ply\nformat binary_little_endian 1.0\ncomment made by examples/scene_assets\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.v.len(),
            self.f.len()
        )
        .unwrap();
        for (p, n) in self.v.iter().zip(&self.n) {
            for c in p.iter().chain(n) {
                out.write_all(&c.to_le_bytes()).unwrap();
            }
        }
        for t in &self.f {
            out.write_all(&[3]).unwrap();
            for i in t {
                out.write_all(&(*i as i32).to_le_bytes()).unwrap();
            }
        }
        println!("wrote {} ({} triangles)", path.display(), self.f.len());
    }
}

/// The emission grid over the mesh's bounding box, as Kiln's VolumeLight reads it: the
/// counts, then x fastest, then y, then z.
pub fn heat_grid(snail: &Snail, mesh: &IsoMesh, counts: [usize; 3]) -> String {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.v {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let mut out = format!(
        "# The glass's heat over the snail's bounding box ({} x {} x {}, x fastest, then y, then\n# z), written by examples/scene_assets: hottest at the foot and where the glass is\n# thick, cooling up the shell towards its apex and at thin edges.\n{}, {}, {}\n",
        counts[0], counts[1], counts[2], counts[0], counts[1], counts[2]
    );
    for k in 0..counts[2] {
        for j in 0..counts[1] {
            let row: Vec<String> = (0..counts[0])
                .map(|i| {
                    // Voxel centres, as Kiln's grid (pbrt-v4's SampledGrid) places them.
                    let f = |n: usize, c: usize| {
                        lo[c] + (hi[c] - lo[c]) * (n as f32 + 0.5) / counts[c] as f32
                    };
                    let p = [f(i, 0), f(j, 1), f(k, 2)];
                    format!("{:.3}", snail.heat(p))
                })
                .collect();
            out.push_str(&row.join(", "));
            out.push('\n');
        }
    }
    out
}
