//! NanoVDB files (pbrt-v4's "nanovdb" medium): float grids read from the file layout of
//! NanoVDB 32.0 to 32.3, the one pbrt-v4 is built with, uncompressed or ZIP-compressed;
//! and written, for tests and scene generators.
//!
//! The format, as NanoVDB's `NanoVDB.h` and `util/IO.h` document it (little-endian):
//! - a file is segments; a segment is a 16-byte header (magic "NanoVDB0", version, grid
//!   count, codec), one 176-byte metadata record per grid followed by its NUL-terminated
//!   name, then the grids' buffers in order (each `fileSize` bytes: the raw buffer, or a
//!   u64 byte count and a zlib stream for ZIP);
//! - a grid buffer is a 672-byte grid record (map, world box, class, type), a 64-byte tree
//!   record (node offsets and counts), the root (a 64-byte record and 32-byte tiles keyed by
//!   coordinate), then internal nodes of 32³ and 16³ children and 8³ leaves, each child
//!   found by a signed byte offset from its parent.
//!
//! Every offset is checked against the buffer before it is read: a corrupt or hostile file
//! is an error, never a panic or a read out of bounds.

mod writer;

pub use writer::{GridToWrite, write_nanovdb};

use std::collections::HashMap;

/// "NanoVDB0", little-endian: the magic of a segment and of a grid record.
const MAGIC: u64 = 0x3042_4456_6f6e_614e;
/// "NanoVDB2": the file magic of NanoVDB 32.6 and later, a layout Kiln does not read.
const MAGIC_NEW_FILE: u64 = 0x3242_4456_6f6e_614e;
const MAJOR: u32 = 32;
/// The newest minor version whose layout this reader knows (pbrt-v4's NanoVDB is 32.3.3).
const NEWEST_MINOR: u32 = 3;

const SEGMENT_HEADER: usize = 16;
const METADATA: usize = 176;
const GRID_DATA: usize = 672;
const TREE_DATA: usize = 64;
const ROOT_DATA: usize = 64;
const ROOT_TILE: usize = 32;
/// Internal node with 32³ children: box, flags, two 4096-byte masks, stats, then the table.
const UPPER_MASKS: usize = 32;
const UPPER_TABLE: usize = 8256;
const UPPER_SIZE: usize = UPPER_TABLE + 8 * 32768;
/// Internal node with 16³ children.
const LOWER_MASKS: usize = 32;
const LOWER_TABLE: usize = 1088;
const LOWER_SIZE: usize = LOWER_TABLE + 8 * 4096;
/// Leaf of 8³ floats.
const LEAF_VALUES: usize = 96;
const LEAF_SIZE: usize = LEAF_VALUES + 4 * 512;

const GRID_TYPE_FLOAT: u32 = 1;
const CODEC_NONE: u16 = 0;
const CODEC_ZIP: u16 = 1;
const CODEC_BLOSC: u16 = 2;

/// NanoVDB's grid classes (those pbrt-v4 accepts for a medium: unknown and fog volume).
pub const CLASS_UNKNOWN: u32 = 0;
pub const CLASS_FOG_VOLUME: u32 = 2;

/// A grid's map from index space to world space, in single precision as pbrt-v4 looks grids
/// up: `world = mat · index + vec`, `index = inv · (world − vec)`, matrices row-major.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexMap {
    pub mat: [f32; 9],
    pub inv: [f32; 9],
    pub vec: [f32; 3],
}

impl IndexMap {
    /// The map of a grid with voxels of `size` whose index origin sits at `origin`.
    pub fn scale_translate(size: [f64; 3], origin: [f64; 3]) -> IndexMap {
        let mut mat = [0.0; 9];
        let mut inv = [0.0; 9];
        for a in 0..3 {
            mat[a * 4] = size[a] as f32;
            inv[a * 4] = (1.0 / size[a]) as f32;
        }
        IndexMap {
            mat,
            inv,
            vec: origin.map(|v| v as f32),
        }
    }

    pub fn world_to_index(&self, w: [f32; 3]) -> [f32; 3] {
        let d = [w[0] - self.vec[0], w[1] - self.vec[1], w[2] - self.vec[2]];
        let m = &self.inv;
        [0, 1, 2].map(|r| m[r * 3] * d[0] + m[r * 3 + 1] * d[1] + m[r * 3 + 2] * d[2])
    }
}

