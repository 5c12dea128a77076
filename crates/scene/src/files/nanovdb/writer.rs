//! Writing NanoVDB files: the counterpart of the reader, for tests and scene generators.
//! Each grid is laid out as NanoVDB lays it out (breadth first: root, upper nodes, lower
//! nodes, leaves), so the reader is tested against the format, not against itself.

use super::{
    Bytes, CODEC_NONE, CODEC_ZIP, GRID_DATA, GRID_TYPE_FLOAT, IndexMap, LEAF_SIZE, LEAF_VALUES,
    LOWER_MASKS, LOWER_SIZE, LOWER_TABLE, MAGIC, MAJOR, METADATA, NEWEST_MINOR, ROOT_DATA,
    ROOT_TILE, TREE_DATA, UPPER_MASKS, UPPER_SIZE, UPPER_TABLE, root_key,
};
use std::collections::{BTreeMap, HashMap};

/// A grid to write: dense values over the index box from `lo` with `dims` samples (x fastest),
/// zero beyond it; a voxel is active where it is not zero, and an 8³ block whose values are
/// all one non-zero value is written as a tile of its parent, as NanoVDB does.
#[derive(Debug, Clone)]
pub struct GridToWrite<'a> {
    pub name: &'a str,
    pub class: u32,
    pub voxel_size: [f64; 3],
    pub origin: [f64; 3],
    pub lo: [i32; 3],
    pub dims: [usize; 3],
    pub values: &'a [f32],
}

/// Writes grids as one segment of a NanoVDB 32.3 file, uncompressed or (`zip`) with each grid
/// zlib-compressed; the counterpart of [`read_grid`], for tests and scene generators.
pub fn write_nanovdb(grids: &[GridToWrite], zip: bool) -> Vec<u8> {
    let version: u32 = (MAJOR << 21) | (NEWEST_MINOR << 10) | 3;
    let buffers: Vec<(Vec<u8>, Vec<u8>)> = grids
        .iter()
        .map(|g| {
            // Each grid is its own buffer (NanoVDB's one grid per handle): index 0 of 1.
            // Readers walk a buffer by these, so anything else sends them past its end.
            let raw = grid_buffer(g, 0, 1, version);
            let stored = if zip {
                use std::io::Write;
                let mut e =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                e.write_all(&raw).unwrap();
                let c = e.finish().unwrap();
                let mut s = (c.len() as u64).to_le_bytes().to_vec();
                s.extend(c);
                s
            } else {
                raw.clone()
            };
            (raw, stored)
        })
        .collect();
    let mut out = Vec::new();
    out.extend(MAGIC.to_le_bytes());
    out.extend(version.to_le_bytes());
    out.extend((grids.len() as u16).to_le_bytes());
    out.extend(if zip { CODEC_ZIP } else { CODEC_NONE }.to_le_bytes());
    for (g, (raw, stored)) in grids.iter().zip(&buffers) {
        let rb = Bytes(raw);
        let mut m = Vec::with_capacity(METADATA);
        m.extend((raw.len() as u64).to_le_bytes());
        m.extend((stored.len() as u64).to_le_bytes());
        m.extend(name_hash(g.name).to_le_bytes());
        m.extend(rb.u64(GRID_DATA + 56).unwrap().to_le_bytes()); // active voxels
        m.extend(GRID_TYPE_FLOAT.to_le_bytes());
        m.extend(g.class.to_le_bytes());
        m.extend(&raw[560..608]); // world box
        let root = GRID_DATA + rb.u64(GRID_DATA + 24).unwrap() as usize;
        m.extend(&raw[root..root + 24]); // index box
        m.extend(&raw[608..632]); // voxel size
        m.extend((g.name.len() as u32 + 1).to_le_bytes());
        m.extend(&raw[GRID_DATA + 32..GRID_DATA + 44]); // node counts
        m.extend(1u32.to_le_bytes()); // one root
        m.extend(&raw[GRID_DATA + 44..GRID_DATA + 56]); // tile counts
        m.extend(if zip { CODEC_ZIP } else { CODEC_NONE }.to_le_bytes());
        m.extend(0u16.to_le_bytes());
        m.extend(version.to_le_bytes());
        debug_assert_eq!(m.len(), METADATA);
        out.extend(m);
        out.extend(g.name.as_bytes());
        out.push(0);
    }
    for (_, stored) in buffers {
        out.extend(stored);
    }
    out
}

