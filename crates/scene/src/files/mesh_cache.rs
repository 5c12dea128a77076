//! Meshes read from files (PLY, OBJ), kept for the next scene that names the same file: a
//! shot's frames include the same geometry, and a farm's worker reads it once rather than
//! once a frame.
//!
//! A mesh is found again by its path, its length and its modification time, so a file
//! changed in place is read again. The cache holds at most a budget of bytes, dropping the
//! meshes kept longest ago first. It counts what it read and what it gave again. Nothing
//! here parses: the readers are `ply.rs`'s and `obj.rs`'s.

use crate::error::{Loc, Result};
use crate::mesh::TriangleMeshData;
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

/// Which reader a file is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    Ply,
    Obj,
}

/// What finds a mesh again: the file, its length and its modification time.
type Key = (MeshFormat, PathBuf, u64, Option<SystemTime>);

/// Meshes read from files, shared by the scenes loaded through it.
pub struct MeshCache {
    kept: Mutex<Kept>,
    budget: u64,
    loads: AtomicU64,
    reused: AtomicU64,
}

#[derive(Default)]
struct Kept {
    meshes: HashMap<Key, (Arc<TriangleMeshData>, u64)>,
    /// The keys, oldest first.
    order: VecDeque<Key>,
    bytes: u64,
}

impl MeshCache {
    /// A cache that keeps at most `budget` bytes of meshes.
    pub fn new(budget: u64) -> MeshCache {
        MeshCache {
            kept: Mutex::new(Kept::default()),
            budget,
            loads: AtomicU64::new(0),
            reused: AtomicU64::new(0),
        }
    }

    /// Mesh files read so far (each read counts, cached or not).
    pub fn loads(&self) -> u64 {
        self.loads.load(Ordering::Relaxed)
    }

    /// Meshes given from the cache instead of read again.
    pub fn reused(&self) -> u64 {
        self.reused.load(Ordering::Relaxed)
    }

    /// The mesh in `path`, from the cache or read by `format`'s reader (its errors name
    /// `loc`). A file whose length or time cannot be read is read every time.
    pub fn get(&self, format: MeshFormat, path: &Path, loc: &Loc) -> Result<Arc<TriangleMeshData>> {
        let key = std::fs::metadata(path)
            .ok()
            .map(|m| (format, path.to_path_buf(), m.len(), m.modified().ok()));
        if let Some(key) = &key
            && let Some((mesh, _)) = self.lock().meshes.get(key)
        {
            self.reused.fetch_add(1, Ordering::Relaxed);
            return Ok(mesh.clone());
        }
        let mesh = Arc::new(read(format, path, loc)?);
        self.loads.fetch_add(1, Ordering::Relaxed);
        if let Some(key) = key {
            self.keep(key, mesh.clone());
        }
        Ok(mesh)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Kept> {
        // Plain inserts and removals: a panic part way leaves nothing half done.
        self.kept.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Keeps `mesh` under `key`, dropping the oldest meshes past the budget. One bigger
    /// than the whole budget is not kept.
    fn keep(&self, key: Key, mesh: Arc<TriangleMeshData>) {
        let size = bytes_of(&mesh);
        if size > self.budget {
            return;
        }
        let mut kept = self.lock();
        if kept.meshes.contains_key(&key) {
            return;
        }
        while kept.bytes + size > self.budget {
            let Some(old) = kept.order.pop_front() else {
                break;
            };
            if let Some((_, b)) = kept.meshes.remove(&old) {
                kept.bytes -= b;
            }
        }
        kept.bytes += size;
        kept.order.push_back(key.clone());
        kept.meshes.insert(key, (mesh, size));
    }
}

fn read(format: MeshFormat, path: &Path, loc: &Loc) -> Result<TriangleMeshData> {
    match format {
        MeshFormat::Ply => super::ply::read_ply(path, loc),
        MeshFormat::Obj => super::obj::read_obj(path, loc),
    }
}

/// The bytes a mesh's arrays hold.
fn bytes_of(m: &TriangleMeshData) -> u64 {
    let n = m.positions.len() as u64;
    n * 12
        + m.normals.as_ref().map_or(0, |v| v.len() as u64 * 12)
        + m.uvs.as_ref().map_or(0, |v| v.len() as u64 * 8)
        + (m.indices.len() + m.quads.len()) as u64 * 4
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_ply(path: &Path, shift: f32) {
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 {shift}\n1 0 0\n0 1 0\n3 0 1 2\n"
        );
        std::fs::write(path, text).unwrap();
    }

    #[test]
    fn a_file_is_read_once_until_it_changes() {
        let dir = std::env::temp_dir().join(format!("kiln-mesh-cache-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("tri.ply");
        write_ply(&path, 0.0);
        let loc = Loc::synthetic("test");
        let cache = MeshCache::new(1 << 20);
        let a = cache.get(MeshFormat::Ply, &path, &loc).unwrap();
        let b = cache.get(MeshFormat::Ply, &path, &loc).unwrap();
        assert!(Arc::ptr_eq(&a, &b), "the second scene gets the same mesh");
        assert_eq!((cache.loads(), cache.reused()), (1, 1));
        // A different length: read again.
        write_ply(&path, 0.25);
        let c = cache.get(MeshFormat::Ply, &path, &loc).unwrap();
        assert_eq!(c.positions[0][2], 0.25);
        assert_eq!((cache.loads(), cache.reused()), (2, 1));
        // A budget too small for a mesh keeps none.
        let tiny = MeshCache::new(8);
        tiny.get(MeshFormat::Ply, &path, &loc).unwrap();
        tiny.get(MeshFormat::Ply, &path, &loc).unwrap();
        assert_eq!((tiny.loads(), tiny.reused()), (2, 0));
        // A missing file is an error, never kept.
        let missing = dir.join("none.ply");
        assert!(cache.get(MeshFormat::Ply, &missing, &loc).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_oldest_mesh_goes_first_past_the_budget() {
        let dir = std::env::temp_dir().join(format!("kiln-mesh-budget-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let loc = Loc::synthetic("test");
        let (p1, p2) = (dir.join("a.ply"), dir.join("b.ply"));
        write_ply(&p1, 0.0);
        write_ply(&p2, 0.5);
        // One triangle: 3 positions (36 bytes) and 3 indices (12): room for one.
        let cache = MeshCache::new(60);
        cache.get(MeshFormat::Ply, &p1, &loc).unwrap();
        cache.get(MeshFormat::Ply, &p2, &loc).unwrap();
        cache.get(MeshFormat::Ply, &p2, &loc).unwrap();
        cache.get(MeshFormat::Ply, &p1, &loc).unwrap();
        assert_eq!((cache.loads(), cache.reused()), (3, 1));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
