//! Choosing which light to sample from a shading point: by power, uniformly, or through a
//! bounding volume hierarchy over the lights whose choice at each node weighs the two
//! clusters' power by their distance and orientation from the point (pbrt-v4's default
//! "bvh" light sampler, after Conty Estevez and Kulla's "Importance Sampling of Many
//! Lights with Adaptive Tree Splitting").
//!
//! Whatever the kind, [`LightSampler::pmf`] gives exactly the probability
//! [`LightSampler::sample`] chose a light with from the same point: multiple importance
//! sampling weighs emission found by BSDF sampling against it. Lights at infinity (and
//! distant lights) are outside the hierarchy and chosen uniformly with one share beside
//! it.
//!
//! A VolumeLight's faces (a hundred thousand lights for seed 000's snail, whose bounds
//! say only where each face is, since the interior shines out of every face every way)
//! sit under one leaf of the hierarchy as one group, and are chosen within it by power
//! from an alias table: a choice in constant time instead of a walk of twenty levels.

use super::Light;
use super::bounds::{Cluster, LightBounds, Pair};
use crate::sampling::AliasTable;
use glam::Vec3A;
use kiln_scene::LightSamplerKind;

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Lights at infinity (and distant lights), chosen uniformly with one share beside the
/// bounded lights' (pbrt-v4's rule for its bvh and exhaustive samplers).
#[derive(Debug, Clone, Default)]
struct Beside {
    lights: Vec<u32>,
}

impl Beside {
    /// The probability of choosing one of these at all.
    fn share(&self, bounded: bool) -> f32 {
        let n = self.lights.len() as f32;
        if n == 0.0 {
            0.0
        } else {
            n / (n + if bounded { 1.0 } else { 0.0 })
        }
    }

    /// One of these and its probability, or `u` remapped to [0, 1) for the bounded lights.
    fn choose(&self, u: f32, bounded: bool) -> Result<(usize, f32), f32> {
        let share = self.share(bounded);
        if u < share {
            let k = self.lights.len();
            let i = ((u / share * k as f32) as usize).min(k - 1);
            return Ok((self.lights[i] as usize, share / k as f32));
        }
        Err(((u - share) / (1.0 - share)).min(ONE_MINUS_EPSILON))
    }

    /// The probability `light`, one of these, is chosen with; None for other lights.
    fn pmf(&self, light: usize, bounded: bool) -> Option<f32> {
        self.lights
            .contains(&(light as u32))
            .then(|| self.share(bounded) / self.lights.len() as f32)
    }
}

/// A node of the light hierarchy: its two children's bounds side by side and its second
/// child (the first follows it) or, in a leaf, its light or its group of lights.
#[derive(Debug, Clone)]
struct Node {
    /// The children's clusters (unused in a leaf).
    children: Pair,
    /// The second child's index, or in a leaf the light's index (the group's, for a
    /// group).
    index: u32,
    leaf: bool,
    /// A leaf for a group of lights ([`Group`]).
    group: bool,
    /// The two children's clusters are equal (a quad's two triangles), so their importances
    /// are too, bit for bit: one is computed for both.
    twins: bool,
}

/// Lights under one leaf of the hierarchy, chosen among themselves by power.
#[derive(Debug, Clone)]
struct Group {
    lights: Vec<u32>,
    table: AliasTable,
}

/// In the ids the hierarchy is built over, the bit that marks a group's index.
const GROUP: u32 = 1 << 31;

/// The hierarchy over the lights with finite bounds, and the lights at infinity beside it.
#[derive(Debug, Clone, Default)]
pub struct LightBvh {
    nodes: Vec<Node>,
    /// The root's cluster: a root that is a leaf lights only where it has importance.
    root: Cluster,
    infinite: Beside,
    /// Per light: the branches (bit k set: the second child at depth k) from the root to
    /// its leaf, or None for lights at infinity and lights that emit nothing.
    trails: Vec<Option<u64>>,
    groups: Vec<Group>,
    /// Per light in a group, its place in the group's `lights` (u32::MAX for the others).
    place: Vec<u32>,
}

/// Below this depth clusters are split by cost; deeper, in the middle of their lights, so
/// that the path to every leaf fits in a 64-bit trail whatever the lights' layout (a
/// degenerate cost can peel one light off at a time).
fn sah_depth(lights: usize) -> u32 {
    63u32.saturating_sub(usize::BITS - lights.max(1).leading_zeros())
}

