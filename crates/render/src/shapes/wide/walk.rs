//! Walking the wide BVH: the closest hit (children nearest first, the nearest taken at once
//! and the others stacked, a child whose entry is beyond the closest hit so far left
//! unopened) and any hit (shadow rays and transmittance: children largest first, out at the
//! first opaque hit). Triangles are tested here; other primitives by the caller's function,
//! and of hits at the same distance the smallest id wins whatever its kind.
//!
//! The box test is the slab test with the far distances widened by 1 + 2γ₃ (as pbrt does,
//! so rounding never loses a box a ray grazes), and a NaN (a ray in a slab's plane, parallel
//! to it) leaves that axis out rather than the box.

use super::tri4::{Ray4, Tri4};
use super::{EMPTY, Kernel, LEAF, LEAF_FIRST, Node, OTHERS, STACK, WIDTH, WideBvh};
#[cfg(target_arch = "x86_64")]
use crate::simd::F8;
use crate::simd::{F4, Mask};
use glam::Vec3A;

/// How far past the closest hit so far a box is still opened: a triangle's distance and
/// its box's entry are rounded differently (by a few ulps, more at grazing angles), so a
/// triangle a hair nearer than the hit may lie in a box whose computed entry is a hair
/// beyond it. Opening boxes up to 1/4096 beyond costs next to nothing and finds it.
const REACH: f32 = 1.0 + 1.0 / 4096.0;

/// pbrt's 1 + 2γ₃: how far a box's far distance is pushed out against rounding.
const WIDEN: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// A ray as the box test takes it.
pub(super) struct BoxRay {
    ray: Ray4,
    o: [f32; 3],
    dir: [f32; 3],
    inv: [f32; 3],
    /// Per axis, the rows of a node's near and far planes (the high plane is the near one
    /// where the direction is negative).
    near: [usize; 3],
    far: [usize; 3],
}

impl BoxRay {
    #[inline(always)]
    fn new(origin: Vec3A, dir: Vec3A) -> BoxRay {
        // -0.0 becomes +0.0, so that a zero component's inverse is +inf, not -inf.
        let dir = dir + Vec3A::ZERO;
        BoxRay {
            ray: Ray4::new(origin, dir),
            o: origin.to_array(),
            dir: dir.to_array(),
            inv: [0, 1, 2].map(|a| 1.0 / dir[a]),
            near: [0, 1, 2].map(|a| if dir[a] < 0.0 { 3 + a } else { a }),
            far: [0, 1, 2].map(|a| if dir[a] < 0.0 { a } else { 3 + a }),
        }
    }

    /// A node's row of near planes and of far planes on `axis`.
    #[inline(always)]
    fn planes<'n>(&self, node: &'n Node, a: usize) -> (&'n [f32; WIDTH], &'n [f32; WIDTH]) {
        (
            &node.planes[self.near[a] % 6],
            &node.planes[self.far[a] % 6],
        )
    }
}

/// A box test of a node's children: the same operations on every lane, four or eight at a
/// time.
pub(super) trait Boxes {
    type Ray;
    fn prepare(r: &BoxRay) -> Self::Ray;
    /// The entry distances of `node`'s children and the mask of those entered within
    /// `tmax`.
    fn enter(r: &BoxRay, p: &Self::Ray, node: &Node, tmax: f32) -> ([f32; WIDTH], Mask);

    /// Two packs' lanes (`a`'s as 0-3, `b`'s as 4-7): each lane's distance, and the lanes
    /// that hit within `[0, tmax]`.
    #[inline(always)]
    fn pair(r: &BoxRay, a: &Tri4, b: &Tri4, tmax: f32) -> ([f32; 8], Mask) {
        let (zero, far) = (F4::splat(0.0), F4::splat(tmax));
        let (ta, ma) = a.intersect(&r.ray, zero, far);
        let (tb, mb) = b.intersect(&r.ray, zero, far);
        let mut t = [0f32; 8];
        t[..4].copy_from_slice(&ta);
        t[4..].copy_from_slice(&tb);
        (t, ma | mb << 4)
    }
}

/// Four lanes at a time: SSE2, or plain arrays off x86-64.
pub(super) struct Quads;

impl Boxes for Quads {
    type Ray = ([F4; 3], [F4; 3]);