/// A float grid of a NanoVDB file, its tree kept as the file's bytes and looked up in place.
#[derive(Debug, Clone)]
pub struct NanoVdbGrid {
    pub name: String,
    /// [`CLASS_FOG_VOLUME`], [`CLASS_UNKNOWN`], or another NanoVDB class.
    pub class: u32,
    pub map: IndexMap,
    /// The world-space box of the active voxels, as the file records it (min, max).
    pub world_bbox: ([f64; 3], [f64; 3]),
    /// The index-space box of the active voxels, both corners inclusive.
    pub index_bbox: ([i32; 3], [i32; 3]),
    buf: Vec<u8>,
    background: f32,
    /// Root tiles by key: a child's byte offset in `buf`, or a constant value.
    tiles: HashMap<u64, Node>,
}

#[derive(Debug, Clone, Copy)]
enum Node {
    Child(usize),
    Value(f32),
}

/// A byte buffer read with bounds checks.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn get<const N: usize>(&self, at: usize) -> Result<[u8; N], String> {
        at.checked_add(N)
            .and_then(|end| self.0.get(at..end))
            .map(|s| s.try_into().unwrap())
            .ok_or_else(|| {
                format!(
                    "truncated or corrupt: a read at byte {at} passes the end ({} bytes)",
                    self.0.len()
                )
            })
    }
    fn u16(&self, at: usize) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.get(at)?))
    }
    fn u32(&self, at: usize) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.get(at)?))
    }
    fn i32(&self, at: usize) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.get(at)?))
    }
    fn u64(&self, at: usize) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.get(at)?))
    }
    fn i64(&self, at: usize) -> Result<i64, String> {
        Ok(i64::from_le_bytes(self.get(at)?))
    }
    fn f32(&self, at: usize) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.get(at)?))
    }
    fn f64(&self, at: usize) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.get(at)?))
    }
}

fn version_text(v: u32) -> String {
    format!("{}.{}.{}", v >> 21, (v >> 10) & 0x7ff, v & 0x3ff)
}

/// Refuses a version whose layout this reader does not know.
fn check_version(v: u32) -> Result<(), String> {
    if v >> 21 != MAJOR || (v >> 10) & 0x7ff > NEWEST_MINOR {
        return Err(format!(
            "written by NanoVDB {}; Kiln reads the layout of NanoVDB 32.0 to 32.{NEWEST_MINOR} (the one pbrt-v4 is built with)",
            version_text(v)
        ));
    }
    Ok(())
}

/// The root key of the 4096³ region holding `ijk` (NanoVDB's single 64-bit root key).
fn root_key(ijk: [i32; 3]) -> u64 {
    let k = |v: i32| u64::from((v as u32) >> 12);
    k(ijk[2]) | (k(ijk[1]) << 21) | (k(ijk[0]) << 42)
}

/// The names of the grids in a NanoVDB file, for an error that lists them.
pub fn grid_names(bytes: &[u8]) -> Result<Vec<String>, String> {
    let mut names = Vec::new();
    for_each_grid(bytes, |name, _| {
        names.push(name.to_string());
        Ok(false)
    })?;
    Ok(names)
}

/// Reads the first float grid named `name` from a NanoVDB file's bytes; `None` if the file has
/// no grid of that name.
pub fn read_grid(bytes: &[u8], name: &str) -> Result<Option<NanoVdbGrid>, String> {
    let mut found = None;
    for_each_grid(bytes, |grid_name, load| {
        if grid_name != name {
            return Ok(false);
        }
        found = Some(parse_grid(load()?, name)?);
        Ok(true)
    })?;
    Ok(found)
}

