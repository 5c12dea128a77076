//! Scene bundles: a scene file and every file it refers to, in one content-addressed blob.
//!
//! Layout: the magic `KILNBDL1`, a u32 entry count, then per entry a u16 path length, the
//! UTF-8 relative path, a u64 data length and the data (little endian). The first entry is
//! the scene file. The digest is the SHA-256 of the whole blob, in hex.
//!
//! Unpacked bundles live in a cache folder, one subfolder per digest, which the coordinator
//! (its data directory's `scenes/`) and workers (`--cache-dir`) fill through the same
//! [`unpack_into_cache`]: a subfolder is complete once its [`SCENE_MARKER`] exists.

use sha2::{Digest, Sha256};
use std::io::{Cursor, Read, Seek, SeekFrom};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

const MAGIC: &[u8; 8] = b"KILNBDL1";

/// The file in an unpacked bundle's folder that names its scene file (a relative path).
/// It is written last, so a folder that has it is complete.
pub const SCENE_MARKER: &str = ".scene";

/// The bundle's own bytes, kept beside its unpacked files when asked (the coordinator
/// serves them to workers).
pub const BUNDLE_FILE: &str = "bundle.kiln";

#[derive(Debug, thiserror::Error)]
pub enum BundleError {
    #[error("{0}")]
    Scene(#[from] kiln_scene::SceneError),
    #[error("cannot read '{path}': {cause}")]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error(
        "'{0}' is outside the scene's directory; a bundle holds only files beside or below the scene"
    )]
    Outside(PathBuf),
    #[error("corrupt bundle: {0}")]
    Corrupt(String),
}

/// A bundle in memory: its bytes and digest.
#[derive(Debug, Clone)]
pub struct Bundle {
    pub bytes: Vec<u8>,
    pub digest: String,
}

pub fn digest_of(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Parses the scene (so a bad one fails here, with its file and line) and packs it with
/// every file it read.
pub fn pack(scene: &Path) -> Result<Bundle, BundleError> {
    let desc = kiln_scene::load_file(scene)?;
    let base = scene.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut entries: Vec<(String, PathBuf)> = Vec::new();
    let name = scene
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene.pbrt".into());
    entries.push((name, scene.to_path_buf()));
    for f in &desc.files {
        let rel = f
            .strip_prefix(&base)
            .map_err(|_| BundleError::Outside(f.clone()))?;
        let rel = rel.to_string_lossy().replace('\\', "/");
        if !entries.iter().any(|(r, _)| *r == rel) {
            entries.push((rel, f.clone()));
        }
    }
    let mut files = Vec::with_capacity(entries.len());
    for (rel, path) in entries {
        let data = std::fs::read(&path).map_err(|cause| BundleError::Io { path, cause })?;
        files.push((rel, data));
    }
    Ok(encode(&files))
}

/// Parses a shot's frames (so a bad one fails here, naming its file and line) and packs
/// them with every file they read, in one bundle: its scene file is the first frame, and
/// every file lies beside or below the first frame's folder. Returns the bundle and each
/// frame's path in it, in the order given. The frames' meshes are read once.
pub fn pack_frames(frames: &[PathBuf]) -> Result<(Bundle, Vec<String>), BundleError> {
    let first = frames
        .first()
        .ok_or_else(|| BundleError::Corrupt("no frames".into()))?;
    let base = first.parent().unwrap_or(Path::new("")).to_path_buf();
    let root = if base.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        base.clone()
    };
    let meshes = std::sync::Arc::new(kiln_scene::MeshCache::new(1 << 30));
    let relative = |f: &Path| -> Result<String, BundleError> {
        let rel = f
            .strip_prefix(&base)
            .map_err(|_| BundleError::Outside(f.to_path_buf()))?;
        Ok(rel.to_string_lossy().replace('\\', "/"))
    };
    let mut entries: Vec<(String, PathBuf)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let mut names = Vec::with_capacity(frames.len());
    let mut read = Vec::new();
    for frame in frames {
        let desc = kiln_scene::load_file_within_sharing(frame, &root, Some(meshes.clone()))?;
        let name = relative(frame)?;
        if seen.insert(name.clone()) {
            entries.push((name.clone(), frame.clone()));
        }
        names.push(name);
        read.extend(desc.files);
    }
    for f in &read {
        let rel = relative(f)?;
        if seen.insert(rel.clone()) {
            entries.push((rel, f.clone()));
        }
    }
    let mut files = Vec::with_capacity(entries.len());
    for (rel, path) in entries {
        let data = std::fs::read(&path).map_err(|cause| BundleError::Io { path, cause })?;
        files.push((rel, data));
    }
    Ok((encode(&files), names))
}

