//! A job's frames (a shot): where each frame's scene is in the bundle, what every frame
//! must share with the first (the film, the colour mode, the integrator's kind), and the
//! order their tiles are lent in (first, last, middle, then the rest: a quick look at the
//! whole shot).
//!
//! A job of one frame is a shot of one. A tile's index in its job is its frame's index
//! times the tiles a frame has, plus its index in the frame.

use super::super::error::PlanError;
use crate::api::{JobSpec, MAX_FRAMES};
use crate::bundle;
use kiln_scene::{MeshCache, SceneDescription};
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

/// How many bytes of meshes planning a shot keeps for its next frame.
pub const PLAN_MESH_BUDGET: u64 = 1 << 30;

/// Checks the job's frame list: at most [`MAX_FRAMES`], each a relative path inside the
/// bundle (no root, no `..`), none twice.
pub fn check_frames(spec: &JobSpec) -> Result<(), PlanError> {
    let frames = &spec.frames;
    if frames.len() > MAX_FRAMES {
        return Err(PlanError::Frames(format!(
            "{} frames; a job has at most {MAX_FRAMES}",
            frames.len()
        )));
    }
    let mut seen = std::collections::HashSet::with_capacity(frames.len());
    for (k, name) in frames.iter().enumerate() {
        let p = Path::new(name);
        if name.is_empty()
            || name.len() > bundle::MAX_PATH_BYTES
            || p.components().any(|c| !matches!(c, Component::Normal(_)))
        {
            return Err(PlanError::Frames(format!(
                "frame {}: {} is not a path inside the scene bundle",
                k + 1,
                shown(name)
            )));
        }
        if !seen.insert(name.as_str()) {
            return Err(PlanError::Frames(format!(
                "frame {}: {} is listed twice",
                k + 1,
                shown(name)
            )));
        }
    }
    Ok(())
}

/// A frame's name as a message quotes it: at most 80 characters, escaped.
fn shown(name: &str) -> String {
    let cut: String = name.chars().take(80).collect();
    let more = if name.chars().count() > 80 { "..." } else { "" };
    format!("'{}{more}'", cut.escape_debug())
}

/// Where frame `frame`'s scene file is, in the bundle unpacked at `root` whose own scene
/// file is `scene`.
pub fn frame_path(
    scene: &Path,
    root: &Path,
    spec: &JobSpec,
    frame: usize,
) -> Result<PathBuf, PlanError> {
    let Some(name) = spec.frame_scene(frame) else {
        return Ok(scene.to_path_buf());
    };
    let path = root.join(name);
    if !path.is_file() {
        return Err(PlanError::Frames(format!(
            "frame {}: {} is not in the scene bundle",
            frame + 1,
            shown(name)
        )));
    }
    Ok(path)
}

/// Loads frame `frame`'s scene (at `path`, confined to `root`) with the job's overrides,
/// sharing meshes through `meshes`, and checks its size. Errors name the frame.
pub fn load(
    path: &Path,
    root: &Path,
    spec: &JobSpec,
    frame: usize,
    max_frame_pixels: u64,
    meshes: &Arc<MeshCache>,
) -> Result<SceneDescription, PlanError> {
    let which = |m: String| match spec.frame_scene(frame) {
        Some(name) => format!("frame {} ({name}): {m}", frame + 1),
        None => m,
    };
    let mut desc = kiln_scene::load_file_within_sharing(path, root, Some(meshes.clone()))
        .map_err(|e| PlanError::Scene(which(bundle::relative_message(&e, root))))?;
    desc.apply_overrides(&spec.overrides())
        .map_err(|m| PlanError::Overrides(which(m)))?;
    desc.check_frame_size(max_frame_pixels)
        .map_err(|m| PlanError::Overrides(which(m)))?;
    Ok(desc)
}