/// NanoVDB's hash of a grid name (its file metadata's `nameKey`).
pub(super) fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0u64, |h, c| {
        let overflow = h >> 56;
        h.wrapping_mul(67).wrapping_add(c as u64 + overflow)
    })
}

fn put<const N: usize>(buf: &mut [u8], at: usize, bytes: [u8; N]) {
    buf[at..at + N].copy_from_slice(&bytes);
}

fn put_box(buf: &mut [u8], at: usize, lo: [i32; 3], hi: [i32; 3]) {
    for a in 0..3 {
        put(buf, at + 4 * a, lo[a].to_le_bytes());
        put(buf, at + 12 + 4 * a, hi[a].to_le_bytes());
    }
}

fn set_bit(buf: &mut [u8], masks: usize, n: usize) {
    buf[masks + n / 8] |= 1 << (n % 8);
}

/// Active box of a set of index points: (min, max) inclusive, or None when empty.
type IBox = Option<([i32; 3], [i32; 3])>;

fn grow(b: &mut IBox, lo: [i32; 3], hi: [i32; 3]) {
    *b = Some(match *b {
        None => (lo, hi),
        Some((l, h)) => (
            [0, 1, 2].map(|a| l[a].min(lo[a])),
            [0, 1, 2].map(|a| h[a].max(hi[a])),
        ),
    });
}

/// An 8³ block of a grid to write: a leaf's 512 values, or a constant tile.
enum Block {
    Leaf(Vec<f32>),
    Tile(f32),
}

/// The grid's 8³ blocks that are not all zero, by their first voxel.
fn blocks_of(g: &GridToWrite) -> BTreeMap<[i32; 3], Block> {
    let at = |x: i64, y: i64, z: i64| -> f32 {
        let (dx, dy, dz) = (x - g.lo[0] as i64, y - g.lo[1] as i64, z - g.lo[2] as i64);
        if dx < 0 || dy < 0 || dz < 0 {
            return 0.0;
        }
        let (dx, dy, dz) = (dx as usize, dy as usize, dz as usize);
        if dx >= g.dims[0] || dy >= g.dims[1] || dz >= g.dims[2] {
            return 0.0;
        }
        g.values[(dz * g.dims[1] + dy) * g.dims[0] + dx]
    };
    let mut blocks = BTreeMap::new();
    let first = |a: usize| (g.lo[a] as i64).div_euclid(8) * 8;
    let end = |a: usize| g.lo[a] as i64 + g.dims[a] as i64;
    let mut z = first(2);
    while z < end(2) {
        let mut y = first(1);
        while y < end(1) {
            let mut x = first(0);
            while x < end(0) {
                let mut v = Vec::with_capacity(512);
                for i in 0..8 {
                    for j in 0..8 {
                        for k in 0..8 {
                            v.push(at(x + i, y + j, z + k));
                        }
                    }
                }
                let key = [x as i32, y as i32, z as i32];
                if v.iter().all(|s| *s == v[0]) {
                    if v[0] != 0.0 {
                        blocks.insert(key, Block::Tile(v[0]));
                    }
                } else {
                    blocks.insert(key, Block::Leaf(v));
                }
                x += 8;
            }
            y += 8;
        }
        z += 8;
    }
    blocks
}

/// Where each node of a grid's tree goes in its buffer.
struct Layout {
    /// Lower nodes (128³ voxels) by origin, with their blocks; upper nodes (4096³) by
    /// origin, with their lower nodes; the leaves in order.
    lowers: BTreeMap<[i32; 3], Vec<[i32; 3]>>,
    uppers: BTreeMap<[i32; 3], Vec<[i32; 3]>>,
    leaves: Vec<[i32; 3]>,
    root: usize,
    upper0: usize,
    lower0: usize,
    leaf0: usize,
    size: usize,
    upper_at: HashMap<[i32; 3], usize>,
    lower_at: HashMap<[i32; 3], usize>,
    leaf_at: HashMap<[i32; 3], usize>,
}

