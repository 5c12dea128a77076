//! A photon map: stored photons and the index that finds those near a point, for fixed-
//! radius gathers (a hash grid whose cells are as wide as the radius) or k-nearest gathers
//! with a maximum radius (a k-d tree, kiddo's).
//!
//! Both indexes are built from the photons in their (deterministic) order by single-
//! threaded code, and queries visit photons in an order fixed by that: a gather's sum is
//! the same on every machine and thread count.

use crate::math::Color;
use glam::Vec3A;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::collections::HashMap;
use std::num::NonZero;
use std::sync::Arc;

/// One stored photon: where, from which direction it arrived (pointing away from `p`),
/// the surface normal there (zero in a medium) and its flux.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Photon {
    pub p: Vec3A,
    pub wi: Vec3A,
    pub n: Vec3A,
    pub power: Color,
}

/// Which photons a density estimate gathers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gather {
    /// Every photon within the radius.
    Radius(f32),
    /// The `k` nearest, no farther than `max_radius`; the estimate's radius is the k-th
    /// photon's distance, or `max_radius` where fewer are that close (seed 003: 100).
    Nearest { k: u32, max_radius: f32 },
}

/// Which index answers fixed-radius gathers (k-nearest ones always use the tree).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Index {
    HashGrid,
    KdTree,
}

/// The photons and their indexes.
#[derive(Debug, Clone, Default)]
pub struct PhotonMap {
    photons: Vec<Photon>,
    gather: Option<Gather>,
    grid: HashGrid,
    tree: Option<KdTree>,
}

/// kiddo's immutable tree over photon positions; items are indices into `photons`.
#[derive(Clone)]
struct KdTree(Arc<ImmutableKdTree<f32, 3>>);

impl std::fmt::Debug for KdTree {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("KdTree")
    }
}

impl PhotonMap {
    /// A map of `photons` gathered as `gather` says, with the index that measured faster
    /// for it (see the photons benchmark): fixed radii in the hash grid, k-nearest in the
    /// tree. `index` forces one for fixed radii (for the benchmark).
    pub fn new(photons: Vec<Photon>, gather: Gather, index: Option<Index>) -> PhotonMap {
        let index = match gather {
            Gather::Nearest { .. } => Index::KdTree,
            Gather::Radius(_) => index.unwrap_or(Index::HashGrid),
        };
        let mut map = PhotonMap {
            photons,
            gather: Some(gather),
            grid: HashGrid::default(),
            tree: None,
        };
        if map.photons.is_empty() {
            return map;
        }
        match (index, gather) {
            (Index::HashGrid, Gather::Radius(r)) => {
                map.grid = HashGrid::new(&mut map.photons, r);
            }
            _ => {
                let points: Vec<[f32; 3]> = map.photons.iter().map(|ph| ph.p.to_array()).collect();
                // Construction fails only for more items than u32 indexes, which the
                // photon counts' limit rules out; an empty tree then gathers nothing.
                map.tree = ImmutableKdTree::new_from_slice(&points)
                    .ok()
                    .map(|t| KdTree(Arc::new(t)));
            }
        }
        map
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    pub fn photons(&self) -> &[Photon] {
        &self.photons
    }

    /// Calls `f` for each photon the estimate at `p` gathers; returns the radius of the
    /// gathered ball (0 for an empty map).
    pub fn gather(&self, p: Vec3A, mut f: impl FnMut(&Photon)) -> f32 {
        let Some(gather) = self.gather.filter(|_| !self.photons.is_empty()) else {
            return 0.0;
        };
        match (gather, &self.tree) {
            (Gather::Radius(r), None) => {
                self.grid.for_each_near(&self.photons, p, f);
                r
            }
            (Gather::Radius(r), Some(tree)) => {
                let found = tree
                    .0
                    .query(&p.to_array())
                    .within::<SquaredEuclidean<f32>>(r * r)
                    .unsorted()
                    .execute();
                for item in found {
                    f(&self.photons[item.item as usize]);
                }
                r
            }
            (Gather::Nearest { k, max_radius }, Some(tree)) => {
                let k = NonZero::new(k.max(1) as usize).unwrap_or(NonZero::<usize>::MIN);
                let found = tree
                    .0
                    .query(&p.to_array())
                    .nearest_n::<SquaredEuclidean<f32>>(k)
                    .within(max_radius * max_radius)
                    .execute();
                let radius = if found.len() == k.get() {
                    found.last().map_or(max_radius, |n| n.distance.sqrt())
                } else {
                    max_radius
                };
                for item in &found {
                    f(&self.photons[item.item as usize]);
                }
                // A gather that found the k-th photon at distance 0 (all k at one point)
                // has no area: fall back to the maximum radius.
                if radius > 0.0 { radius } else { max_radius }
            }
            (Gather::Nearest { .. }, None) => 0.0,
        }
    }

    /// Calls `f` for each photon within `radius` of `p`; `radius` must not exceed the map's
    /// fixed gather radius where the map is a hash grid (SPPM's radii only shrink).
    pub fn gather_within(&self, p: Vec3A, radius: f32, mut f: impl FnMut(&Photon)) {
        if self.photons.is_empty() {
            return;
        }
        match &self.tree {
            Some(tree) => {
                let found = tree
                    .0
                    .query(&p.to_array())
                    .within::<SquaredEuclidean<f32>>(radius * radius)
                    .unsorted()
                    .execute();
                for item in found {
                    f(&self.photons[item.item as usize]);
                }
            }
            None => {
                debug_assert!(radius <= self.grid.radius);
                let r2 = radius * radius;
                self.grid.for_each_near(&self.photons, p, |ph| {
                    if (ph.p - p).length_squared() <= r2 {
                        f(ph);
                    }
                });
            }
        }
    }

    /// The sum of `weight(photon) * power` over the photons gathered at `p`, and the radius.
    pub fn sum(&self, p: Vec3A, weight: impl Fn(&Photon) -> Color) -> (Color, f32) {
        let mut sum = Color::ZERO;
        let r = self.gather(p, |ph| sum += ph.power * weight(ph));
        (sum, r)
    }
}

/// Photons bucketed in a uniform hash grid whose cells are as wide as the search radius,
/// so a query visits at most 27 cells.
#[derive(Debug, Clone, Default)]
struct HashGrid {
    cells: HashMap<(i32, i32, i32), (u32, u32)>,
    radius: f32,
}

impl HashGrid {
    /// Sorts `photons` by cell (stably, keeping their order within a cell) and indexes them.
    fn new(photons: &mut [Photon], radius: f32) -> HashGrid {
        let key = |p: Vec3A| {
            let c = (p / radius).floor();
            (c.x as i32, c.y as i32, c.z as i32)
        };
        photons.sort_by_key(|ph| key(ph.p));
        let mut cells = HashMap::new();
        let mut start = 0;
        while start < photons.len() {
            let k = key(photons[start].p);
            let mut end = start + 1;
            while end < photons.len() && key(photons[end].p) == k {
                end += 1;
            }
            cells.insert(k, (start as u32, end as u32));
            start = end;
        }
        HashGrid { cells, radius }
    }