/// A bundle of these (relative name, contents) entries, the first being the scene file.
pub fn encode(files: &[(String, Vec<u8>)]) -> Bundle {
    let mut bytes = Vec::new();
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&(files.len() as u32).to_le_bytes());
    for (rel, data) in files {
        bytes.extend_from_slice(&(rel.len() as u16).to_le_bytes());
        bytes.extend_from_slice(rel.as_bytes());
        bytes.extend_from_slice(&(data.len() as u64).to_le_bytes());
        bytes.extend_from_slice(data);
    }
    let digest = digest_of(&bytes);
    Bundle { bytes, digest }
}

/// An error's message with the folder a bundle was unpacked in taken off the file names it
/// quotes: a farm's clients see paths inside their bundle, never the server's.
pub fn relative_message(e: &impl std::fmt::Display, root: &Path) -> String {
    e.to_string().replace(&format!("{}/", root.display()), "")
}

/// A relative path that stays inside the bundle (no root, no `..`).
fn safe_relative(rel: &str) -> Option<PathBuf> {
    let p = Path::new(rel);
    if rel.is_empty() || p.components().any(|c| !matches!(c, Component::Normal(_))) {
        return None;
    }
    Some(p.to_path_buf())
}

/// The longest name one path component may have (what common file systems allow).
const MAX_NAME_BYTES: usize = 255;

/// The longest path an entry may have, in bytes (Linux's PATH_MAX): the file systems that
/// unpack it refuse longer ones.
pub const MAX_PATH_BYTES: usize = 4096;

/// The most folders an entry's path may pass through. A scene's files sit a few folders
/// deep; thousands of levels only make every check and every unpacking slow.
pub const MAX_DEPTH: usize = 64;

/// The most entries a bundle may hold: a scene reads tens or thousands of files, never
/// this many, and each is an inode wherever it is unpacked.
pub const MAX_ENTRIES: usize = 65_536;

/// Checks that a bundle's entry names can all be files in one folder tree: no NUL, no
/// component longer than [`MAX_NAME_BYTES`], no path longer than [`MAX_PATH_BYTES`] or
/// deeper than [`MAX_DEPTH`], no name twice, and no name that is both a file and a folder
/// (`a` and `a/b`). A name the file system would refuse is the bundle's fault, said here;
/// what fails after this is the server's. Time and memory are linear in the names' total
/// length (times the log of their count, for one sort).
fn check_names(names: &[&Path]) -> Result<(), BundleError> {
    let corrupt = |m: String| Err(BundleError::Corrupt(m));
    // What is shown of a name in a message: its start, for the longest.
    let shown = |name: &Path| {
        let text = name.display().to_string();
        match text.char_indices().nth(80) {
            Some((cut, _)) => format!("{}...", &text[..cut]),
            None => text,
        }
    };
    for name in names {
        if name.as_os_str().len() > MAX_PATH_BYTES {
            return corrupt(format!(
                "path '{}' is {} bytes long; the most is {MAX_PATH_BYTES}",
                shown(name),
                name.as_os_str().len()
            ));
        }
        let mut depth = 0;
        for c in name.components() {
            depth += 1;
            let c = c.as_os_str().as_encoded_bytes();
            if c.contains(&0) {
                return corrupt(format!(
                    "path '{}' holds a NUL byte",
                    shown(name).escape_debug()
                ));
            }
            if c.len() > MAX_NAME_BYTES {
                return corrupt(format!(
                    "a name in path '{}' is longer than {MAX_NAME_BYTES} bytes",
                    shown(name)
                ));
            }
        }
        if depth > MAX_DEPTH + 1 {
            return corrupt(format!(
                "path '{}' is {} folders deep; the most is {MAX_DEPTH}",
                shown(name),
                depth - 1
            ));
        }
    }
    // Sorted by components, a path's descendants follow it at once ("a", "a/b", "a-b"):
    // a name twice, or a file that is also a folder, is next to its other self.
    let mut sorted = names.to_vec();
    sorted.sort_unstable();
    for pair in sorted.windows(2) {
        if pair[0] == pair[1] {
            return corrupt(format!("path '{}' is in it twice", shown(pair[0])));
        }
        if pair[1].starts_with(pair[0]) {
            return corrupt(format!("'{}' is both a file and a folder", shown(pair[0])));
        }
    }
    Ok(())
}