impl Layout {
    fn of(blocks: &BTreeMap<[i32; 3], Block>) -> Layout {
        let origin = |k: [i32; 3], mask: i32| k.map(|v| v & !mask);
        let lowers: BTreeMap<[i32; 3], Vec<[i32; 3]>> =
            blocks.keys().fold(BTreeMap::new(), |mut m, k| {
                m.entry(origin(*k, 127)).or_default().push(*k);
                m
            });
        let uppers: BTreeMap<[i32; 3], Vec<[i32; 3]>> =
            lowers.keys().fold(BTreeMap::new(), |mut m, k| {
                m.entry(origin(*k, 4095)).or_default().push(*k);
                m
            });
        let leaves: Vec<[i32; 3]> = lowers
            .values()
            .flatten()
            .filter(|k| matches!(blocks[*k], Block::Leaf(_)))
            .copied()
            .collect();
        let root = GRID_DATA + TREE_DATA;
        let upper0 = root + ROOT_DATA + ROOT_TILE * uppers.len();
        let lower0 = upper0 + UPPER_SIZE * uppers.len();
        let leaf0 = lower0 + LOWER_SIZE * lowers.len();
        let size = leaf0 + LEAF_SIZE * leaves.len();
        let offsets = |keys: &mut dyn Iterator<Item = &[i32; 3]>, first: usize, each: usize| {
            keys.enumerate()
                .map(|(i, k)| (*k, first + i * each))
                .collect::<HashMap<_, _>>()
        };
        Layout {
            upper_at: offsets(&mut uppers.keys(), upper0, UPPER_SIZE),
            lower_at: offsets(&mut lowers.keys(), lower0, LOWER_SIZE),
            leaf_at: offsets(&mut leaves.iter(), leaf0, LEAF_SIZE),
            lowers,
            uppers,
            leaves,
            root,
            upper0,
            lower0,
            leaf0,
            size,
        }
    }
}

/// What a grid's records say of its values: their range, the active voxels, the lower
/// nodes' tiles.
struct Tally {
    vmin: f32,
    vmax: f32,
    active: u64,
    lower_tiles: u32,
}

impl Tally {
    fn count(&mut self, v: f32, voxels: u64) {
        self.active += voxels;
        (self.vmin, self.vmax) = (self.vmin.min(v), self.vmax.max(v));
    }
}

/// One grid's buffer: grid record, tree record, root and tiles, then upper nodes, lower
/// nodes and leaves, breadth first.
fn grid_buffer(g: &GridToWrite, index: u32, count: u32, version: u32) -> Vec<u8> {
    let blocks = blocks_of(g);
    let layout = Layout::of(&blocks);
    let mut buf = vec![0u8; layout.size];
    let mut tally = Tally {
        vmin: f32::INFINITY,
        vmax: f32::NEG_INFINITY,
        active: 0,
        lower_tiles: 0,
    };
    let lower_boxes = write_lowers(&mut buf, &layout, &blocks, &mut tally);
    let all_box = write_uppers(&mut buf, &layout, &lower_boxes);
    let (ilo, ihi) = all_box.unwrap_or(([0; 3], [0; 3]));
    write_root(&mut buf, &layout, (ilo, ihi), &tally);
    write_tree_record(&mut buf, &layout, &tally);
    write_grid_record(
        &mut buf,
        g,
        [index, count, version],
        layout.size,
        (ilo, ihi),
    );
    buf
}

