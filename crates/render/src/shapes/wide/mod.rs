//! Kiln's own wide BVH over every primitive of a scene: eight children per node with their
//! boxes stored axis by axis (one AVX2 operation, or two SSE ones, tests eight boxes), and
//! leaves either of packs of four triangles tested at once ([`tri4`]) or of other
//! primitives (spheres, quadrics, curves, moving groups), which the walks hand to the
//! caller one by one. One walk finds the closest hit of every kind.
//!
//! It is collapsed from a binary build (Kiln's binned SAH, [`sah`], or the median split of
//! [`super::bvh_build`] where that is too deep): each node takes its binary node's two
//! children, then opens the largest internal one among them until it holds eight. Eight measured 1.17x the closest hits per second of four on the snail's
//! rays, and one tree serves every kernel.
//!
//! Bit for bit: every kernel is one IEEE operation per lane in a fixed order
//! ([`crate::simd`]), a triangle's distance is obvhs's scalar test's to the bit, and where two triangles lie at
//! exactly the closest distance the one the scene declared first wins, so the hit found is
//! a function of the ray and the triangles alone, not of the tree or the order of the walk.

pub mod sah;
#[cfg(test)]
mod tests;
mod tri4;
mod walk;

use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::rt_triangle::RtTriangle;
use tri4::Tri4;

/// A child that is a leaf: its count less one in bits 27-29 and its first below: packs of
/// triangles, or with [`OTHERS`] set, entries of [`WideBvh::others`].
const LEAF: u32 = 1 << 31;
const OTHERS: u32 = 1 << 30;
const LEAF_FIRST: u32 = (1 << 27) - 1;
const LEAF_COUNT: u32 = 8;
/// A slot with no child (its box is empty, so no ray enters it).
const EMPTY: u32 = u32::MAX;

/// The stack the walks keep: a node pushes at most its WIDTH children and pops itself, so a
/// tree of depth d needs at most (WIDTH - 1)d + 1 entries. A deeper tree is built again by median
/// split ([`WideBvh::new`]).
pub(super) const STACK: usize = 256;

/// Children per node: a multiple of four (the lanes of one box test).
pub(super) const WIDTH: usize = 8;

/// A node: its children's boxes, plane by plane (`planes[axis][child]` the low planes,
/// `planes[3 + axis][child]` the high ones, each row 32-byte aligned), and what each child
/// is (a node's index, a leaf, or [`EMPTY`]).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node {
    planes: [[f32; WIDTH]; 6],
    child: [u32; WIDTH],
}

/// Which instructions walk the BVH. Every kernel finds the same hit to the bit (the same
/// operation on every lane, in the same order); they differ only in speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kernel {
    /// Four lanes at a time: SSE2 on x86-64 (every such CPU has it), plain arrays elsewhere.
    Sse,
    /// A node's eight boxes at once, and a leaf's two packs.
    Avx2,
    /// The AVX2 kernel compiled for AVX-512 (F and VL): the same eight-lane operations, with
    /// twice the vector registers to keep the ray in.
    Avx512,
}

impl Kernel {
    /// The fastest kernel this CPU runs, unless `KILN_BVH_KERNEL` (`sse`, `avx2` or
    /// `avx512`) names a slower one (for tests that compare them, and to rule one out).
    pub fn choose() -> Kernel {
        let best = Kernel::detect();
        let asked = match std::env::var("KILN_BVH_KERNEL").as_deref() {
            Ok("sse") => Kernel::Sse,
            Ok("avx2") => Kernel::Avx2,
            Ok("avx512") => Kernel::Avx512,
            _ => best,
        };
        asked.min(best)
    }

    /// The name `KILN_BVH_KERNEL` takes for this kernel.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Sse => "sse",
            Kernel::Avx2 => "avx2",
            Kernel::Avx512 => "avx512",
        }
    }

    /// The fastest kernel this CPU runs.
    pub fn detect() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx2") && has!("avx512f") && has!("avx512vl") {
                return Kernel::Avx512;
            }
            if has!("avx2") {
                return Kernel::Avx2;
            }
        }
        Kernel::Sse
    }

    /// Every kernel this CPU runs.
    pub fn available() -> Vec<Kernel> {
        [Kernel::Sse, Kernel::Avx2, Kernel::Avx512]
            .into_iter()
            .filter(|&k| k <= Kernel::detect())
            .collect()
    }
}

/// A binary BVH to collapse: obvhs's node layout (a leaf has primitives, an inner node's
/// children are `first_index` and the next), and the primitives its leaves index.
pub struct Binary<'a> {
    pub nodes: &'a [Bvh2Node],
    pub prims: &'a [u32],
}

impl<'a> From<&'a Bvh2> for Binary<'a> {
    fn from(b: &'a Bvh2) -> Binary<'a> {
        Binary {
            nodes: &b.nodes,
            prims: &b.primitive_indices,
        }
    }
}

/// The wide BVH over a scene's triangles and other primitives.
#[derive(Clone)]
pub struct WideBvh {
    nodes: Vec<Node>,
    packs: Vec<Tri4>,
    /// The other primitives' leaves: their ids (at least the triangle count).
    others: Vec<u32>,
    /// Node levels from the root to the deepest leaf.
    depth: usize,
    kernel: Kernel,
}