    fn for_each_near(&self, photons: &[Photon], p: Vec3A, mut f: impl FnMut(&Photon)) {
        let r2 = self.radius * self.radius;
        let c = (p / self.radius).floor();
        let (cx, cy, cz) = (c.x as i32, c.y as i32, c.z as i32);
        for z in cz - 1..=cz + 1 {
            for y in cy - 1..=cy + 1 {
                for x in cx - 1..=cx + 1 {
                    if let Some(&(a, b)) = self.cells.get(&(x, y, z)) {
                        for ph in &photons[a as usize..b as usize] {
                            if (ph.p - p).length_squared() <= r2 {
                                f(ph);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::TrackingRng;

    fn photons(n: usize) -> Vec<Photon> {
        let mut rng = TrackingRng::new(7);
        (0..n)
            .map(|i| Photon {
                p: Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
                wi: Vec3A::Z,
                n: Vec3A::ZERO,
                power: Color::splat(i as f32),
            })
            .collect()
    }

    /// The hash grid, the tree's radius query and a brute-force scan find the same photons;
    /// the k-nearest gather finds the k closest and reports the k-th distance.
    #[test]
    fn indexes_agree_with_brute_force() {
        let all = photons(5000);
        let grid = PhotonMap::new(all.clone(), Gather::Radius(0.1), Some(Index::HashGrid));
        let tree = PhotonMap::new(all.clone(), Gather::Radius(0.1), Some(Index::KdTree));
        let nearest = PhotonMap::new(
            all.clone(),
            Gather::Nearest {
                k: 20,
                max_radius: 0.5,
            },
            None,
        );
        let mut rng = TrackingRng::new(9);
        for _ in 0..100 {
            let q = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let mut want: Vec<u32> = all
                .iter()
                .filter(|ph| (ph.p - q).length_squared() <= 0.01)
                .map(|ph| ph.power.x as u32)
                .collect();
            want.sort();
            for map in [&grid, &tree] {
                let mut got = Vec::new();
                let r = map.gather(q, |ph| got.push(ph.power.x as u32));
                got.sort();
                assert_eq!(got, want);
                assert_eq!(r, 0.1);
            }
            let mut d: Vec<(f32, u32)> = all
                .iter()
                .map(|ph| ((ph.p - q).length(), ph.power.x as u32))
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0));
            let mut got = Vec::new();
            let r = nearest.gather(q, |ph| got.push(ph.power.x as u32));
            got.sort();
            let mut want: Vec<u32> = d[..20].iter().map(|x| x.1).collect();
            want.sort();
            assert_eq!(got, want);
            assert!((r - d[19].0).abs() < 1e-5, "{r} vs {}", d[19].0);
        }
        // Fewer than k within the maximum radius: those, and the maximum radius.
        let sparse = PhotonMap::new(
            all,
            Gather::Nearest {
                k: 20,
                max_radius: 0.02,
            },
            None,
        );
        let mut count = 0;
        let r = sparse.gather(Vec3A::splat(0.5), |_| count += 1);
        assert!(count < 20);
        assert_eq!(r, 0.02);
    }
}