/// Calls `visit(name, load)` for each grid of the file in order until it returns true;
/// `load` decompresses that grid's buffer.
fn for_each_grid(
    bytes: &[u8],
    mut visit: impl FnMut(&str, &dyn Fn() -> Result<Vec<u8>, String>) -> Result<bool, String>,
) -> Result<(), String> {
    let b = Bytes(bytes);
    let mut at = 0usize;
    if bytes.is_empty() {
        return Err("the file is empty".into());
    }
    while at < bytes.len() {
        let magic = b.u64(at)?;
        if magic != MAGIC {
            return Err(match magic {
                MAGIC_NEW_FILE => "written in the file format of NanoVDB 32.6 or later (\"NanoVDB2\"); pbrt-v4 and Kiln read NanoVDB 32.3's (\"NanoVDB0\"): save it with an older NanoVDB".into(),
                m if m == MAGIC.swap_bytes() => "written big-endian; NanoVDB files are little-endian".into(),
                _ if at == 0 => "not a NanoVDB file (it does not start with \"NanoVDB0\")".into(),
                _ => format!("corrupt: no segment header at byte {at}"),
            });
        }
        check_version(b.u32(at + 8)?)?;
        let count = b.u16(at + 12)? as usize;
        let codec = b.u16(at + 14)?;
        match codec {
            CODEC_NONE | CODEC_ZIP => {}
            CODEC_BLOSC => {
                return Err("Blosc-compressed; Kiln reads uncompressed and ZIP NanoVDB files (pbrt-v4 reads only uncompressed ones)".into());
            }
            other => return Err(format!("unknown compression codec {other}")),
        }
        at += SEGMENT_HEADER;
        let mut grids = Vec::with_capacity(count.min(1024));
        for _ in 0..count {
            let grid_size = b.u64(at)?;
            let file_size = b.u64(at + 8)?;
            let grid_type = b.u32(at + 32)?;
            let name_size = b.u32(at + 136)? as usize;
            let name_at = at + METADATA;
            let raw_name = name_at
                .checked_add(name_size)
                .and_then(|end| bytes.get(name_at..end))
                .ok_or_else(|| format!("truncated: a grid name at byte {name_at}"))?;
            let name = String::from_utf8_lossy(raw_name.split(|c| *c == 0).next().unwrap_or(&[]))
                .into_owned();
            grids.push((name, grid_size, file_size, grid_type));
            at = name_at + name_size;
        }
        for (name, grid_size, file_size, grid_type) in grids {
            let start = at;
            let end = usize::try_from(file_size)
                .ok()
                .and_then(|s| start.checked_add(s))
                .filter(|e| *e <= bytes.len())
                .ok_or_else(|| {
                    format!(
                        "truncated: grid '{name}' needs {file_size} bytes from byte {start}, the file has {}",
                        bytes.len()
                    )
                })?;
            let stored = &bytes[start..end];
            let load = || -> Result<Vec<u8>, String> {
                if grid_type != GRID_TYPE_FLOAT {
                    return Err(format!(
                        "grid '{name}' holds {} values; a medium needs a float grid",
                        type_name(grid_type)
                    ));
                }
                let size = usize::try_from(grid_size)
                    .ok()
                    .filter(|s| *s as u64 <= crate::files::MAX_DECOMPRESSED_BYTES)
                    .ok_or_else(|| {
                        format!("grid '{name}' claims {grid_size} bytes, more than Kiln reads")
                    })?;
                let buf = match codec {
                    CODEC_ZIP => {
                        let sb = Bytes(stored);
                        let n = sb.u64(0)? as usize;
                        let data = stored
                            .get(8..8usize.saturating_add(n))
                            .ok_or_else(|| format!("truncated: grid '{name}''s compressed data"))?;
                        use std::io::Read;
                        // No reservation from the size the file claims: `take` bounds the
                        // growth, and a small hostile file allocates only what it inflates to.
                        let mut out = Vec::new();
                        flate2::read::ZlibDecoder::new(data)
                            .take(size as u64 + 1)
                            .read_to_end(&mut out)
                            .map_err(|e| format!("grid '{name}': the ZIP data is corrupt: {e}"))?;
                        out
                    }
                    _ => stored.to_vec(),
                };
                if buf.len() != size {
                    return Err(format!(
                        "grid '{name}' is {} bytes; its metadata says {size}",
                        buf.len()
                    ));
                }
                Ok(buf)
            };
            if visit(&name, &load)? {
                return Ok(());
            }
            at = end;
        }
    }
    Ok(())
}

fn type_name(t: u32) -> &'static str {
    const NAMES: [&str; 19] = [
        "unknown", "float", "double", "int16", "int32", "int64", "Vec3f", "Vec3d", "mask", "half",
        "uint32", "bool", "RGBA8", "Fp4", "Fp8", "Fp16", "FpN", "Vec4f", "Vec4d",
    ];
    NAMES.get(t as usize).copied().unwrap_or("unknown-type")
}