/// The lower nodes' tables and their leaves; returns each lower node's active box.
fn write_lowers(
    buf: &mut [u8],
    layout: &Layout,
    blocks: &BTreeMap<[i32; 3], Block>,
    tally: &mut Tally,
) -> HashMap<[i32; 3], IBox> {
    let mut lower_boxes = HashMap::new();
    for (lk, children) in &layout.lowers {
        let l = layout.lower_at[lk];
        let mut lbox: IBox = None;
        for bk in children {
            let n = ((((bk[0] & 127) >> 3) << 8)
                | (((bk[1] & 127) >> 3) << 4)
                | ((bk[2] & 127) >> 3)) as usize;
            match &blocks[bk] {
                Block::Tile(v) => {
                    put(buf, l + LOWER_TABLE + 8 * n, v.to_le_bytes());
                    set_bit(buf, l + LOWER_MASKS, n);
                    grow(&mut lbox, *bk, bk.map(|c| c + 7));
                    tally.count(*v, 512);
                    tally.lower_tiles += 1;
                }
                Block::Leaf(values) => {
                    let f = layout.leaf_at[bk];
                    put(buf, l + LOWER_TABLE + 8 * n, ((f - l) as i64).to_le_bytes());
                    set_bit(buf, l + LOWER_MASKS + 512, n);
                    if let Some((lo, hi)) = write_leaf(buf, f, *bk, values, tally) {
                        grow(&mut lbox, lo, hi);
                    }
                }
            }
        }
        let (lo, hi) = lbox.unwrap_or((*lk, *lk));
        put_box(buf, l, lo, hi);
        lower_boxes.insert(*lk, lbox);
    }
    lower_boxes
}

/// One leaf at `f`, its block at `bk`; returns its active box.
fn write_leaf(buf: &mut [u8], f: usize, bk: [i32; 3], values: &[f32], tally: &mut Tally) -> IBox {
    let mut fbox: IBox = None;
    for (i, v) in values.iter().enumerate() {
        put(buf, f + LEAF_VALUES + 4 * i, v.to_le_bytes());
        if *v != 0.0 {
            set_bit(buf, f + 16, i);
            let p = [
                bk[0] + (i >> 6) as i32,
                bk[1] + ((i >> 3) & 7) as i32,
                bk[2] + (i & 7) as i32,
            ];
            grow(&mut fbox, p, p);
            tally.count(*v, 1);
        }
    }
    let (flo, fhi) = fbox.unwrap_or((bk, bk));
    for a in 0..3 {
        put(buf, f + 4 * a, flo[a].to_le_bytes());
        buf[f + 12 + a] = (fhi[a] - flo[a]) as u8;
    }
    fbox
}

/// The upper nodes' tables; returns the active box of the whole grid.
fn write_uppers(buf: &mut [u8], layout: &Layout, lower_boxes: &HashMap<[i32; 3], IBox>) -> IBox {
    let mut all_box: IBox = None;
    for (uk, children) in &layout.uppers {
        let u = layout.upper_at[uk];
        let mut ubox: IBox = None;
        for lk in children {
            let n = ((((lk[0] & 4095) >> 7) << 10)
                | (((lk[1] & 4095) >> 7) << 5)
                | ((lk[2] & 4095) >> 7)) as usize;
            put(
                buf,
                u + UPPER_TABLE + 8 * n,
                ((layout.lower_at[lk] - u) as i64).to_le_bytes(),
            );
            set_bit(buf, u + UPPER_MASKS + 4096, n);
            if let Some((lo, hi)) = lower_boxes[lk] {
                grow(&mut ubox, lo, hi);
            }
        }
        let (lo, hi) = ubox.unwrap_or((*uk, *uk));
        put_box(buf, u, lo, hi);
        if let Some((lo, hi)) = ubox {
            grow(&mut all_box, lo, hi);
        }
    }
    all_box
}

/// The root record (index box, value range) and its tiles, one per upper node.
fn write_root(buf: &mut [u8], layout: &Layout, (ilo, ihi): ([i32; 3], [i32; 3]), tally: &Tally) {
    let root = layout.root;
    put_box(buf, root, ilo, ihi);
    put(buf, root + 24, (layout.uppers.len() as u32).to_le_bytes());
    put(buf, root + 28, 0f32.to_le_bytes());
    if tally.active > 0 {
        put(buf, root + 32, tally.vmin.to_le_bytes());
        put(buf, root + 36, tally.vmax.to_le_bytes());
    }
    for (i, uk) in layout.uppers.keys().enumerate() {
        let t = root + ROOT_DATA + ROOT_TILE * i;
        put(buf, t, root_key(*uk).to_le_bytes());
        put(
            buf,
            t + 8,
            ((layout.upper_at[uk] - root) as i64).to_le_bytes(),
        );
    }
}