impl LightBvh {
    /// Builds the hierarchy over `bounds` (None: a light at infinity). Lights with the same
    /// `group` (a VolumeLight's faces) sit under one leaf, chosen within it by power.
    pub fn new(bounds: &[Option<LightBounds>], group: &[Option<u32>]) -> LightBvh {
        debug_assert_eq!(bounds.len(), group.len());
        let mut bvh = LightBvh {
            nodes: Vec::new(),
            root: Cluster::default(),
            infinite: Beside::default(),
            trails: vec![None; bounds.len()],
            groups: Vec::new(),
            place: vec![u32::MAX; bounds.len()],
        };
        let mut finite: Vec<(u32, LightBounds)> = Vec::new();
        // Each group's members and their bounds, in the order groups first appear (the map
        // finds a key's place: a scene may have many VolumeLights).
        let mut grouped: Vec<Vec<(u32, LightBounds)>> = Vec::new();
        let mut place_of: std::collections::HashMap<u32, usize> = Default::default();
        for (i, b) in bounds.iter().enumerate() {
            match (b, group.get(i).copied().flatten()) {
                (None, _) => bvh.infinite.lights.push(i as u32),
                (Some(b), key) if b.phi > 0.0 && b.phi.is_finite() => match key {
                    None => finite.push((i as u32, *b)),
                    Some(key) => {
                        let k = *place_of.entry(key).or_insert_with(|| {
                            grouped.push(Vec::new());
                            grouped.len() - 1
                        });
                        grouped[k].push((i as u32, *b));
                    }
                },
                (Some(_), _) => {}
            }
        }
        for members in grouped {
            if members.len() == 1 {
                finite.push(members[0]);
                continue;
            }
            let g = bvh.groups.len() as u32;
            let union = members[1..]
                .iter()
                .fold(members[0].1, |acc, (_, b)| acc.union(b));
            let powers: Vec<f64> = members.iter().map(|(_, b)| b.phi as f64).collect();
            for (k, (light, _)) in members.iter().enumerate() {
                bvh.place[*light as usize] = k as u32;
            }
            bvh.groups.push(Group {
                lights: members.iter().map(|(light, _)| *light).collect(),
                table: AliasTable::new(&powers),
            });
            finite.push((GROUP | g, union));
        }
        if !finite.is_empty() {
            let limit = sah_depth(finite.len());
            let b = bvh.build(&mut finite, 0, 0, limit);
            bvh.root = Cluster::new(&b);
        }
        bvh
    }

    fn build(
        &mut self,
        lights: &mut [(u32, LightBounds)],
        depth: u32,
        trail: u64,
        sah_limit: u32,
    ) -> LightBounds {
        if lights.len() == 1 {
            let (light, b) = lights[0];
            let group = light & GROUP != 0;
            self.nodes.push(Node {
                children: Pair::default(),
                index: light & !GROUP,
                leaf: true,
                group,
                twins: false,
            });
            if group {
                for &member in &self.groups[(light & !GROUP) as usize].lights {
                    self.trails[member as usize] = Some(trail);
                }
            } else {
                self.trails[light as usize] = Some(trail);
            }
            return b;
        }
        let split = if depth < sah_limit {
            best_split(lights)
        } else {
            None
        }
        .unwrap_or(lights.len() / 2);
        let me = self.nodes.len();
        self.nodes.push(Node {
            children: Pair::default(),
            index: 0,
            leaf: false,
            group: false,
            twins: false,
        });
        let (first, second) = lights.split_at_mut(split);
        let b0 = self.build(first, depth + 1, trail, sah_limit);
        self.nodes[me].index = self.nodes.len() as u32;
        let b1 = self.build(second, depth + 1, trail | (1 << depth), sah_limit);
        let (c0, c1) = (Cluster::new(&b0), Cluster::new(&b1));
        self.nodes[me].children = Pair::new(&c0, &c1);
        self.nodes[me].twins = c0 == c1;
        b0.union(&b1)
    }

