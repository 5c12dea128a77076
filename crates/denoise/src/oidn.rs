//! Intel Open Image Denoise's ray-tracing filter, with the render's albedo and normals as
//! its auxiliary images (the `oidn` cargo feature; the library found through OIDN_DIR).
//! Its network runs on whatever instructions the CPU has, so its output is not
//! bit-reproducible across machines.

use crate::{Error, Noisy};

pub fn denoise(input: &Noisy) -> Result<Vec<[f32; 3]>, Error> {
    let flat = |v: &[[f32; 3]]| v.iter().flatten().copied().collect::<Vec<f32>>();
    let color = flat(&input.color);
    // OIDN wants albedo in [0, 1].
    let albedo: Vec<f32> = flat(&input.albedo)
        .into_iter()
        .map(|v| v.clamp(0.0, 1.0))
        .collect();
    let normal = flat(&input.normal);
    let mut out = vec![0.0f32; color.len()];
    let failed = |e: oidn::Error| Error::Oidn(format!("{:?}: {}", e.kind(), e.message()));
    // On the CPU: a farm's coordinator and workers have no other device to count on.
    let device = oidn::Device::cpu().map_err(failed)?;
    oidn::RayTracing::try_new(&device)
        .map_err(failed)?
        .hdr(true)
        .srgb(false)
        .image_dimensions(input.width, input.height)
        .albedo_normal(&albedo, &normal)
        .filter(&color, &mut out)
        .map_err(failed)?;
    device.get_error().map_err(failed)?;
    Ok(out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}
