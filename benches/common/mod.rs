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

/// Writes a binary PLY UV sphere with smooth normals; returns its face count.
#[allow(dead_code)]
pub fn write_sphere_ply(path: &std::path::Path, rings: usize, segments: usize) -> usize {
    let mut verts = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            verts.push([
                libm::sinf(theta) * libm::cosf(phi),
                libm::cosf(theta),
                libm::sinf(theta) * libm::sinf(phi),
            ]);
        }
    }
    let mut faces = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = (i * segments + j) as u32;
            let b = (i * segments + (j + 1) % segments) as u32;
            let (c, d) = (a + segments as u32, b + segments as u32);
            if i != 0 {
                faces.push([a, b, c]);
            }
            if i != rings - 1 {
                faces.push([b, d, c]);
            }
        }
    }
    use std::io::Write;
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(
        f,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        verts.len(),
        faces.len()
    )
    .unwrap();
    for v in &verts {
        for c in v.iter().chain(v.iter()) {
            f.write_all(&c.to_le_bytes()).unwrap();
        }
    }
    for t in &faces {
        f.write_all(&[3u8]).unwrap();
        for i in t {
            f.write_all(&(*i as i32).to_le_bytes()).unwrap();
        }
    }
    faces.len()
}