    #[inline(always)]
    fn prepare(r: &BoxRay) -> Self::Ray {
        (r.o.map(F4::splat), r.inv.map(F4::splat))
    }

    #[inline(always)]
    fn enter(r: &BoxRay, p: &Self::Ray, node: &Node, tmax: f32) -> ([f32; WIDTH], Mask) {
        let mut entries = [0f32; WIDTH];
        let mut mask = 0;
        let tmax = F4::splat(tmax);
        for q in 0..WIDTH / 4 {
            let slab = |a: usize| {
                let (near, far) = r.planes(node, a);
                (
                    F4::load(quad(near, q)).sub(p.0[a]).mul(p.1[a]),
                    F4::load(quad(far, q)).sub(p.0[a]).mul(p.1[a]),
                )
            };
            let ((nx, fx), (ny, fy), (nz, fz)) = (slab(0), slab(1), slab(2));
            // max(a, b) is b where a is NaN: each axis in turn onto what is known.
            let t_in = nx.max(ny.max(nz.max(F4::splat(0.0))));
            let t_out = fx
                .min(fy.min(fz.min(F4::splat(f32::INFINITY))))
                .mul(F4::splat(WIDEN))
                .min(tmax);
            entries[q * 4..q * 4 + 4].copy_from_slice(&t_in.store());
            mask |= t_in.le(t_out) << (q * 4);
        }
        (entries, mask)
    }
}

/// Eight lanes at once: AVX2. Only for walks compiled for AVX2 or AVX-512
/// ([`Kernel::Avx2`], [`Kernel::Avx512`]).
#[cfg(target_arch = "x86_64")]
pub(super) struct Octs;

#[cfg(target_arch = "x86_64")]
impl Boxes for Octs {
    type Ray = ([F8; 3], [F8; 3]);

    #[inline(always)]
    fn prepare(r: &BoxRay) -> Self::Ray {
        (r.o.map(F8::splat), r.inv.map(F8::splat))
    }

    #[inline(always)]
    fn enter(r: &BoxRay, p: &Self::Ray, node: &Node, tmax: f32) -> ([f32; WIDTH], Mask) {
        const { assert!(WIDTH == 8) };
        let slab = |a: usize| {
            let (near, far) = r.planes(node, a);
            (
                F8::load_aligned(oct(near)).sub(p.0[a]).mul(p.1[a]),
                F8::load_aligned(oct(far)).sub(p.0[a]).mul(p.1[a]),
            )
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (slab(0), slab(1), slab(2));
        let t_in = nx.max(ny.max(nz.max(F8::splat(0.0))));
        let t_out = fx
            .min(fy.min(fz.min(F8::splat(f32::INFINITY))))
            .mul(F8::splat(WIDEN))
            .min(F8::splat(tmax));
        let mut entries = [0f32; WIDTH];
        entries[..8].copy_from_slice(&t_in.store());
        (entries, t_in.le(t_out))
    }

    #[inline(always)]
    fn pair(r: &BoxRay, a: &Tri4, b: &Tri4, tmax: f32) -> ([f32; 8], Mask) {
        a.intersect_pair(b, r.o, r.dir, 0.0, tmax)
    }
}

/// A node's row as eight lanes.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn oct(row: &[f32; WIDTH]) -> &[f32; 8] {
    row[..8].try_into().expect("eight lanes")
}

/// Packs `k` and `k + 1` of a leaf's `packs` (or `k` alone, the last), tested at once:
/// each lane's distance, the lanes that hit within `[0, tmax]`, and each lane's triangle.
#[inline(always)]
fn test_packs<K: Boxes>(
    r: &BoxRay,
    packs: &[Tri4],
    k: usize,
    tmax: f32,
) -> ([f32; 8], Mask, [u32; 8]) {
    let a = &packs[k];
    let mut ids = [u32::MAX; 8];
    ids[..4].copy_from_slice(&a.id);
    if let Some(b) = packs.get(k + 1) {
        ids[4..].copy_from_slice(&b.id);
        let (t, m) = K::pair(r, a, b, tmax);
        return (t, m, ids);
    }
    let (t4, m) = a.intersect(&r.ray, F4::splat(0.0), F4::splat(tmax));
    let mut t = [0f32; 8];
    t[..4].copy_from_slice(&t4);
    (t, m, ids)
}

