//! Images a scene refers to: texture images, and environment maps for the "infinite" light.

use crate::error::{Loc, Result, SceneError};
use crate::textures::{ColorEncoding, ImageData, TextureImage};
use kiln_image::ImageRgb;
use std::path::Path;

/// The most pixels an environment map may hold: 16384 x 8192, 1.5 GiB of float RGB. The
/// EXR's header is checked against it before its pixels are read.
pub const MAX_ENVIRONMENT_PIXELS: u64 = 1 << 27;

/// Reads an environment map as linear RGB, from any format [`read_texture_image`] reads
/// (8-bit PNGs as sRGB, pbrt-v4's default); grey maps become grey RGB, alpha is dropped.
pub fn read_environment(path: &Path, loc: &Loc) -> Result<ImageRgb> {
    let image = read_texture_image(path, ColorEncoding::Srgb, loc)?;
    let n = image.channels;
    let mut pixels = Vec::with_capacity(image.width as usize * image.height as usize);
    for y in 0..image.height {
        for x in 0..image.width {
            let c = |i: u32| image.channel(x, y, i);
            pixels.push(if n < 3 { [c(0); 3] } else { [c(0), c(1), c(2)] });
        }
    }
    Ok(ImageRgb {
        width: image.width,
        height: image.height,
        pixels,
    })
}

/// The most pixels a texture image may hold (as many as an environment map).
pub const MAX_TEXTURE_PIXELS: u64 = MAX_ENVIRONMENT_PIXELS;

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Reads an image file for a texture or a light, as pbrt-v4 reads it: EXR, PFM and HDR as
/// linear floats; PNG with `encoding` (16-bit PNGs decoded to floats); TGA, JPEG, BMP and
/// QOI as sRGB bytes whatever `encoding` says (pbrt-v4 consults it for PNG only). Grey with
/// alpha keeps the grey; RGBA drops an alpha that is 1 everywhere (and TGA, JPEG, BMP and
/// QOI drop alpha always). The size is checked against [`MAX_TEXTURE_PIXELS`] before the
/// pixels are decoded.
pub fn read_texture_image(path: &Path, encoding: ColorEncoding, loc: &Loc) -> Result<TextureImage> {
    let fail = |e: String| SceneError::at(loc, format!("image '{}': {e}", path.display()));
    let bytes = super::read_bytes(path, loc)?;
    let (width, height, channels, data) =
        decode_texture_image(&bytes, &extension(path), encoding).map_err(fail)?;
    Ok(TextureImage {
        width,
        height,
        channels,
        data,
        path: path.to_path_buf(),
    })
}

/// Decodes an image file's bytes by its extension (lower case, without the dot): width,
/// height, channels and pixels, or what is wrong with them.
pub fn decode_texture_image(
    bytes: &[u8],
    ext: &str,
    encoding: ColorEncoding,
) -> std::result::Result<(u32, u32, u32, ImageData), String> {
    let (width, height, channels, data) = match ext {
        "exr" => {
            let image = kiln_image::decode_exr_limited(bytes, MAX_TEXTURE_PIXELS)
                .map_err(|e| e.to_string())?;
            let pixels = image.pixels.iter().flatten().copied().collect();
            (image.width, image.height, 3, ImageData::F32(pixels))
        }
        "pfm" => {
            let (w, h, c, pixels) = decode_pfm(bytes)?;
            (w, h, c, ImageData::F32(pixels))
        }
        ext => decode_with_image_crate(bytes, ext, encoding)?,
    };
    if let ImageData::F32(v) = &data
        && v.iter().any(|v| !v.is_finite())
    {
        return Err("holds a value that is not finite (NaN or infinity)".into());
    }
    Ok((width, height, channels, data))
}

fn check_size(width: u64, height: u64) -> std::result::Result<(), String> {
    if width == 0 || height == 0 {
        return Err("has no pixels".into());
    }
    if width * height > MAX_TEXTURE_PIXELS {
        return Err(format!(
            "is {width}x{height}, more than the {MAX_TEXTURE_PIXELS} pixels Kiln reads"
        ));
    }
    Ok(())
}

/// Keeps `keep` of every `from` values (dropping alpha or a second channel).
fn keep_channels<T: Copy>(v: Vec<T>, from: usize, keep: usize) -> Vec<T> {
    if from == keep {
        return v;
    }
    v.chunks_exact(from)
        .flat_map(|px| px[..keep].iter().copied())
        .collect()
}

