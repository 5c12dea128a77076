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
fn name_hash(name: &str) -> u64 {
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

/// One grid's buffer: grid record, tree record, root and tiles, then upper nodes, lower
/// nodes and leaves, breadth first.
fn grid_buffer(g: &GridToWrite, index: u32, count: u32, version: u32) -> Vec<u8> {
    use std::collections::BTreeMap;
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
    // 8³ blocks: a leaf's 512 values, or a constant tile.
    enum Out {
        Leaf(Vec<f32>),
        Tile(f32),
    }
    let mut blocks: BTreeMap<[i32; 3], Out> = BTreeMap::new();
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
                        blocks.insert(key, Out::Tile(v[0]));
                    }
                } else {
                    blocks.insert(key, Out::Leaf(v));
                }
                x += 8;
            }
            y += 8;
        }
        z += 8;
    }
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
        .filter(|k| matches!(blocks[*k], Out::Leaf(_)))
        .copied()
        .collect();
    let root = GRID_DATA + TREE_DATA;
    let upper0 = root + ROOT_DATA + ROOT_TILE * uppers.len();
    let lower0 = upper0 + UPPER_SIZE * uppers.len();
    let leaf0 = lower0 + LOWER_SIZE * lowers.len();
    let size = leaf0 + LEAF_SIZE * leaves.len();
    let mut buf = vec![0u8; size];
    let upper_at: HashMap<[i32; 3], usize> = uppers
        .keys()
        .enumerate()
        .map(|(i, k)| (*k, upper0 + i * UPPER_SIZE))
        .collect();
    let lower_at: HashMap<[i32; 3], usize> = lowers
        .keys()
        .enumerate()
        .map(|(i, k)| (*k, lower0 + i * LOWER_SIZE))
        .collect();
    let leaf_at: HashMap<[i32; 3], usize> = leaves
        .iter()
        .enumerate()
        .map(|(i, k)| (*k, leaf0 + i * LEAF_SIZE))
        .collect();
    let (mut vmin, mut vmax) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut active = 0u64;
    let mut all_box: IBox = None;
    let mut lower_boxes: HashMap<[i32; 3], IBox> = HashMap::new();
    let mut lower_tiles = 0u32;
    // Leaves, and lower-node tables.
    for (lk, children) in &lowers {
        let l = lower_at[lk];
        let mut lbox: IBox = None;
        for bk in children {
            let n = ((((bk[0] & 127) >> 3) << 8)
                | (((bk[1] & 127) >> 3) << 4)
                | ((bk[2] & 127) >> 3)) as usize;
            match &blocks[bk] {
                Out::Tile(v) => {
                    put(&mut buf, l + LOWER_TABLE + 8 * n, v.to_le_bytes());
                    set_bit(&mut buf, l + LOWER_MASKS, n);
                    grow(&mut lbox, *bk, bk.map(|c| c + 7));
                    active += 512;
                    lower_tiles += 1;
                    (vmin, vmax) = (vmin.min(*v), vmax.max(*v));
                }
                Out::Leaf(values) => {
                    let f = leaf_at[bk];
                    put(
                        &mut buf,
                        l + LOWER_TABLE + 8 * n,
                        ((f - l) as i64).to_le_bytes(),
                    );
                    set_bit(&mut buf, l + LOWER_MASKS + 512, n);
                    let mut fbox: IBox = None;
                    for (i, v) in values.iter().enumerate() {
                        put(&mut buf, f + LEAF_VALUES + 4 * i, v.to_le_bytes());
                        if *v != 0.0 {
                            set_bit(&mut buf, f + 16, i);
                            let p = [
                                bk[0] + (i >> 6) as i32,
                                bk[1] + ((i >> 3) & 7) as i32,
                                bk[2] + (i & 7) as i32,
                            ];
                            grow(&mut fbox, p, p);
                            active += 1;
                            (vmin, vmax) = (vmin.min(*v), vmax.max(*v));
                        }
                    }
                    let (flo, fhi) = fbox.unwrap_or((*bk, *bk));
                    for a in 0..3 {
                        put(&mut buf, f + 4 * a, flo[a].to_le_bytes());
                        buf[f + 12 + a] = (fhi[a] - flo[a]) as u8;
                    }
                    if let Some((lo, hi)) = fbox {
                        grow(&mut lbox, lo, hi);
                    }
                }
            }
        }
        let (lo, hi) = lbox.unwrap_or((*lk, *lk));
        put_box(&mut buf, l, lo, hi);
        lower_boxes.insert(*lk, lbox);
    }
    // Upper nodes.
    for (uk, children) in &uppers {
        let u = upper_at[uk];
        let mut ubox: IBox = None;
        for lk in children {
            let n = ((((lk[0] & 4095) >> 7) << 10)
                | (((lk[1] & 4095) >> 7) << 5)
                | ((lk[2] & 4095) >> 7)) as usize;
            put(
                &mut buf,
                u + UPPER_TABLE + 8 * n,
                ((lower_at[lk] - u) as i64).to_le_bytes(),
            );
            set_bit(&mut buf, u + UPPER_MASKS + 4096, n);
            if let Some((lo, hi)) = lower_boxes[lk] {
                grow(&mut ubox, lo, hi);
            }
        }
        let (lo, hi) = ubox.unwrap_or((*uk, *uk));
        put_box(&mut buf, u, lo, hi);
        if let Some((lo, hi)) = ubox {
            grow(&mut all_box, lo, hi);
        }
    }
    // Root.
    let (ilo, ihi) = all_box.unwrap_or(([0; 3], [0; 3]));
    put_box(&mut buf, root, ilo, ihi);
    put(&mut buf, root + 24, (uppers.len() as u32).to_le_bytes());
    put(&mut buf, root + 28, 0f32.to_le_bytes());
    if active > 0 {
        put(&mut buf, root + 32, vmin.to_le_bytes());
        put(&mut buf, root + 36, vmax.to_le_bytes());
    }
    for (i, uk) in uppers.keys().enumerate() {
        let t = root + ROOT_DATA + ROOT_TILE * i;
        put(&mut buf, t, root_key(*uk).to_le_bytes());
        put(
            &mut buf,
            t + 8,
            ((upper_at[uk] - root) as i64).to_le_bytes(),
        );
    }
    // Tree record: offsets from the tree to the first leaf, lower, upper node and root.
    let tree = GRID_DATA;
    let off = |first: usize, any: bool| if any { (first - tree) as u64 } else { 0 };
    put(&mut buf, tree, off(leaf0, !leaves.is_empty()).to_le_bytes());
    put(
        &mut buf,
        tree + 8,
        off(lower0, !lowers.is_empty()).to_le_bytes(),
    );
    put(
        &mut buf,
        tree + 16,
        off(upper0, !uppers.is_empty()).to_le_bytes(),
    );
    put(&mut buf, tree + 24, ((root - tree) as u64).to_le_bytes());
    put(&mut buf, tree + 32, (leaves.len() as u32).to_le_bytes());
    put(&mut buf, tree + 36, (lowers.len() as u32).to_le_bytes());
    put(&mut buf, tree + 40, (uppers.len() as u32).to_le_bytes());
    put(&mut buf, tree + 44, lower_tiles.to_le_bytes());
    put(&mut buf, tree + 56, active.to_le_bytes());
    // Grid record.
    put(&mut buf, 0, MAGIC.to_le_bytes());
    put(&mut buf, 8, u64::MAX.to_le_bytes()); // no checksum
    put(&mut buf, 16, version.to_le_bytes());
    put(&mut buf, 20, (2u32 | 4 | 32).to_le_bytes()); // bbox, min/max, breadth first
    put(&mut buf, 24, index.to_le_bytes());
    put(&mut buf, 28, count.to_le_bytes());
    put(&mut buf, 32, (size as u64).to_le_bytes());
    let name = g.name.as_bytes();
    buf[40..40 + name.len().min(255)].copy_from_slice(&name[..name.len().min(255)]);
    let map = IndexMap::scale_translate(g.voxel_size, g.origin);
    for i in 0..9 {
        put(&mut buf, 296 + 4 * i, map.mat[i].to_le_bytes());
        put(&mut buf, 332 + 4 * i, map.inv[i].to_le_bytes());
    }
    for a in 0..3 {
        put(&mut buf, 368 + 4 * a, map.vec[a].to_le_bytes());
    }
    put(&mut buf, 380, 1f32.to_le_bytes()); // taper
    for a in 0..3 {
        put(&mut buf, 384 + 32 * a, g.voxel_size[a].to_le_bytes()); // mMatD diagonal
        put(
            &mut buf,
            456 + 32 * a,
            (1.0 / g.voxel_size[a]).to_le_bytes(),
        ); // mInvMatD
        put(&mut buf, 528 + 8 * a, g.origin[a].to_le_bytes()); // mVecD
    }
    put(&mut buf, 552, 1f64.to_le_bytes()); // taper
    for a in 0..3 {
        // The world box of the active voxels' index box [min, max + 1].
        let w0 = g.origin[a] + g.voxel_size[a] * ilo[a] as f64;
        let w1 = g.origin[a] + g.voxel_size[a] * (ihi[a] as f64 + 1.0);
        put(&mut buf, 560 + 8 * a, w0.min(w1).to_le_bytes());
        put(&mut buf, 584 + 8 * a, w0.max(w1).to_le_bytes());
        put(&mut buf, 608 + 8 * a, g.voxel_size[a].to_le_bytes());
    }
    put(&mut buf, 632, g.class.to_le_bytes());
    put(&mut buf, 636, GRID_TYPE_FLOAT.to_le_bytes());
    buf
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_grid() -> (Vec<f32>, [i32; 3], [usize; 3]) {
        let (lo, dims) = ([-13, 5, -40], [29usize, 21, 17]);
        let mut v = Vec::new();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    // A smooth blob, and a constant 8³ block (written as a tile).
                    let (gx, gy, gz) = (x as i32 + lo[0], y as i32 + lo[1], z as i32 + lo[2]);
                    let in_block =
                        (0..8).contains(&gx) && (8..16).contains(&gy) && (-32..-24).contains(&gz);
                    let r2 = ((x as f32 - 10.0).powi(2)
                        + (y as f32 - 9.0).powi(2)
                        + (z as f32 - 8.0).powi(2))
                        / 40.0;
                    v.push(if in_block {
                        0.75
                    } else if r2 < 1.0 {
                        1.0 - r2
                    } else {
                        0.0
                    });
                }
            }
        }
        (v, lo, dims)
    }

    #[test]
    fn written_grids_read_back_voxel_for_voxel() {
        let (values, lo, dims) = sample_grid();
        let temperature: Vec<f32> = values.iter().map(|v| v * 2000.0).collect();
        for zip in [false, true] {
            let file = write_nanovdb(
                &[
                    GridToWrite {
                        name: "density",
                        class: CLASS_FOG_VOLUME,
                        voxel_size: [0.5, 0.25, 0.125],
                        origin: [1.0, -2.0, 3.0],
                        lo,
                        dims,
                        values: &values,
                    },
                    GridToWrite {
                        name: "temperature",
                        class: CLASS_FOG_VOLUME,
                        voxel_size: [0.5, 0.25, 0.125],
                        origin: [1.0, -2.0, 3.0],
                        lo,
                        dims,
                        values: &temperature,
                    },
                ],
                zip,
            );
            assert_eq!(grid_names(&file).unwrap(), ["density", "temperature"]);
            let d = read_grid(&file, "density").unwrap().unwrap();
            let t = read_grid(&file, "temperature").unwrap().unwrap();
            assert!(read_grid(&file, "velocity").unwrap().is_none());
            assert_eq!(d.class, CLASS_FOG_VOLUME);
            // One sample of margin on every side: zero (background) there.
            let wide_lo = lo.map(|v| v - 1);
            let wide = dims.map(|v| v + 2);
            let dense = d.dense(wide_lo, wide).unwrap();
            let tdense = t.dense(wide_lo, wide).unwrap();
            for z in 0..wide[2] {
                for y in 0..wide[1] {
                    for x in 0..wide[0] {
                        let inside = (1..=dims[0]).contains(&x)
                            && (1..=dims[1]).contains(&y)
                            && (1..=dims[2]).contains(&z);
                        let want = if inside {
                            values[((z - 1) * dims[1] + y - 1) * dims[0] + x - 1]
                        } else {
                            0.0
                        };
                        let i = (z * wide[1] + y) * wide[0] + x;
                        assert_eq!(dense[i], want, "voxel {x} {y} {z}");
                        assert_eq!(tdense[i], want * 2000.0);
                        let ijk = [
                            x as i32 + wide_lo[0],
                            y as i32 + wide_lo[1],
                            z as i32 + wide_lo[2],
                        ];
                        assert_eq!(d.value(ijk).unwrap(), want);
                    }
                }
            }
            // The active box, and the map: index (0, 0, 0) sits at the origin.
            let active: Vec<usize> = (0..values.len()).filter(|i| values[*i] != 0.0).collect();
            assert!(!active.is_empty());
            assert_eq!(d.map.world_to_index([1.0, -2.0, 3.0]), [0.0, 0.0, 0.0]);
            assert_eq!(d.map.world_to_index([1.5, -1.5, 3.375]), [1.0, 2.0, 3.0]);
            let (bl, bh) = d.index_bbox;
            assert!(bl.iter().zip(&bh).all(|(l, h)| l <= h));
            assert_eq!(d.world_bbox.0[0], 1.0 + 0.5 * bl[0] as f64);
            assert_eq!(d.world_bbox.1[2], 3.0 + 0.125 * (bh[2] as f64 + 1.0));
        }
    }

    #[test]
    fn the_name_hash_is_nanovdbs() {
        // NanoVDB's io::stringHash: h = h * 67 + c + (h >> 56) per byte.
        assert_eq!(name_hash(""), 0);
        assert_eq!(name_hash("a"), 97);
        assert_eq!(name_hash("ab"), 97 * 67 + 98);
    }

    #[test]
    fn corrupt_files_are_errors_not_panics() {
        let (values, lo, dims) = sample_grid();
        let file = write_nanovdb(
            &[GridToWrite {
                name: "density",
                class: CLASS_FOG_VOLUME,
                voxel_size: [1.0; 3],
                origin: [0.0; 3],
                lo,
                dims,
                values: &values,
            }],
            false,
        );
        assert!(read_grid(&[], "density").unwrap_err().contains("empty"));
        assert!(read_grid(b"VOL\x03", "density").is_err());
        // Every truncation, and a byte flipped at a spread of offsets: an error or a grid
        // whose lookups are errors or values, never a panic.
        for cut in (0..file.len()).step_by(97) {
            let _ = read_grid(&file[..cut], "density");
        }
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..400 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let mut f = file.clone();
            let at = (rng % f.len() as u64) as usize;
            f[at] ^= (rng >> 32) as u8 | 1;
            if let Ok(Some(g)) = read_grid(&f, "density") {
                let _ = g.dense(lo, dims);
            }
        }
        // Another version's layout is refused with the version named.
        let mut f = file.clone();
        f[8..12].copy_from_slice(&((32u32 << 21) | (6 << 10)).to_le_bytes());
        assert!(read_grid(&f, "density").unwrap_err().contains("32.6.0"));
        let mut f = file;
        f[0..8].copy_from_slice(&MAGIC_NEW_FILE.to_le_bytes());
        assert!(read_grid(&f, "density").unwrap_err().contains("NanoVDB2"));
    }
}