fn parse_grid(buf: Vec<u8>, name: &str) -> Result<NanoVdbGrid, String> {
    let b = Bytes(&buf);
    if b.u64(0)? != MAGIC {
        return Err(format!("grid '{name}': its record has no NanoVDB magic"));
    }
    check_version(b.u32(16)?)?;
    let grid_type = b.u32(636)?;
    if grid_type != GRID_TYPE_FLOAT {
        return Err(format!(
            "grid '{name}' holds {} values; a medium needs a float grid",
            type_name(grid_type)
        ));
    }
    let class = b.u32(632)?;
    let f32s = |at: usize| -> Result<[f32; 9], String> {
        let mut m = [0.0; 9];
        for (i, v) in m.iter_mut().enumerate() {
            *v = b.f32(at + 4 * i)?;
        }
        Ok(m)
    };
    let map = IndexMap {
        mat: f32s(296)?,
        inv: f32s(332)?,
        vec: [b.f32(368)?, b.f32(372)?, b.f32(376)?],
    };
    let f64x3 = |at: usize| -> Result<[f64; 3], String> {
        Ok([b.f64(at)?, b.f64(at + 8)?, b.f64(at + 16)?])
    };
    let world_bbox = (f64x3(560)?, f64x3(584)?);
    let tree = GRID_DATA;
    let root = usize::try_from(b.u64(tree + 24)?)
        .ok()
        .and_then(|o| tree.checked_add(o))
        .filter(|r| r.saturating_add(ROOT_DATA) <= buf.len())
        .ok_or_else(|| format!("grid '{name}': the root node's offset is out of the buffer"))?;
    let i32x3 = |at: usize| -> Result<[i32; 3], String> {
        Ok([b.i32(at)?, b.i32(at + 4)?, b.i32(at + 8)?])
    };
    let index_bbox = (i32x3(root)?, i32x3(root + 12)?);
    let table_size = b.u32(root + 24)? as usize;
    let background = b.f32(root + 28)?;
    if table_size
        .checked_mul(ROOT_TILE)
        .and_then(|s| s.checked_add(root + ROOT_DATA))
        .is_none_or(|end| end > buf.len())
    {
        return Err(format!(
            "grid '{name}': the root's {table_size} tiles pass the end of the buffer"
        ));
    }
    let mut tiles = HashMap::with_capacity(table_size);
    for t in 0..table_size {
        let at = root + ROOT_DATA + t * ROOT_TILE;
        let key = b.u64(at)?;
        let child = b.i64(at + 8)?;
        let node = if child != 0 {
            Node::Child(child_at(root, child, UPPER_SIZE, buf.len(), name)?)
        } else {
            Node::Value(b.f32(at + 20)?)
        };
        tiles.entry(key).or_insert(node);
    }
    for (a, m) in world_bbox.0.iter().chain(&world_bbox.1).enumerate() {
        if !m.is_finite() {
            return Err(format!(
                "grid '{name}': its world box has a value {m} (coordinate {a}) that is not finite"
            ));
        }
    }
    if map
        .inv
        .iter()
        .chain(&map.mat)
        .chain(&map.vec)
        .any(|v| !v.is_finite())
    {
        return Err(format!(
            "grid '{name}': its index-to-world map is not finite"
        ));
    }
    Ok(NanoVdbGrid {
        name: name.to_string(),
        class,
        map,
        world_bbox,
        index_bbox,
        background,
        tiles,
        buf,
    })
}

/// The absolute offset of a child `offset` bytes from its parent at `parent`, checked to leave
/// room for a node of `size` bytes.
fn child_at(
    parent: usize,
    offset: i64,
    size: usize,
    len: usize,
    name: &str,
) -> Result<usize, String> {
    (parent as i64)
        .checked_add(offset)
        .and_then(|a| usize::try_from(a).ok())
        .filter(|a| a.saturating_add(size) <= len)
        .ok_or_else(|| {
            format!("grid '{name}': a child node's offset {offset} is out of the buffer")
        })
}

/// What an 8³ block of the index space holds.
enum Block {
    /// A leaf: its values start at this byte.
    Leaf(usize),
    Constant(f32),
}

