//! The headline frame's projection: scenes/molten-glass at its full 2880x1920 through
//! `kiln farm --workers 2` (one thread each), as a user renders it, timed whole (process
//! start, scene load, VolumeLight power estimates, merge). A run at 1 spp measures what
//! does not grow with the sample count; a run at `--spp` (64 by default) the cost per
//! sample; the projection for 2048 spp with every pixel taking every sample is the first
//! plus 2047 times the second.
//!
//! The scene asks for adaptive sampling from 256 samples on, which neither run reaches. Its
//! share is measured on the whole frame at `--adaptive-resolution` (360x240 by default; 0
//! skips it): `kiln render` at the target count with the scene's threshold and with none;
//! the adaptive projection scales the per-sample part by the ratio of their times.
//! (`cargo bench --bench adaptive` says what error that time buys.)
//!
//! `cargo bench --bench headline [-- --spp N --target-spp N --adaptive-resolution W]`
//! (about 14 minutes on 2 cores)

mod common;
use common::arg;
use std::process::Command;
use std::time::Instant;

fn main() {
    let kiln = env!("CARGO_BIN_EXE_kiln");
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/molten-glass/scene.pbrt"
    );
    let spp: u32 = arg("--spp", 64);
    let target: u32 = arg("--target-spp", 2048);
    let dir = tempfile::tempdir().unwrap();
    let run = |spp: u32| {
        let out = dir.path().join(format!("headline-{spp}.exr"));
        let start = Instant::now();
        let s = Command::new(kiln)
            .args([
                "farm",
                scene,
                "-q",
                "--workers",
                "2",
                "--threads-per-worker",
                "1",
            ])
            .args(["--spp", &spp.to_string(), "-o", out.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
        start.elapsed().as_secs_f64()
    };
    let fixed = run(1);
    let full = run(spp);
    let per_spp = (full - fixed) / (spp - 1) as f64;
    let samples = 2880.0 * 1920.0 * spp as f64;
    let projected = fixed + per_spp * (target - 1) as f64;
    println!(
        "headline 2880x1920 kiln farm --workers 2: 1 spp {fixed:.1} s, {spp} spp {full:.1} s \
         ({:.3} M samples/s over the whole run, {:.3} M samples/s past the fixed cost); \
         {target} spp projected {projected:.0} s = {:.2} h (issue 36's target: under 2.5 h)",
        samples / full / 1e6,
        2880.0 * 1920.0 / per_spp / 1e6,
        projected / 3600.0
    );
    let width: u32 = arg("--adaptive-resolution", 360);
    if width == 0 {
        return;
    }
    let resolution = format!("{width}x{}", width * 2 / 3);
    let time_render = |threshold: Option<&str>| {
        let out = dir.path().join("adaptive.exr");
        let mut cmd = Command::new(kiln);
        cmd.args(["render", scene, "-q", "--resolution", &resolution])
            .args(["--spp", &target.to_string(), "-o", out.to_str().unwrap()]);
        if let Some(t) = threshold {
            cmd.args(["--noise-threshold", t]);
        }
        let start = Instant::now();
        let s = cmd.output().unwrap();
        assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
        start.elapsed().as_secs_f64()
    };
    let uniform = time_render(Some("0"));
    let adaptive = time_render(None);
    let share = adaptive / uniform;
    let projected = fixed + per_spp * (target - 1) as f64 * share;
    println!(
        "headline adaptive sampling (the scene's threshold) at {resolution}, {target} spp: \
         {adaptive:.1} s against {uniform:.1} s with every pixel taking every sample ({share:.3}); \
         {target} spp projected {projected:.0} s = {:.2} h (issue 36's target: under 1.5 h)",
        projected / 3600.0
    );
}
