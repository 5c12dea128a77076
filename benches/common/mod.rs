//! What the benchmarks share: flag parsing, peak memory, timed tile rendering.

/// The value after `--name` on the command line, or `default`.
pub fn arg<T: std::str::FromStr>(name: &str, default: T) -> T {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Peak resident memory of this process in MiB, from /proc (Linux).
#[allow(dead_code)]
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Renders the pixels `bounds` in 32-pixel tiles on rayon's pool (as `kiln render` does:
/// SPPM iterates over all of them at once); returns the seconds taken and the tiles in
/// order.
#[allow(dead_code)]
pub fn render_tiles(
    renderer: &kiln_render::Renderer,
    bounds: [u32; 4],
) -> (f64, Vec<kiln_render::TileResult>) {
    let tiles = kiln_render::split_into_tiles(bounds, 32);
    let start = std::time::Instant::now();
    let results = kiln_render::render_tiles(renderer, &tiles, &|| {});
    (start.elapsed().as_secs_f64(), results)
}

/// [`render_tiles`] over the frame `0..w` x `0..h`, the tiles put together: seconds,
/// samples and the row-major pixels.
#[allow(dead_code)]
pub fn render_image(
    renderer: &kiln_render::Renderer,
    (w, h): (u32, u32),
) -> (f64, u64, Vec<[f32; 3]>) {
    let (secs, results) = render_tiles(renderer, [0, w, 0, h]);
    let mut pixels = vec![[0.0f32; 3]; (w * h) as usize];
    let mut samples = 0;
    for r in &results {
        samples += r.stats.samples;
        for (i, p) in r.pixels.iter().enumerate() {
            let (x, y) = (
                r.rect.x0 + i as u32 % r.rect.width,
                r.rect.y0 + i as u32 / r.rect.width,
            );
            pixels[(y * w + x) as usize] = *p;
        }
    }
    (secs, samples, pixels)
}