impl NanoVdbGrid {
    fn bytes(&self) -> Bytes<'_> {
        Bytes(&self.buf)
    }

    /// The value at an index-space point, as NanoVDB's accessor returns it (inactive voxels
    /// keep what the file stores; outside the tree, the background).
    pub fn value(&self, ijk: [i32; 3]) -> Result<f32, String> {
        let i = |v: i32| (v & 7) as usize;
        Ok(match self.block(ijk)? {
            Block::Constant(v) => v,
            Block::Leaf(at) => self
                .bytes()
                .f32(at + 4 * ((i(ijk[0]) << 6) | (i(ijk[1]) << 3) | i(ijk[2])))?,
        })
    }

    /// Finds the leaf or tile holding `ijk`.
    fn block(&self, ijk: [i32; 3]) -> Result<Block, String> {
        let b = self.bytes();
        let upper = match self.tiles.get(&root_key(ijk)) {
            None => return Ok(Block::Constant(self.background)),
            Some(Node::Value(v)) => return Ok(Block::Constant(*v)),
            Some(Node::Child(at)) => *at,
        };
        let bit = |masks: usize, n: usize| -> Result<bool, String> {
            Ok(b.u64(masks + 8 * (n >> 6))? >> (n & 63) & 1 == 1)
        };
        let o = |v: i32, mask: i32, shift: u32| ((v & mask) >> shift) as usize;
        let n = (o(ijk[0], 4095, 7) << 10) | (o(ijk[1], 4095, 7) << 5) | o(ijk[2], 4095, 7);
        // The child mask follows the value mask (4096 bytes for 32³ children).
        let table = upper + UPPER_TABLE + 8 * n;
        if !bit(upper + UPPER_MASKS + 4096, n)? {
            return Ok(Block::Constant(b.f32(table)?));
        }
        let lower = child_at(upper, b.i64(table)?, LOWER_SIZE, self.buf.len(), &self.name)?;
        let n = (o(ijk[0], 127, 3) << 8) | (o(ijk[1], 127, 3) << 4) | o(ijk[2], 127, 3);
        let table = lower + LOWER_TABLE + 8 * n;
        if !bit(lower + LOWER_MASKS + 512, n)? {
            return Ok(Block::Constant(b.f32(table)?));
        }
        let leaf = child_at(lower, b.i64(table)?, LEAF_SIZE, self.buf.len(), &self.name)?;
        Ok(Block::Leaf(leaf + LEAF_VALUES))
    }

    /// The values over the index-space box from `lo` with `dims` samples per axis, x fastest,
    /// then y, then z (Kiln's voxel-grid order); one tree descent per 8³ block.
    pub fn dense(&self, lo: [i32; 3], dims: [usize; 3]) -> Result<Vec<f32>, String> {
        let total = dims[0]
            .checked_mul(dims[1])
            .and_then(|v| v.checked_mul(dims[2]))
            .filter(|v| *v <= 1 << 28)
            .ok_or_else(|| {
                format!(
                    "grid '{}': a {}x{}x{} region is more than Kiln samples (2^28 values)",
                    self.name, dims[0], dims[1], dims[2]
                )
            })?;
        let hi: [i64; 3] = [0, 1, 2].map(|a| lo[a] as i64 + dims[a] as i64);
        if hi.iter().any(|h| *h > i32::MAX as i64 + 1) {
            return Err(format!(
                "grid '{}': the region passes the index range",
                self.name
            ));
        }
        let mut out = vec![0.0f32; total];
        let b = self.bytes();
        let first = |a: usize| (lo[a] as i64).div_euclid(8) * 8;
        let mut bz = first(2);
        while bz < hi[2] {
            let mut by = first(1);
            while by < hi[1] {
                let mut bx = first(0);
                while bx < hi[0] {
                    let block = self.block([bx as i32, by as i32, bz as i32])?;
                    let range = |o: i64, a: usize| o.max(lo[a] as i64)..(o + 8).min(hi[a]);
                    for z in range(bz, 2) {
                        for y in range(by, 1) {
                            for x in range(bx, 0) {
                                let v = match block {
                                    Block::Constant(v) => v,
                                    Block::Leaf(at) => {
                                        let i = ((x & 7) << 6 | (y & 7) << 3 | (z & 7)) as usize;
                                        b.f32(at + 4 * i)?
                                    }
                                };
                                let (dx, dy, dz) = (
                                    (x - lo[0] as i64) as usize,
                                    (y - lo[1] as i64) as usize,
                                    (z - lo[2] as i64) as usize,
                                );
                                out[(dz * dims[1] + dy) * dims[0] + dx] = v;
                            }
                        }
                    }
                    bx += 8;
                }
                by += 8;
            }
            bz += 8;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests;