/// Checks that frame `frame` (`other`) renders into the frame the first (`first`) set up:
/// the same film size, window and channels, colour mode, integrator kind and sums.
pub fn check_alike(
    first: &SceneDescription,
    other: &SceneDescription,
    spec: &JobSpec,
    frame: usize,
) -> Result<(), PlanError> {
    let (a, b) = (&first.film, &other.film);
    let differs = |what: &str, mine: String, theirs: String| {
        Err(PlanError::Frames(format!(
            "frame {} ({}): its {what} is {mine} and frame 1's is {theirs}; a shot's frames share it",
            frame + 1,
            spec.frame_scene(frame).unwrap_or_default(),
        )))
    };
    if (a.xresolution, a.yresolution) != (b.xresolution, b.yresolution) {
        return differs(
            "film",
            format!("{}x{}", b.xresolution, b.yresolution),
            format!("{}x{}", a.xresolution, a.yresolution),
        );
    }
    if a.pixel_bounds != b.pixel_bounds {
        return differs(
            "pixel bounds",
            format!("{:?}", b.pixel_bounds),
            format!("{:?}", a.pixel_bounds),
        );
    }
    if a.gbuffer != b.gbuffer {
        return differs("film type", film_type(b.gbuffer), film_type(a.gbuffer));
    }
    if first.spectral != other.spectral {
        return differs("colour mode", mode(other.spectral), mode(first.spectral));
    }
    if first.integrator.kind != other.integrator.kind {
        return differs(
            "integrator",
            format!("{:?}", other.integrator.kind),
            format!("{:?}", first.integrator.kind),
        );
    }
    let sums =
        |d: &SceneDescription| kiln_render::RenderSettings::from_description(d).sums_layout();
    if sums(first) != sums(other) {
        return differs(
            "sampler's running sums",
            format!("{:?}", sums(other)),
            format!("{:?}", sums(first)),
        );
    }
    Ok(())
}

fn film_type(gbuffer: Option<kiln_scene::GBufferSpace>) -> String {
    match gbuffer {
        Some(space) => format!("gbuffer ({space:?})"),
        None => "rgb".into(),
    }
}

fn mode(spectral: bool) -> String {
    if spectral { "spectral" } else { "RGB" }.into()
}

/// The order a shot of `frames` frames of `tiles` tiles each is lent in: the first frame,
/// the last, the middle one, then the rest in order, each frame's tiles in order.
pub fn lending_order(tiles: usize, frames: usize) -> Vec<usize> {
    let mut order: Vec<usize> = Vec::with_capacity(frames);
    for f in [0, frames.saturating_sub(1), frames / 2]
        .into_iter()
        .chain(0..frames)
    {
        if f < frames && !order.contains(&f) {
            order.push(f);
        }
        if order.len() == frames.min(3) {
            break;
        }
    }
    let mut seen = vec![false; frames];
    for &f in &order {
        seen[f] = true;
    }
    order.extend((0..frames).filter(|&f| !seen[f]));
    order
        .into_iter()
        .flat_map(|f| f * tiles..(f + 1) * tiles)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_lent_first_last_middle_then_the_rest() {
        let frames_of = |tiles: usize, frames: usize| -> Vec<usize> {
            let order = lending_order(tiles, frames);
            assert_eq!(order.len(), tiles * frames);
            let mut sorted = order.clone();
            sorted.sort_unstable();
            assert_eq!(
                sorted,
                (0..tiles * frames).collect::<Vec<_>>(),
                "each tile once"
            );
            order.chunks(tiles).map(|c| c[0] / tiles).collect()
        };
        assert_eq!(frames_of(2, 1), [0]);
        assert_eq!(frames_of(1, 2), [0, 1]);
        assert_eq!(frames_of(3, 3), [0, 2, 1]);
        assert_eq!(frames_of(2, 5), [0, 4, 2, 1, 3]);
        assert_eq!(frames_of(1, 48)[..5], [0, 47, 24, 1, 2]);
        // Each frame's tiles stay together and in order.
        assert_eq!(lending_order(2, 3), [0, 1, 4, 5, 2, 3]);
    }

    #[test]
    fn a_frame_list_is_paths_inside_the_bundle() {
        let spec = |frames: &[&str]| JobSpec {
            frames: frames.iter().map(|f| f.to_string()).collect(),
            ..JobSpec::new("x")
        };
        assert!(check_frames(&spec(&["f1.pbrt", "shots/f2.pbrt"])).is_ok());
        for (bad, says) in [
            (
                vec!["../f1.pbrt"],
                "frame 1: '../f1.pbrt' is not a path inside",
            ),
            (vec!["a.pbrt", "/etc/passwd"], "frame 2: '/etc/passwd'"),
            (vec!["a.pbrt", ""], "frame 2: '' is not"),
            (
                vec!["a.pbrt", "a.pbrt"],
                "frame 2: 'a.pbrt' is listed twice",
            ),
        ] {
            let e = check_frames(&spec(&bad)).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
        let many = vec!["f.pbrt"; MAX_FRAMES + 1];
        let e = check_frames(&spec(&many)).unwrap_err().to_string();
        assert!(e.contains("at most 10000"), "{e}");
    }
}