fn decode_with_image_crate(
    bytes: &[u8],
    ext: &str,
    encoding: ColorEncoding,
) -> std::result::Result<(u32, u32, u32, ImageData), String> {
    use image::{ColorType, ImageFormat, ImageReader, Limits};
    let format = match ext {
        "png" => ImageFormat::Png,
        "tga" => ImageFormat::Tga,
        "jpg" | "jpeg" => ImageFormat::Jpeg,
        "bmp" => ImageFormat::Bmp,
        "hdr" => ImageFormat::Hdr,
        "qoi" => ImageFormat::Qoi,
        other => {
            return Err(format!(
                "Kiln reads EXR, PFM, PNG, TGA, JPEG, BMP, HDR and QOI images, not '.{other}'"
            ));
        }
    };
    let (w, h) = ImageReader::with_format(std::io::Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|e| e.to_string())?;
    check_size(w as u64, h as u64)?;
    let mut reader = ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = Limits::default();
    limits.max_alloc = Some(MAX_TEXTURE_PIXELS * 16);
    reader.limits(limits);
    let image = reader.decode().map_err(|e| e.to_string())?;
    let png = format == ImageFormat::Png;
    // pbrt-v4 reads only PNGs with the scene's encoding; the other 8-bit formats are sRGB.
    let encoding = if png { encoding } else { ColorEncoding::Srgb };
    let color = image.color();
    let n = color.channel_count() as usize;
    // Grey (1, 2 channels) keeps one; colour keeps RGB, and alpha where PNG has a real one.
    let keep = |alpha_is_one: bool| match n {
        1 | 2 => 1,
        3 => 3,
        _ if png && !alpha_is_one => 4,
        _ => 3,
    };
    match color {
        ColorType::Rgb32F | ColorType::Rgba32F => {
            let v = if n == 4 {
                image.to_rgba32f().into_raw()
            } else {
                image.to_rgb32f().into_raw()
            };
            let k = keep(v.chunks_exact(n).all(|px| n < 4 || px[3] == 1.0));
            Ok((w, h, k as u32, ImageData::F32(keep_channels(v, n, k))))
        }
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 => {
            let mut v = match n {
                1 | 2 => image.to_luma_alpha32f().into_raw(),
                _ => image.to_rgba32f().into_raw(),
            };
            let stride = if n <= 2 { 2 } else { 4 };
            let k = keep(v.chunks_exact(stride).all(|px| px[stride - 1] == 1.0));
            for px in v.chunks_exact_mut(stride) {
                for c in px.iter_mut().take(k.min(3)) {
                    *c = encoding.to_linear(*c);
                }
            }
            Ok((w, h, k as u32, ImageData::F32(keep_channels(v, stride, k))))
        }
        _ => {
            let (v, stride) = match n {
                1 | 2 => (image.to_luma_alpha8().into_raw(), 2),
                _ => (image.to_rgba8().into_raw(), 4),
            };
            let k = keep(v.chunks_exact(stride).all(|px| px[stride - 1] == 255));
            Ok((
                w,
                h,
                k as u32,
                ImageData::U8 {
                    bytes: keep_channels(v, stride, k),
                    encoding,
                },
            ))
        }
    }
}

/// PFM: "PF" (RGB) or "Pf" (grey), the width and height, a scale whose sign gives the byte
/// order (negative: little-endian) and whose magnitude multiplies the values, then rows of
/// 32-bit floats from the bottom row up.
pub fn decode_pfm(bytes: &[u8]) -> std::result::Result<(u32, u32, u32, Vec<f32>), String> {
    let mut pos = 0;
    let mut token = || -> std::result::Result<String, String> {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos - start > 32 {
            return Err("is not a PFM file (its header is cut short or malformed)".into());
        }
        Ok(String::from_utf8_lossy(&bytes[start..pos]).into_owned())
    };
    let channels = match token()?.as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err("is not a PFM file (it does not start with PF or Pf)".into()),
    };
    let number = |s: String, what: &str| -> std::result::Result<f64, String> {
        s.parse::<f64>()
            .map_err(|_| format!("has a malformed PFM {what} '{s}'"))
    };
    let width = number(token()?, "width")?;
    let height = number(token()?, "height")?;
    let scale = number(token()?, "scale")?;
    if width.fract() != 0.0 || height.fract() != 0.0 || width < 0.0 || height < 0.0 {
        return Err(format!("has a malformed PFM size {width}x{height}"));
    }
    check_size(width as u64, height as u64)?;
    if scale == 0.0 || !scale.is_finite() {
        return Err("has a PFM scale of zero or not finite".into());
    }
    // Exactly one whitespace byte ends the header.
    let data = &bytes[(pos + 1).min(bytes.len())..];
    let (w, h) = (width as usize, height as usize);
    let count = w * h * channels;
    if data.len() < count * 4 {
        return Err(format!(
            "is cut short: a {w}x{h} PFM needs {} bytes of pixels, the file has {}",
            count * 4,
            data.len()
        ));
    }
    let little = scale < 0.0;
    let magnitude = scale.abs() as f32;
    let mut pixels = vec![0.0f32; count];
    let row = w * channels;
    for (i, chunk) in data[..count * 4].chunks_exact(4).enumerate() {
        let b = [chunk[0], chunk[1], chunk[2], chunk[3]];
        let v = if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        };
        // File rows run bottom to top; Kiln's images top to bottom.
        let (y, x) = (i / row, i % row);
        pixels[(h - 1 - y) * row + x] = v * magnitude;
    }
    Ok((w as u32, h as u32, channels as u32, pixels))
}