/// Lanes `4q..4q + 4` of a node's row.
#[inline(always)]
fn quad(row: &[f32; WIDTH], q: usize) -> &[f32; 4] {
    row[q * 4..q * 4 + 4].try_into().expect("four lanes")
}

impl WideBvh {
    /// The closest triangle along `dir` from `origin` within `[0, tmax]` that `opaque(id,
    /// t)` lets stop the ray: its distance and id (the id the scene declared; of equally
    /// distant ones, the smallest). A BVH with other primitives needs [`Self::closest_with`].
    #[inline(always)]
    pub fn closest(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
    ) -> Option<(f32, u32)> {
        self.closest_with(origin, dir, tmax, opaque, |_, _| None)
    }

    /// [`Self::closest`] over triangles and other primitives: `other(id, limit)` is the
    /// distance at which other primitive `id` stops the ray before `limit` (exclusive), if
    /// it does.
    #[inline(always)]
    pub fn closest_with(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(f32, u32)> {
        match self.kernel {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the kernel is AVX2 only where the CPU has it (Kernel::choose).
            Kernel::Avx2 => unsafe { self.closest_avx2(origin, dir, tmax, opaque, other) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the kernel is AVX-512 only where the CPU has it (Kernel::choose).
            Kernel::Avx512 => unsafe { self.closest_avx512(origin, dir, tmax, opaque, other) },
            _ => self.closest_in::<Quads>(origin, dir, tmax, opaque, other),
        }
    }

    /// [`Self::closest_with`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn closest_avx2(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(f32, u32)> {
        self.closest_in::<Octs>(origin, dir, tmax, opaque, other)
    }

    /// [`Self::closest_with`] compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    unsafe fn closest_avx512(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(f32, u32)> {
        self.closest_in::<Octs>(origin, dir, tmax, opaque, other)
    }

    #[inline(always)]
    fn closest_in<K: Boxes>(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        mut opaque: impl FnMut(u32, f32) -> bool,
        mut other: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(f32, u32)> {
        let r = BoxRay::new(origin, dir);
        let p = K::prepare(&r);
        let (mut best_t, mut best) = (tmax, None::<u32>);
        // Left uninitialised: a ray touches a few entries, and zeroing them all costs more.
        let mut stack = [std::mem::MaybeUninit::<(u32, f32)>::uninit(); STACK];
        let mut sp = 0;
        // The node or leaf in hand: the nearest child entered goes on at once, the others
        // on the stack.
        let mut code = 0u32;
        loop {
            if code & (LEAF | OTHERS) == LEAF | OTHERS {
                let first = (code & LEAF_FIRST) as usize;
                let count = ((code >> 27) & 0x7) as usize + 1;
                for &id in &self.others[first..first + count] {
                    // Up to the closest hit so far inclusive, once there is one: at an equal
                    // distance the smaller id wins, whichever the walk met first.
                    let limit = if best.is_some() {
                        best_t.next_up()
                    } else {
                        best_t
                    };
                    if let Some(t) = other(id, limit)
                        && (t < best_t || best.is_none_or(|b| id < b))
                    {
                        best_t = t;
                        best = Some(id);
                    }
                }
            } else if code & LEAF != 0 {
                let first = (code & LEAF_FIRST) as usize;
                let count = ((code >> 27) & 0x7) as usize + 1;
                let packs = &self.packs[first..first + count];
                for k in (0..count).step_by(2) {
                    let (t, mut hits, ids) = test_packs::<K>(&r, packs, k, best_t);
                    while hits != 0 {
                        let lane = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        let (t, id) = (t[lane], ids[lane]);
                        let nearer = t < best_t || (t == best_t && best.is_none_or(|b| id < b));
                        if nearer && opaque(id, t) {
                            best_t = t;
                            best = Some(id);
                        }
                    }
                }
            } else {
                let node = &self.nodes[code as usize];
                let (entries, mut mask) = K::enter(&r, &p, node, best_t * REACH);
                if mask != 0 && mask & (mask - 1) == 0 {
                    code = node.child[mask.trailing_zeros() as usize];
                    continue;
                }
                // The children entered, farthest first onto the stack, so that the nearest
                // is on top; of equal entries, the later slot below.
                let mut order = [(0f32, 0u32); WIDTH];
                let mut n = 0;
                while mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let e = entries[slot];
                    let mut k = n;
                    while k > 0 && order[k - 1].0 < e {
                        order[k] = order[k - 1];
                        k -= 1;
                    }
                    order[k] = (e, node.child[slot]);
                    n += 1;
                }
                if n > 0 {
                    for &(e, c) in &order[..n - 1] {
                        debug_assert_ne!(c, EMPTY);
                        stack[sp].write((c, e));
                        sp += 1;
                    }
                    code = order[n - 1].1;
                    continue;
                }
            }
            // The next entry on the stack not beyond the closest hit, if any.
            loop {
                if sp == 0 {
                    return best.map(|id| (best_t, id));
                }
                sp -= 1;
                // SAFETY: entries below `sp` were written before `sp` passed them.
                let (c, entry) = unsafe { stack[sp].assume_init() };
                if entry <= best_t * REACH {
                    code = c;
                    break;
                }
            }
        }
    }