    fn sample(&self, p: Vec3A, n: Vec3A, u: f32) -> Option<(usize, f32)> {
        let bounded = !self.nodes.is_empty();
        let mut u = match self.infinite.choose(u, bounded) {
            Ok(chosen) => return Some(chosen),
            Err(_) if !bounded => return None,
            Err(u) => u,
        };
        let mut pmf = 1.0 - self.infinite.share(bounded);
        let mut i = 0;
        loop {
            let node = &self.nodes[i];
            if node.leaf {
                if i == 0 && self.root.importance(p, n) <= 0.0 {
                    return None;
                }
                if node.group {
                    let group = &self.groups[node.index as usize];
                    let (k, chosen) = group.table.sample(u)?;
                    return Some((group.lights[k] as usize, pmf * chosen));
                }
                return Some((node.index as usize, pmf));
            }
            let (c0, c1) = self.child_importances(node, p, n);
            let total = c0 + c1;
            if total == 0.0 {
                return None;
            }
            let p0 = c0 / total;
            if u < p0 {
                u = (u / p0).min(ONE_MINUS_EPSILON);
                pmf *= c0 / total;
                i += 1;
            } else {
                u = ((u - p0) / (1.0 - p0)).min(ONE_MINUS_EPSILON);
                pmf *= c1 / total;
                i = node.index as usize;
            }
        }
    }

    /// The importances of `node`'s two children at (`p`, `n`).
    #[inline(always)]
    fn child_importances(&self, node: &Node, p: Vec3A, n: Vec3A) -> (f32, f32) {
        let (c0, c1) = node.children.importances(p, n);
        if node.twins {
            return (c0, c0);
        }
        (c0, c1)
    }

    fn pmf(&self, p: Vec3A, n: Vec3A, light: usize) -> f32 {
        let bounded = !self.nodes.is_empty();
        let Some(mut trail) = self.trails[light] else {
            return self.infinite.pmf(light, bounded).unwrap_or(0.0);
        };
        let mut pmf = 1.0 - self.infinite.share(bounded);
        let mut i = 0;
        loop {
            let node = &self.nodes[i];
            if node.leaf {
                if i == 0 && self.root.importance(p, n) == 0.0 {
                    return 0.0;
                }
                if node.group {
                    let group = &self.groups[node.index as usize];
                    return pmf * group.table.pmf(self.place[light] as usize);
                }
                return pmf;
            }
            let (c0, c1) = self.child_importances(node, p, n);
            let total = c0 + c1;
            if total == 0.0 {
                return 0.0;
            }
            if trail & 1 == 0 {
                pmf *= c0 / total;
                i += 1;
            } else {
                pmf *= c1 / total;
                i = node.index as usize;
            }
            trail >>= 1;
        }
    }
}