/// The entries of a bundle: (relative path, data). Checks the structure, never panics.
/// Where a bundle's bytes are: in memory (a download), or in a file (an upload streamed
/// to disk, so that a large bundle is never held in memory whole).
#[derive(Debug, Clone, Copy)]
pub enum Source<'a> {
    Bytes(&'a [u8]),
    File(&'a Path),
}

/// A bundle's entries: each path, with where its contents lie (offset, length).
type Index = Vec<(PathBuf, u64, u64)>;

/// Reads a bundle's table of entries from `r` (`len` bytes long), checking every name and
/// that the entries exactly fill it, without reading their contents.
fn index(r: &mut (impl Read + Seek), len: u64) -> Result<Index, BundleError> {
    let corrupt = |m: &str| BundleError::Corrupt(m.to_string());
    let truncated = |_| corrupt("it is truncated");
    let mut head = [0u8; 12];
    if len < 12 || r.read_exact(&mut head).is_err() || &head[..8] != MAGIC {
        return Err(corrupt("it does not start with KILNBDL1"));
    }
    let count = u32::from_le_bytes(head[8..12].try_into().unwrap());
    if count as usize > MAX_ENTRIES {
        return Err(BundleError::Corrupt(format!(
            "it has {count} entries; the most is {MAX_ENTRIES}"
        )));
    }
    let mut pos = 12u64;
    let mut out = Vec::new();
    for _ in 0..count {
        let mut n = [0u8; 2];
        r.read_exact(&mut n).map_err(truncated)?;
        let n = u16::from_le_bytes(n);
        if pos + 2 + u64::from(n) + 8 > len {
            return Err(corrupt("it is truncated"));
        }
        let mut name = vec![0u8; usize::from(n)];
        r.read_exact(&mut name).map_err(truncated)?;
        let rel = std::str::from_utf8(&name).map_err(|_| corrupt("a path is not UTF-8"))?;
        if rel.ends_with('/') {
            return Err(BundleError::Corrupt(format!(
                "path '{}' names a folder; a bundle holds files",
                rel.chars().take(80).collect::<String>()
            )));
        }
        let path = safe_relative(rel).ok_or_else(|| {
            BundleError::Corrupt(format!(
                "path '{}' escapes the bundle",
                rel.chars().take(80).collect::<String>()
            ))
        })?;
        let mut size = [0u8; 8];
        r.read_exact(&mut size).map_err(truncated)?;
        let size = u64::from_le_bytes(size);
        pos += 2 + u64::from(n) + 8;
        if size > len - pos {
            return Err(corrupt("it is truncated"));
        }
        out.push((path, pos, size));
        pos += size;
        r.seek(SeekFrom::Start(pos)).map_err(truncated)?;
    }
    if pos != len {
        return Err(corrupt("it has bytes after its last entry"));
    }
    if out.is_empty() {
        return Err(corrupt("it has no scene file"));
    }
    check_names(&out.iter().map(|(p, _, _)| p.as_path()).collect::<Vec<_>>())?;
    Ok(out)
}

pub fn entries(bytes: &[u8]) -> Result<Vec<(PathBuf, &[u8])>, BundleError> {
    let index = index(&mut Cursor::new(bytes), bytes.len() as u64)?;
    Ok(index
        .into_iter()
        .map(|(path, at, len)| (path, &bytes[at as usize..(at + len) as usize]))
        .collect())
}

/// Unpacks a bundle into `dir` (created) and returns the path of its scene file.
pub fn unpack(bytes: &[u8], dir: &Path) -> Result<PathBuf, BundleError> {
    unpack_from(Source::Bytes(bytes), dir)
}

/// [`unpack`] from either kind of [`Source`]: a file's entries are copied from it piece by
/// piece.
fn unpack_from(source: Source, dir: &Path) -> Result<PathBuf, BundleError> {
    let io = |path: &Path, cause| BundleError::Io {
        path: path.to_path_buf(),
        cause,
    };
    let write = |rel: &Path, contents: &mut dyn Read| {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
        }
        let mut out = std::fs::File::create(&path).map_err(|e| io(&path, e))?;
        std::io::copy(contents, &mut out).map_err(|e| io(&path, e))?;
        Ok::<_, BundleError>(())
    };
    let index = match source {
        Source::Bytes(bytes) => {
            let index = index(&mut Cursor::new(bytes), bytes.len() as u64)?;
            for (rel, at, len) in &index {
                write(rel, &mut &bytes[*at as usize..(*at + *len) as usize])?;
            }
            index
        }
        Source::File(file) => {
            let mut f = std::fs::File::open(file).map_err(|e| io(file, e))?;
            let len = f.metadata().map_err(|e| io(file, e))?.len();
            let index = index(&mut std::io::BufReader::new(&mut f), len)?;
            for (rel, at, size) in &index {
                f.seek(SeekFrom::Start(*at)).map_err(|e| io(file, e))?;
                write(rel, &mut (&mut f).take(*size))?;
            }
            index
        }
    };
    Ok(dir.join(&index[0].0))
}

