//! A shot of many frames from the command line: scene arguments (a list, or a quoted glob
//! such as `'shot/f*.pbrt'`) expanded into frames in name order, each frame's result
//! named after its scene file in the output folder, and a shot's job followed to its end
//! with each frame written as its passes are merged.

use anyhow::{Result, bail};
use kiln_farm::client::Client;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The frames the scene arguments name: a file as it is; an argument that is no file and
/// has `*` or `?` in its last part, the files of its folder that it matches, in name order.
pub fn expand(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut frames = Vec::new();
    for arg in args {
        let name = arg.file_name().map(|n| n.to_string_lossy().into_owned());
        let pattern = name.filter(|n| !arg.exists() && (n.contains('*') || n.contains('?')));
        let Some(pattern) = pattern else {
            frames.push(arg.clone());
            continue;
        };
        let dir = match arg.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let listing = std::fs::read_dir(&dir)
            .map_err(|e| anyhow::anyhow!("cannot list {} for '{pattern}': {e}", dir.display()))?;
        let mut found: Vec<PathBuf> = listing
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_file())
            .filter(|e| matches(&pattern, &e.file_name().to_string_lossy()))
            .map(|e| arg.with_file_name(e.file_name()))
            .collect();
        if found.is_empty() {
            bail!("no file matches '{}'", arg.display());
        }
        found.sort();
        frames.extend(found);
    }
    Ok(frames)
}

/// Whether `name` matches `pattern`, where `*` is any run of characters and `?` any one.
fn matches(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    // The classic two-pointer match with backtracking to the last star.
    let (mut i, mut j, mut star, mut mark) = (0, 0, None, 0);
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some(i);
            mark = j;
            i += 1;
        } else if let Some(s) = star {
            i = s + 1;
            mark += 1;
            j = mark;
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

/// Each frame's EXR in `dir`: its scene file's name with `.exr`. Two frames of one name (in
/// different folders) are refused, since one would overwrite the other.
pub fn outputs(frames: &[PathBuf], dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out: Vec<PathBuf> = Vec::with_capacity(frames.len());
    for f in frames {
        let stem = f.file_stem().unwrap_or_default();
        let path = dir.join(stem).with_extension("exr");
        if let Some(k) = out.iter().position(|o| *o == path) {
            bail!(
                "frames {} and {} would both be written to {}: give frames of different names",
                frames[k].display(),
                f.display(),
                path.display()
            );
        }
        out.push(path);
    }
    Ok(out)
}

/// Follows shot `id` to its end with a progress bar; writes each frame to its output as its
/// passes are merged (so each file is always a whole frame).
pub async fn wait_for_shot(
    client: &Client,
    id: u64,
    outputs: &[PathBuf],
    quiet: bool,
) -> Result<()> {
    if let Some(dir) = outputs.first().and_then(|o| o.parent())
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    }
    let bar = crate::output::progress_bar(quiet);
    let mut written = vec![0u32; outputs.len()];
    loop {
        let s = client.status(id).await?;
        let frames = client.frames(id).await?;
        if frames.len() != outputs.len() {
            bail!(
                "job {id} has {} frames, not the {} submitted",
                frames.len(),
                outputs.len()
            );
        }
        bar.set_position((s.progress * 1000.0) as u64);
        let finished = frames
            .iter()
            .filter(|f| f.passes_done as usize >= s.passes.len())
            .count();
        bar.set_message(format!(
            "{finished}/{} frames, {}/{} tiles, {:.2} M samples/s",
            frames.len(),
            s.tiles_done,
            s.tiles_total,
            s.samples_per_second / 1e6
        ));
        for f in &frames {
            let k = f.index as usize;
            if f.passes_done > written[k] {
                let bytes = client.frame_result(id, f.index).await?;
                crate::output::write_replacing(&outputs[k], &bytes)?;
                written[k] = f.passes_done;
            }
        }
        if crate::output::ended(id, &s)? {
            break;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    bar.finish_and_clear();
    // The last merges may have landed between the listing and the end.
    for (k, out) in outputs.iter().enumerate() {
        let bytes = client.frame_result(id, k as u32).await?;
        crate::output::write_replacing(out, &bytes)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn globs_match_as_a_shell_does() {
        for (p, n, m) in [
            ("f*.pbrt", "f0001.pbrt", true),
            ("f*.pbrt", "f0001.pbrt.bak", false),
            ("f????.pbrt", "f0001.pbrt", true),
            ("f????.pbrt", "f001.pbrt", false),
            ("*", "", true),
            ("a*b*c", "axxbyyc", true),
            ("a*b*c", "axxbyy", false),
            ("*.pbrt", "geometry.pbrt", true),
        ] {
            assert_eq!(matches(p, n), m, "{p} against {n}");
        }
    }

    #[test]
    fn frames_are_named_after_their_scene_files() {
        let frames = [PathBuf::from("shot/f1.pbrt"), PathBuf::from("shot/f2.pbrt")];
        let out = outputs(&frames, Path::new("out")).unwrap();
        assert_eq!(
            out,
            [PathBuf::from("out/f1.exr"), PathBuf::from("out/f2.exr")]
        );
        let twice = [PathBuf::from("a/f1.pbrt"), PathBuf::from("b/f1.pbrt")];
        let e = outputs(&twice, Path::new("out")).unwrap_err().to_string();
        assert!(e.contains("a/f1.pbrt and b/f1.pbrt"), "{e}");
    }

    #[test]
    fn a_glob_expands_in_name_order_and_one_that_matches_nothing_is_an_error() {
        let dir = std::env::temp_dir().join(format!("kiln-glob-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for n in ["f2.pbrt", "f1.pbrt", "f10.pbrt", "geometry.ply"] {
            std::fs::write(dir.join(n), "").unwrap();
        }
        let got = expand(&[dir.join("f*.pbrt")]).unwrap();
        let names: Vec<_> = got.iter().map(|p| p.file_name().unwrap()).collect();
        assert_eq!(names, ["f1.pbrt", "f10.pbrt", "f2.pbrt"]);
        let e = expand(&[dir.join("g*.pbrt")]).unwrap_err().to_string();
        assert!(e.contains("no file matches"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