/// The tree record: offsets from the tree to the first leaf, lower, upper node and root,
/// and the counts.
fn write_tree_record(buf: &mut [u8], layout: &Layout, tally: &Tally) {
    let tree = GRID_DATA;
    let off = |first: usize, any: bool| if any { (first - tree) as u64 } else { 0 };
    put(
        buf,
        tree,
        off(layout.leaf0, !layout.leaves.is_empty()).to_le_bytes(),
    );
    put(
        buf,
        tree + 8,
        off(layout.lower0, !layout.lowers.is_empty()).to_le_bytes(),
    );
    put(
        buf,
        tree + 16,
        off(layout.upper0, !layout.uppers.is_empty()).to_le_bytes(),
    );
    put(buf, tree + 24, ((layout.root - tree) as u64).to_le_bytes());
    put(buf, tree + 32, (layout.leaves.len() as u32).to_le_bytes());
    put(buf, tree + 36, (layout.lowers.len() as u32).to_le_bytes());
    put(buf, tree + 40, (layout.uppers.len() as u32).to_le_bytes());
    put(buf, tree + 44, tally.lower_tiles.to_le_bytes());
    put(buf, tree + 56, tally.active.to_le_bytes());
}

/// The grid record: identity, the index-to-world map and the world box of the active
/// voxels' index box.
fn write_grid_record(
    buf: &mut [u8],
    g: &GridToWrite,
    [index, count, version]: [u32; 3],
    size: usize,
    (ilo, ihi): ([i32; 3], [i32; 3]),
) {
    put(buf, 0, MAGIC.to_le_bytes());
    put(buf, 8, u64::MAX.to_le_bytes()); // no checksum
    put(buf, 16, version.to_le_bytes());
    put(buf, 20, (2u32 | 4 | 32).to_le_bytes()); // bbox, min/max, breadth first
    put(buf, 24, index.to_le_bytes());
    put(buf, 28, count.to_le_bytes());
    put(buf, 32, (size as u64).to_le_bytes());
    let name = g.name.as_bytes();
    buf[40..40 + name.len().min(255)].copy_from_slice(&name[..name.len().min(255)]);
    let map = IndexMap::scale_translate(g.voxel_size, g.origin);
    for i in 0..9 {
        put(buf, 296 + 4 * i, map.mat[i].to_le_bytes());
        put(buf, 332 + 4 * i, map.inv[i].to_le_bytes());
    }
    for a in 0..3 {
        put(buf, 368 + 4 * a, map.vec[a].to_le_bytes());
    }
    put(buf, 380, 1f32.to_le_bytes()); // taper
    for a in 0..3 {
        put(buf, 384 + 32 * a, g.voxel_size[a].to_le_bytes()); // mMatD diagonal
        put(buf, 456 + 32 * a, (1.0 / g.voxel_size[a]).to_le_bytes()); // mInvMatD
        put(buf, 528 + 8 * a, g.origin[a].to_le_bytes()); // mVecD
    }
    put(buf, 552, 1f64.to_le_bytes()); // taper
    for a in 0..3 {
        // The world box of the active voxels' index box [min, max + 1].
        let w0 = g.origin[a] + g.voxel_size[a] * ilo[a] as f64;
        let w1 = g.origin[a] + g.voxel_size[a] * (ihi[a] as f64 + 1.0);
        put(buf, 560 + 8 * a, w0.min(w1).to_le_bytes());
        put(buf, 584 + 8 * a, w0.max(w1).to_le_bytes());
        put(buf, 608 + 8 * a, g.voxel_size[a].to_le_bytes());
    }
    put(buf, 632, g.class.to_le_bytes());
    put(buf, 636, GRID_TYPE_FLOAT.to_le_bytes());
}