    /// Whether some triangle that `opaque(id, t)` lets stop the ray lies along `dir` from
    /// `origin` within `[0, tmax]`. A BVH with other primitives needs [`Self::any_with`].
    #[inline(always)]
    pub fn any(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
    ) -> bool {
        self.any_with(origin, dir, tmax, opaque, |_, _| false)
    }

    /// [`Self::any`] over triangles and other primitives: `other(id, tmax)` says whether
    /// other primitive `id` stops the ray within `tmax`.
    #[inline(always)]
    pub fn any_with(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> bool,
    ) -> bool {
        match self.kernel {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the kernel is AVX2 only where the CPU has it (Kernel::choose).
            Kernel::Avx2 => unsafe { self.any_avx2(origin, dir, tmax, opaque, other) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the kernel is AVX-512 only where the CPU has it (Kernel::choose).
            Kernel::Avx512 => unsafe { self.any_avx512(origin, dir, tmax, opaque, other) },
            _ => self.any_in::<Quads>(origin, dir, tmax, opaque, other),
        }
    }

    /// [`Self::any_with`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn any_avx2(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> bool,
    ) -> bool {
        self.any_in::<Octs>(origin, dir, tmax, opaque, other)
    }

    /// [`Self::any_with`] compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    unsafe fn any_avx512(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        opaque: impl FnMut(u32, f32) -> bool,
        other: impl FnMut(u32, f32) -> bool,
    ) -> bool {
        self.any_in::<Octs>(origin, dir, tmax, opaque, other)
    }

    #[inline(always)]
    fn any_in<K: Boxes>(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        mut opaque: impl FnMut(u32, f32) -> bool,
        mut other: impl FnMut(u32, f32) -> bool,
    ) -> bool {
        let r = BoxRay::new(origin, dir);
        let p = K::prepare(&r);
        let mut stack = [std::mem::MaybeUninit::<u32>::uninit(); STACK];
        stack[0].write(0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            // SAFETY: entries below `sp` were written before `sp` passed them.
            let code = unsafe { stack[sp].assume_init() };
            if code & (LEAF | OTHERS) == LEAF | OTHERS {
                let first = (code & LEAF_FIRST) as usize;
                let count = ((code >> 27) & 0x7) as usize + 1;
                if self.others[first..first + count]
                    .iter()
                    .any(|&id| other(id, tmax))
                {
                    return true;
                }
                continue;
            }
            if code & LEAF != 0 {
                let first = (code & LEAF_FIRST) as usize;
                let count = ((code >> 27) & 0x7) as usize + 1;
                let packs = &self.packs[first..first + count];
                for k in (0..count).step_by(2) {
                    let (t, mut hits, ids) = test_packs::<K>(&r, packs, k, tmax);
                    while hits != 0 {
                        let lane = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        if opaque(ids[lane], t[lane]) {
                            return true;
                        }
                    }
                }
                continue;
            }
            let node = &self.nodes[code as usize];
            // The last slot pushed first, so that slot 0, the largest box (see `open`), is
            // taken first.
            let (_, mut mask) = K::enter(&r, &p, node, tmax);
            while mask != 0 {
                let slot = 31 - mask.leading_zeros() as usize;
                mask &= !(1 << slot);
                stack[sp].write(node.child[slot]);
                sp += 1;
            }
        }
        false
    }
}