impl WideBvh {
    /// The BVH over `tris` (`tris[i]` is the triangle the scene declared `i`th) and other
    /// primitives (ids from `tris.len()` on), collapsed from `bvh2`, whose leaves never mix
    /// the two. `None` where the tree is too deep for the walks' stack.
    pub fn collapse(bvh2: &Binary, tris: &[RtTriangle]) -> Option<WideBvh> {
        let mut b = WideBvh {
            nodes: Vec::new(),
            packs: Vec::new(),
            others: Vec::new(),
            depth: 0,
            kernel: Kernel::choose(),
        };
        if bvh2.nodes.is_empty() || bvh2.prims.is_empty() {
            return None;
        }
        let root = &bvh2.nodes[0];
        if root.prim_count > 0 {
            // One leaf: a root holding it alone.
            b.nodes.push(Node::empty());
            let leaf = b.leaf(bvh2, 0, tris)?;
            b.nodes[0].set(0, root.aabb.min, root.aabb.max, leaf);
            b.depth = 1;
            return Some(b);
        }
        b.nodes.push(Node::empty());
        // (bvh2 node, its Node, the Node's depth)
        let mut todo = vec![(0usize, 0usize, 1usize)];
        while let Some((n2, n4, depth)) = todo.pop() {
            b.depth = b.depth.max(depth);
            if (WIDTH - 1) * b.depth + 1 > STACK {
                return None;
            }
            for (slot, &c) in open(bvh2, n2).iter().enumerate() {
                let node = &bvh2.nodes[c];
                let code = if node.prim_count > 0 {
                    b.leaf(bvh2, c, tris)?
                } else {
                    b.nodes.push(Node::empty());
                    let i = b.nodes.len() - 1;
                    todo.push((c, i, depth + 1));
                    i as u32
                };
                b.nodes[n4].set(slot, node.aabb.min, node.aabb.max, code);
            }
        }
        Some(b)
    }

    /// Binary leaf `n2` as a child code: its triangles' packs, or its other primitives.
    fn leaf(&mut self, bvh2: &Binary, n2: usize, tris: &[RtTriangle]) -> Option<u32> {
        let node = &bvh2.nodes[n2];
        let first = node.first_index as usize;
        let ids = &bvh2.prims[first..first + node.prim_count as usize];
        let is_triangle = |i: &u32| (*i as usize) < tris.len();
        if !ids.iter().all(is_triangle) {
            assert!(
                !ids.iter().any(is_triangle),
                "a leaf mixes triangles and others"
            );
            let start = self.others.len();
            self.others.extend_from_slice(ids);
            let count = ids.len() as u32;
            return (start < LEAF_FIRST as usize && count <= LEAF_COUNT)
                .then(|| LEAF | OTHERS | ((count - 1) << 27) | start as u32);
        }
        let start = self.packs.len();
        for chunk in ids.chunks(4) {
            let lanes: Vec<(RtTriangle, u32)> =
                chunk.iter().map(|&i| (tris[i as usize], i)).collect();
            self.packs.push(Tri4::pack(&lanes));
        }
        let count = (self.packs.len() - start) as u32;
        (start < LEAF_FIRST as usize && count <= LEAF_COUNT)
            .then(|| LEAF | ((count - 1) << 27) | start as u32)
    }

    /// Bytes held, for the memory a triangle costs.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
            + self.packs.len() * std::mem::size_of::<Tri4>()
            + self.others.len() * std::mem::size_of::<u32>()
    }

    /// Nodes, packs, and the lanes of the packs that hold a triangle.
    pub fn counts(&self) -> (usize, usize, usize) {
        let lanes = self
            .packs
            .iter()
            .map(|p| p.id.iter().filter(|&&i| i != u32::MAX).count())
            .sum();
        (self.nodes.len(), self.packs.len(), lanes)
    }

    /// The same BVH walked by `kernel`, which must be one of [`Kernel::available`].
    pub fn with_kernel(mut self, kernel: Kernel) -> WideBvh {
        assert!(
            Kernel::available().contains(&kernel),
            "{kernel:?} is not available here"
        );
        self.kernel = kernel;
        self
    }

    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Node levels from the root to the deepest leaf.
    pub fn depth(&self) -> usize {
        self.depth
    }
}

/// Binary node `n2`'s descendants a wide node takes: its two children, then, while fewer
/// than eight, the internal one of largest surface opened into its two (the first of
/// equals, so the tree is the same everywhere); largest first.
fn open(bvh2: &Binary, n2: usize) -> Vec<usize> {
    let first = bvh2.nodes[n2].first_index as usize;
    let mut kids = vec![first, first + 1];
    while kids.len() < WIDTH {
        let mut widest: Option<(usize, f32)> = None;
        for (i, &k) in kids.iter().enumerate() {
            let node = &bvh2.nodes[k];
            let area = node.aabb.half_area();
            if node.prim_count == 0 && widest.is_none_or(|(_, a)| area > a) {
                widest = Some((i, area));
            }
        }
        let Some((i, _)) = widest else {
            break;
        };
        let f = bvh2.nodes[kids[i]].first_index as usize;
        kids.splice(i..=i, [f, f + 1]);
    }
    // Largest first: the any-hit walk takes children in slot order, and a larger box is
    // likelier to hold what stops a shadow ray (1.8x the any hits per second of the binary
    // order on the snail's rays). Ties keep the binary order.
    let area = |k: &usize| bvh2.nodes[*k].aabb.half_area();
    kids.sort_by(|a, b| area(b).total_cmp(&area(a)));
    kids
}

impl Node {
    fn empty() -> Node {
        Node {
            planes: std::array::from_fn(|row| {
                [if row < 3 {
                    f32::INFINITY
                } else {
                    f32::NEG_INFINITY
                }; WIDTH]
            }),
            child: [EMPTY; WIDTH],
        }
    }

    fn set(&mut self, slot: usize, lo: glam::Vec3A, hi: glam::Vec3A, code: u32) {
        for a in 0..3 {
            self.planes[a][slot] = lo[a];
            self.planes[3 + a][slot] = hi[a];
        }
        self.child[slot] = code;
    }
}