/// Whether `text` has the form of a digest (hexadecimal), and so is safe as a folder name.
pub fn is_digest(text: &str) -> bool {
    !text.is_empty() && text.bytes().all(|b| b.is_ascii_hexdigit())
}

/// The scene file of the bundle `digest` if it is completely unpacked in `cache`.
pub fn cached_scene(cache: &Path, digest: &str) -> Option<PathBuf> {
    if !is_digest(digest) {
        return None;
    }
    let dir = cache.join(digest);
    let rel = std::fs::read_to_string(dir.join(SCENE_MARKER)).ok()?;
    Some(dir.join(safe_relative(rel.trim())?))
}

/// Unpacks a bundle into `cache/<digest>` unless it is there already, and returns the path
/// of its scene file. `digest` must be the bundle's (callers check or compute it).
///
/// The files are written to a private temporary folder, the marker last, and the folder is
/// renamed into place, so a reader never sees half a bundle and two processes unpacking the
/// same bundle at once both succeed. A folder left without a marker (by an older layout) is
/// replaced. With `keep_bundle` the bundle's bytes are kept too, as [`BUNDLE_FILE`].
pub fn unpack_into_cache(
    source: Source,
    digest: &str,
    cache: &Path,
    keep_bundle: bool,
) -> Result<PathBuf, BundleError> {
    if let Some(scene) = cached_scene(cache, digest) {
        return Ok(scene);
    }
    if !is_digest(digest) {
        return Err(BundleError::Corrupt(format!("'{digest}' is not a digest")));
    }
    let io = |path: &Path, cause| BundleError::Io {
        path: path.to_path_buf(),
        cause,
    };
    static UNIQUE: AtomicU64 = AtomicU64::new(0);
    let tmp = cache.join(format!(
        ".{digest}.{}.{}.tmp",
        std::process::id(),
        UNIQUE.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| {
        let scene = unpack_from(source, &tmp)?;
        let rel = scene
            .strip_prefix(&tmp)
            .expect("unpack writes inside its folder");
        if keep_bundle {
            let path = tmp.join(BUNDLE_FILE);
            match source {
                Source::Bytes(bytes) => std::fs::write(&path, bytes).map(|_| ()),
                Source::File(file) => std::fs::copy(file, &path).map(|_| ()),
            }
            .map_err(|e| io(&path, e))?;
        }
        let marker = tmp.join(SCENE_MARKER);
        std::fs::write(&marker, rel.to_string_lossy().as_bytes()).map_err(|e| io(&marker, e))?;
        let dir = cache.join(digest);
        let mut replaced = false;
        loop {
            match std::fs::rename(&tmp, &dir) {
                Ok(()) => return Ok(dir.join(rel)),
                // Another request or process unpacked it first.
                Err(_) if cached_scene(cache, digest).is_some() => {
                    let _ = std::fs::remove_dir_all(&tmp);
                    return Ok(dir.join(rel));
                }
                Err(_) if !replaced && dir.is_dir() => {
                    std::fs::remove_dir_all(&dir).map_err(|e| io(&dir, e))?;
                    replaced = true;
                }
                Err(e) => return Err(io(&dir, e)),
            }
        }
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundles_round_trip_and_reject_escapes_and_truncation() {
        let dir = std::env::temp_dir().join(format!("kiln-bundle-test-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("models")).unwrap();
        std::fs::write(dir.join("models/inc.pbrt"), "Shape \"sphere\"\n").unwrap();
        std::fs::write(
            dir.join("scene.pbrt"),
            "WorldBegin\nInclude \"models/inc.pbrt\"\n",
        )
        .unwrap();
        let b = pack(&dir.join("scene.pbrt")).unwrap();
        assert_eq!(b.digest, digest_of(&b.bytes));
        let e = entries(&b.bytes).unwrap();
        assert_eq!(e.len(), 2);
        assert_eq!(e[1].0, PathBuf::from("models/inc.pbrt"));
        let out = dir.join("out");
        let scene = unpack(&b.bytes, &out).unwrap();
        assert!(kiln_scene::load_file(&scene).is_ok());
        for cut in [0, 5, 13, b.bytes.len() - 1] {
            assert!(entries(&b.bytes[..cut]).is_err());
        }
        // A path with .. is refused.
        let mut evil = Vec::new();
        evil.extend_from_slice(MAGIC);
        evil.extend_from_slice(&1u32.to_le_bytes());
        evil.extend_from_slice(&5u16.to_le_bytes());
        evil.extend_from_slice(b"../x1");
        evil.extend_from_slice(&0u64.to_le_bytes());
        assert!(matches!(entries(&evil), Err(BundleError::Corrupt(m)) if m.contains("escapes")));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A bundle of `entries` (name, contents) written by hand, names unchecked.
    fn raw(entries: &[(&str, &[u8])]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&(entries.len() as u32).to_le_bytes());
        for (name, data) in entries {
            b.extend_from_slice(&(name.len() as u16).to_le_bytes());
            b.extend_from_slice(name.as_bytes());
            b.extend_from_slice(&(data.len() as u64).to_le_bytes());
            b.extend_from_slice(data);
        }
        b
    }

    fn refused(bytes: &[u8]) -> String {
        match entries(bytes) {
            Err(BundleError::Corrupt(m)) => m,
            other => panic!("not refused as corrupt: {other:?}"),
        }
    }

    /// Deep, long and folder-like names and too many entries are the bundle's fault, said
    /// at once: five entries 32,700 folders deep (which once took the square of their depth
    /// in memory) are refused in well under a second.
    #[test]
    fn deep_long_and_folder_names_and_too_many_entries_are_refused() {
        let deep = "a/".repeat(32_700) + "f";
        let deeps: Vec<String> = (0..5).map(|i| format!("{deep}{i}")).collect();
        let entries_of: Vec<(&str, &[u8])> = std::iter::once(("scene.pbrt", &b""[..]))
            .chain(deeps.iter().map(|d| (d.as_str(), &b""[..])))
            .collect();
        let start = std::time::Instant::now();
        let m = refused(&raw(&entries_of));
        assert!(m.contains("bytes long; the most is 4096"), "{m}");
        assert!(
            m.len() < 300,
            "the message quotes the path whole: {} bytes",
            m.len()
        );
        assert!(start.elapsed() < std::time::Duration::from_secs(1));
        let long = "b/".repeat(2100) + "f";
        assert!(refused(&raw(&[(&long, b"")])).contains("the most is 4096"));
        let nested = "c/".repeat(MAX_DEPTH + 1) + "f";
        assert!(refused(&raw(&[(&nested, b"")])).contains("folders deep; the most is 64"));
        let just = "c/".repeat(MAX_DEPTH) + "f";
        assert!(entries(&raw(&[(&just, b"")])).is_ok());
        assert!(refused(&raw(&[("scene.pbrt", b""), ("d/", b"")])).contains("names a folder"));
        // A file that is also a folder, even with a name between them in byte order.
        let m = refused(&raw(&[("a", b""), ("a-b", b""), ("a/c", b"")]));
        assert!(m.contains("'a' is both a file and a folder"), "{m}");
        assert!(refused(&raw(&[("x", b""), ("y", b""), ("x", b"")])).contains("twice"));
        // A table claiming a million entries is refused before any is read.
        let mut many = raw(&[("scene.pbrt", b"")]);
        many[8..12].copy_from_slice(&1_000_000u32.to_le_bytes());
        let m = refused(&many);
        assert!(m.contains("1000000 entries; the most is 65536"), "{m}");
    }

    /// A two-file bundle (a scene including another file) in a fresh folder.
    fn sample_bundle(name: &str) -> (PathBuf, Bundle) {
        let dir = std::env::temp_dir().join(format!("kiln-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("src/models")).unwrap();
        std::fs::write(dir.join("src/models/inc.pbrt"), "Shape \"sphere\"\n").unwrap();
        std::fs::write(
            dir.join("src/scene.pbrt"),
            "WorldBegin\nInclude \"models/inc.pbrt\"\n",
        )
        .unwrap();
        let b = pack(&dir.join("src/scene.pbrt")).unwrap();
        (dir, b)
    }

    #[test]
    fn unpacking_into_a_cache_is_complete_once_and_idempotent() {
        let (dir, b) = sample_bundle("cache-test");
        let cache = dir.join("cache");
        std::fs::create_dir_all(&cache).unwrap();
        assert_eq!(cached_scene(&cache, &b.digest), None);
        let scene = unpack_into_cache(Source::Bytes(&b.bytes), &b.digest, &cache, true).unwrap();
        assert_eq!(scene, cache.join(&b.digest).join("scene.pbrt"));
        assert_eq!(cached_scene(&cache, &b.digest), Some(scene.clone()));
        assert!(kiln_scene::load_file(&scene).is_ok());
        assert_eq!(
            std::fs::read(cache.join(&b.digest).join(BUNDLE_FILE)).unwrap(),
            b.bytes
        );
        // A second unpack finds it and writes nothing; no temporary folder is left.
        std::fs::write(cache.join(&b.digest).join("models/inc.pbrt"), "# kept\n").unwrap();
        assert_eq!(
            unpack_into_cache(Source::Bytes(&b.bytes), &b.digest, &cache, true).unwrap(),
            scene
        );
        assert_eq!(
            std::fs::read_to_string(cache.join(&b.digest).join("models/inc.pbrt")).unwrap(),
            "# kept\n"
        );
        let names: Vec<_> = std::fs::read_dir(&cache)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names, [b.digest.as_str()]);
        // Without keep_bundle only the scene's files and the marker are written.
        let other = dir.join("other");
        unpack_into_cache(Source::Bytes(&b.bytes), &b.digest, &other, false).unwrap();
        assert!(!other.join(&b.digest).join(BUNDLE_FILE).exists());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn an_incomplete_cache_folder_is_replaced_and_bad_input_leaves_nothing() {
        let (dir, b) = sample_bundle("cache-replace-test");
        let cache = dir.join("cache");
        // A folder without the marker (a worker cache of an older layout).
        std::fs::create_dir_all(cache.join(&b.digest)).unwrap();
        std::fs::write(cache.join(&b.digest).join(".kiln-scene"), "scene.pbrt").unwrap();
        assert_eq!(cached_scene(&cache, &b.digest), None);
        let scene = unpack_into_cache(Source::Bytes(&b.bytes), &b.digest, &cache, false).unwrap();
        assert_eq!(cached_scene(&cache, &b.digest), Some(scene));
        assert!(!cache.join(&b.digest).join(".kiln-scene").exists());
        // A corrupt bundle or a digest that is not one writes nothing.
        let bad = dir.join("bad");
        std::fs::create_dir_all(&bad).unwrap();
        let cut = &b.bytes[..b.bytes.len() - 3];
        assert!(unpack_into_cache(Source::Bytes(cut), "abc", &bad, false).is_err());
        assert!(unpack_into_cache(Source::Bytes(&b.bytes), "../escape", &bad, false).is_err());
        assert_eq!(cached_scene(&bad, "../escape"), None);
        assert_eq!(std::fs::read_dir(&bad).unwrap().count(), 0);
        std::fs::remove_dir_all(&dir).ok();
    }
}