/// Where to split a cluster: pbrt-v4's 12 buckets per axis by centroid, at the boundary
/// of least cost; None where the centroids coincide (split by count).
fn best_split(lights: &mut [(u32, LightBounds)]) -> Option<usize> {
    const BUCKETS: usize = 12;
    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let (mut blo, mut bhi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for (_, b) in lights.iter() {
        lo = lo.min(b.centroid());
        hi = hi.max(b.centroid());
        blo = blo.min(b.lo);
        bhi = bhi.max(b.hi);
    }
    let parent_diag = bhi - blo;
    let extent = hi - lo;
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let bucket_of = |b: &LightBounds| {
            let t = (b.centroid()[axis] - lo[axis]) / extent[axis];
            ((t * BUCKETS as f32) as usize).min(BUCKETS - 1)
        };
        let mut buckets: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
        for (_, b) in lights.iter() {
            let k = bucket_of(b);
            buckets[k] = Some(buckets[k].map_or(*b, |x| x.union(b)));
        }
        for split in 1..BUCKETS {
            let union = |range: &[Option<LightBounds>]| {
                range.iter().flatten().fold(None::<LightBounds>, |acc, b| {
                    Some(acc.map_or(*b, |a| a.union(b)))
                })
            };
            let (Some(a), Some(b)) = (union(&buckets[..split]), union(&buckets[split..])) else {
                continue;
            };
            let cost = a.cost(parent_diag, axis) + b.cost(parent_diag, axis);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (_, axis, split) = best?;
    let t = |b: &LightBounds| (b.centroid()[axis] - lo[axis]) / extent[axis];
    // Stable, so that the order of lights (and the bytes rendered) never depends on the
    // sort's internals.
    lights.sort_by(|a, b| t(&a.1).total_cmp(&t(&b.1)));
    let mid = lights
        .partition_point(|(_, b)| ((t(b) * BUCKETS as f32) as usize).min(BUCKETS - 1) < split);
    (mid > 0 && mid < lights.len()).then_some(mid)
}

/// How the path tracer chooses the light to sample.
#[derive(Debug, Clone)]
pub enum LightSampler {
    Power(AliasTable),
    Uniform(usize),
    Bvh(Box<LightBvh>),
    Exhaustive(Box<Exhaustive>),
}

/// Every bounded light weighed by its importance from the shading point, and the lights at
/// infinity beside them (pbrt-v4's "exhaustive").
#[derive(Debug, Clone)]
pub struct Exhaustive {
    bounded: Vec<(u32, Cluster)>,
    infinite: Beside,
    /// Per light, its place in `bounded` (None: at infinity, or emits nothing).
    place: Vec<Option<u32>>,
}

impl Exhaustive {
    fn new(bounds: &[Option<LightBounds>]) -> Exhaustive {
        let mut e = Exhaustive {
            bounded: Vec::new(),
            infinite: Beside::default(),
            place: vec![None; bounds.len()],
        };
        for (i, b) in bounds.iter().enumerate() {
            match b {
                None => e.infinite.lights.push(i as u32),
                Some(b) if b.phi > 0.0 && b.phi.is_finite() => {
                    e.place[i] = Some(e.bounded.len() as u32);
                    e.bounded.push((i as u32, Cluster::new(b)));
                }
                Some(_) => {}
            }
        }
        e
    }

    fn sample(&self, p: Vec3A, n: Vec3A, u: f32) -> Option<(usize, f32)> {
        let bounded = !self.bounded.is_empty();
        let u = match self.infinite.choose(u, bounded) {
            Ok(chosen) => return Some(chosen),
            Err(u) => u,
        };
        let p_inf = self.infinite.share(bounded);
        // Two passes over the lights (the total, then the walk to it): nothing allocated.
        let total: f32 = self.bounded.iter().map(|(_, b)| b.importance(p, n)).sum();
        if total <= 0.0 {
            return None;
        }
        let target = u * total;
        let mut acc = 0.0;
        let mut chosen = None;
        for (k, (_, b)) in self.bounded.iter().enumerate() {
            let w = b.importance(p, n);
            if w > 0.0 {
                chosen = Some((k, w));
                acc += w;
                if target < acc {
                    break;
                }
            }
        }
        let (k, w) = chosen?;
        Some((self.bounded[k].0 as usize, (1.0 - p_inf) * w / total))
    }

    fn pmf(&self, p: Vec3A, n: Vec3A, light: usize) -> f32 {
        let bounded = !self.bounded.is_empty();
        let Some(k) = self.place[light] else {
            return self.infinite.pmf(light, bounded).unwrap_or(0.0);
        };
        let total: f32 = self.bounded.iter().map(|(_, b)| b.importance(p, n)).sum();
        if total <= 0.0 {
            return 0.0;
        }
        (1.0 - self.infinite.share(bounded)) * self.bounded[k as usize].1.importance(p, n) / total
    }
}

impl Default for LightSampler {
    fn default() -> LightSampler {
        LightSampler::Uniform(0)
    }
}

impl LightSampler {
    /// The sampler of `kind` over `lights`, whose powers are `powers`.
    pub fn new(
        kind: LightSamplerKind,
        lights: &[Light],
        powers: &[f64],
        ctx: &super::LightContext,
    ) -> LightSampler {
        match kind {
            LightSamplerKind::Power => LightSampler::Power(AliasTable::new(powers)),
            LightSamplerKind::Uniform => LightSampler::Uniform(lights.len()),
            LightSamplerKind::Bvh | LightSamplerKind::Exhaustive => {
                let bounds: Vec<Option<LightBounds>> = lights
                    .iter()
                    .zip(powers)
                    .map(|(l, &power)| l.bounds(ctx, power as f32))
                    .collect();
                if kind == LightSamplerKind::Bvh {
                    // A VolumeLight's faces as one group, by the interior they share.
                    let group: Vec<Option<u32>> = lights
                        .iter()
                        .map(|l| match l {
                            Light::VolumeTriangle(f) => Some(f.volume),
                            Light::VolumeQuadric(q) => Some(q.volume),
                            _ => None,
                        })
                        .collect();
                    LightSampler::Bvh(Box::new(LightBvh::new(&bounds, &group)))
                } else {
                    LightSampler::Exhaustive(Box::new(Exhaustive::new(&bounds)))
                }
            }
        }
    }

    /// No light can be chosen from anywhere.
    pub fn is_empty(&self) -> bool {
        match self {
            LightSampler::Power(t) => t.is_empty(),
            LightSampler::Uniform(n) => *n == 0,
            LightSampler::Bvh(b) => b.nodes.is_empty() && b.infinite.lights.is_empty(),
            LightSampler::Exhaustive(e) => e.bounded.is_empty() && e.infinite.lights.is_empty(),
        }
    }

    /// Chooses a light to sample from the point `p` with shading normal `n` (zero in a
    /// medium): its index and the probability it was chosen with; None where no light
    /// could light `p`.
    pub fn sample(&self, p: Vec3A, n: Vec3A, u: f32) -> Option<(usize, f32)> {
        match self {
            LightSampler::Power(t) => t.sample(u),
            LightSampler::Uniform(0) => None,
            LightSampler::Uniform(k) => {
                Some((((u * *k as f32) as usize).min(k - 1), 1.0 / *k as f32))
            }
            LightSampler::Bvh(b) => b.sample(p, n, u),
            LightSampler::Exhaustive(e) => e.sample(p, n, u),
        }
    }

    /// The probability [`LightSampler::sample`] chooses `light` from `p` with normal `n`.
    pub fn pmf(&self, p: Vec3A, n: Vec3A, light: usize) -> f32 {
        match self {
            LightSampler::Power(t) => t.pmf(light),
            LightSampler::Uniform(k) => 1.0 / *k as f32,
            LightSampler::Bvh(b) => b.pmf(p, n, light),
            LightSampler::Exhaustive(e) => e.pmf(p, n, light),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(p: Vec3A, phi: f32) -> Option<LightBounds> {
        Some(LightBounds::everywhere(p, p, phi))
    }

    /// The lights' pmfs from any point sum to at most 1, and sampling picks each as often
    /// as its pmf says, with the probability its pmf gives, for the hierarchy and the
    /// exhaustive sampler.
    #[test]
    fn pmf_matches_sampling() {
        let mut bounds = vec![None]; // a light at infinity
        for i in 0..37 {
            let x = libm::sinf(i as f32 * 0.37) * 4.0;
            let y = libm::cosf(i as f32 * 1.3) * 3.0;
            let p = Vec3A::new(x, y, (i % 5) as f32);
            if i % 3 == 0 {
                let n = Vec3A::new(x, 1.0, -y).normalize();
                bounds.push(Some(LightBounds::diffuse(
                    p - 0.1,
                    p + 0.1,
                    n,
                    1.0,
                    1.0 + i as f32,
                    i % 2 == 0,
                )));
            } else {
                bounds.push(point(p, 0.5 + (i % 7) as f32));
            }
        }
        bounds.push(point(Vec3A::ONE, 0.0)); // emits nothing: never chosen
        for sampler in [
            LightSampler::Bvh(Box::new(LightBvh::new(&bounds, &vec![None; bounds.len()]))),
            LightSampler::Exhaustive(Box::new(Exhaustive::new(&bounds))),
        ] {
            check_pmf_against_sampling(&sampler, bounds.len());
        }
    }

    /// Grouped lights (a VolumeLight's faces) are chosen by power within their group's
    /// leaf: the pmfs still match sampling, the group's members share its probability in
    /// proportion to their power, and a group of one is a plain leaf.
    #[test]
    fn grouped_lights_are_chosen_by_power_within_their_leaf() {
        let mut bounds = vec![None];
        let mut group = vec![None];
        for i in 0..60 {
            let p = Vec3A::new(
                libm::sinf(i as f32 * 0.91) * 3.0,
                libm::cosf(i as f32 * 0.4),
                (i % 4) as f32,
            );
            bounds.push(point(p, 0.25 + (i % 5) as f32));
            // Lights 20-49 one group, light 55 a group of its own, the rest alone.
            group.push(match i {
                20..50 => Some(7),
                55 => Some(9),
                _ => None,
            });
        }
        bounds.push(point(Vec3A::ONE, 0.0)); // emits nothing: never chosen
        group.push(Some(7));
        let bvh = LightBvh::new(&bounds, &group);
        assert_eq!(bvh.groups.len(), 1);
        assert_eq!(bvh.groups[0].lights.len(), 30);
        let sampler = LightSampler::Bvh(Box::new(bvh));
        check_pmf_against_sampling(&sampler, bounds.len());
        let (p, n) = (Vec3A::new(0.5, 2.0, 1.0), Vec3A::ZERO);
        let (a, b) = (sampler.pmf(p, n, 21 + 1), sampler.pmf(p, n, 22 + 1));
        let (pa, pb) = (0.25 + (21 % 5) as f32, 0.25 + (22 % 5) as f32);
        assert!((a / b - pa / pb).abs() < 1e-4, "{a} {b}");
    }

    fn check_pmf_against_sampling(sampler: &LightSampler, lights: usize) {
        for (p, n) in [
            (Vec3A::new(0.3, -0.2, 1.0), Vec3A::Z),
            (Vec3A::new(10.0, 2.0, -3.0), Vec3A::ZERO),
            (Vec3A::new(-1.0, 0.5, 2.5), Vec3A::new(0.6, 0.0, 0.8)),
        ] {
            let pmfs: Vec<f32> = (0..lights).map(|i| sampler.pmf(p, n, i)).collect();
            let total: f32 = pmfs.iter().sum();
            // A cluster may be worth choosing while neither of its halves is: that share
            // of the choices finds no light.
            assert!(total > 0.5 && total <= 1.0 + 1e-4, "pmfs sum to {total}");
            assert_eq!(pmfs[lights - 1], 0.0);
            let trials = 200_000;
            let mut counts = vec![0u32; lights];
            let mut none = 0;
            for k in 0..trials {
                let u = (k as f32 + 0.5) / trials as f32;
                let Some((i, pmf)) = sampler.sample(p, n, u) else {
                    none += 1;
                    continue;
                };
                assert!(
                    (pmf - pmfs[i]).abs() <= 1e-5 * pmfs[i],
                    "pmf {pmf} vs {}",
                    pmfs[i]
                );
                counts[i] += 1;
            }
            let expected_none = (1.0 - total) * trials as f32;
            assert!((none as f32 - expected_none).abs() <= 2.0 + 1e-3 * trials as f32);
            for (i, &c) in counts.iter().enumerate() {
                let expected = pmfs[i] * trials as f32;
                assert!(
                    (c as f32 - expected).abs() <= 2.0 + 1e-3 * trials as f32,
                    "light {i}: chosen {c} times, pmf says {expected}"
                );
            }
        }
    }

    /// Thousands of point lights on one line (every split's boxes have no area, so the
    /// cost cannot tell splits apart): the hierarchy stays within its 64-bit trails and its
    /// pmfs sum to 1.
    #[test]
    fn collinear_lights_keep_within_the_trail() {
        let bounds: Vec<Option<LightBounds>> = (0..5000)
            .map(|i| point(Vec3A::new(i as f32 * 0.01, 0.0, 0.0), 1.0 + (i % 3) as f32))
            .collect();
        let bvh = LightBvh::new(&bounds, &vec![None; bounds.len()]);
        assert!(bvh.trails.iter().all(Option::is_some));
        let sampler = LightSampler::Bvh(Box::new(bvh));
        let p = Vec3A::new(3.0, 1.0, 0.5);
        let total: f32 = (0..bounds.len())
            .map(|i| sampler.pmf(p, Vec3A::ZERO, i))
            .sum();
        assert!((total - 1.0).abs() < 1e-3, "{total}");
        let (i, pmf) = sampler.sample(p, Vec3A::ZERO, 0.37).unwrap();
        assert_eq!(pmf, sampler.pmf(p, Vec3A::ZERO, i));
    }

    /// A one-sided emitter facing away from the point is never chosen, and importance
    /// prefers the near of two equal lights.
    #[test]
    fn importance_sees_orientation_and_distance() {
        let facing_up = LightBounds::diffuse(Vec3A::ZERO, Vec3A::ZERO, Vec3A::Z, 1.0, 1.0, false);
        assert!(facing_up.importance(Vec3A::new(0.0, 0.0, 1.0), Vec3A::ZERO) > 0.0);
        assert_eq!(
            facing_up.importance(Vec3A::new(0.0, 0.0, -1.0), Vec3A::ZERO),
            0.0
        );
        let two_sided = LightBounds {
            two_sided: true,
            ..facing_up
        };
        assert!(two_sided.importance(Vec3A::new(0.0, 0.0, -1.0), Vec3A::ZERO) > 0.0);
        let near = LightBounds::everywhere(Vec3A::X, Vec3A::X, 1.0);
        let far = LightBounds::everywhere(Vec3A::X * 10.0, Vec3A::X * 10.0, 1.0);
        let (a, b) = (
            near.importance(Vec3A::ZERO, Vec3A::ZERO),
            far.importance(Vec3A::ZERO, Vec3A::ZERO),
        );
        assert!((a / b - 100.0).abs() < 1e-3, "{a} {b}");
        // The cone of a cluster holds both of its members' cones.
        let u = facing_up.union(&LightBounds::diffuse(
            Vec3A::X,
            Vec3A::X,
            Vec3A::X,
            1.0,
            1.0,
            false,
        ));
        assert!(u.w.dot(Vec3A::Z) >= u.cos_o - 1e-5 && u.w.dot(Vec3A::X) >= u.cos_o - 1e-5);
    }
}
