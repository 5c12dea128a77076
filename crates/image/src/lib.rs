//! Image files for Kiln: float32 RGB EXR frames and tiles (with a data window
//! inside a display window), EXR reading for environment maps and reference
//! images, and sRGB PNG previews.
//!
//! ```
//! let frame = kiln_image::RgbBuffer::new(4, 2, 0, 0, 4, 2);
//! let bytes = kiln_image::encode_exr(&frame).unwrap();
//! let back = kiln_image::decode_exr(&bytes).unwrap();
//! assert_eq!(back.width, 4);
//! ```

use std::io::Cursor;
use std::path::Path;

/// Why an image could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("cannot read or write '{path}': {cause}")]
    Io { path: String, cause: std::io::Error },
    #[error("EXR: {0}")]
    Exr(String),
    #[error("PNG: {0}")]
    Png(String),
    #[error("{0}")]
    Invalid(String),
}

/// A rectangle of RGB pixels placed inside a frame (display window).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbBuffer {
    /// Size of the whole frame (the display window).
    pub frame_width: u32,
    pub frame_height: u32,
    /// The data window: origin and size of the pixels held, inside the frame.
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first, `width * height` entries.
    pub pixels: Vec<[f32; 3]>,
    /// Further channels (a G-buffer's), written beside R, G and B.
    pub aovs: Aovs,
    /// Exact 32-bit integer channels (a farm tile's running sums, bit for bit), which
    /// [`RgbBuffer::paste`] leaves behind: they travel with a tile, never into a frame.
    pub words: Words,
}

/// Channels beyond R, G and B: their names, sorted (as EXR stores channels), and their
/// values, `names.len()` per pixel in the pixels' order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Aovs {
    pub names: Vec<String>,
    pub values: Vec<f32>,
}

/// The most channels beyond R, G and B that an image may hold.
pub const MAX_AOVS: usize = 64;

/// Unsigned 32-bit integer channels, stored exactly (EXR's UINT type): their names, sorted,
/// and `names.len()` values per pixel in the pixels' order. Any EXR reader shows them as
/// integers; Kiln keeps a farm tile's running sums in them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Words {
    pub names: Vec<String>,
    pub values: Vec<u32>,
}

/// The most integer channels an image may hold.
pub const MAX_WORDS: usize = 128;

impl RgbBuffer {
    /// A black buffer of `width x height` at (x0, y0) in a `frame_width x frame_height` frame.
    pub fn new(
        frame_width: u32,
        frame_height: u32,
        x0: u32,
        y0: u32,
        width: u32,
        height: u32,
    ) -> RgbBuffer {
        RgbBuffer {
            frame_width,
            frame_height,
            x0,
            y0,
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
            aovs: Aovs::default(),
            words: Words::default(),
        }
    }

    /// This buffer holding `pixels` (row by row, one per pixel of its window) and the
    /// further channels `aovs`: a rendered tile as an image, as a worker uploads it and
    /// `kiln render` pastes it.
    pub fn holding(mut self, pixels: Vec<[f32; 3]>, aovs: Aovs) -> RgbBuffer {
        debug_assert_eq!(pixels.len(), self.pixels.len());
        self.pixels = pixels;
        self.aovs = aovs;
        self
    }

    /// This buffer with the further channels `names` (sorted here), all zero.
    pub fn with_aovs<S: Into<String>>(mut self, names: impl IntoIterator<Item = S>) -> RgbBuffer {
        let mut names: Vec<String> = names.into_iter().map(Into::into).collect();
        names.sort();
        self.aovs.values = vec![0.0; names.len() * self.pixels.len()];
        self.aovs.names = names;
        self
    }

    /// The further channels' values at (x, y) of the data window.
    pub fn aovs_at(&self, x: u32, y: u32) -> &[f32] {
        let n = self.aovs.names.len();
        let i = (y * self.width + x) as usize * n;
        &self.aovs.values[i..i + n]
    }

    pub fn windows(&self) -> Windows {
        Windows {
            frame_width: self.frame_width,
            frame_height: self.frame_height,
            x0: self.x0,
            y0: self.y0,
            width: self.width,
            height: self.height,
        }
    }

    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Copies `tile`'s pixels into this buffer at the tile's data window (both windows are
    /// in the same frame's coordinates). A tile of another frame size, one whose pixels do
    /// not match its window, or one that reaches outside this buffer's data window is an
    /// error and leaves this buffer unchanged.
    pub fn paste(&mut self, tile: &RgbBuffer) -> Result<(), ImageError> {
        if (tile.frame_width, tile.frame_height) != (self.frame_width, self.frame_height) {
            return Err(ImageError::Invalid(format!(
                "a tile of a {}x{} frame cannot be pasted into a {}x{} frame",
                tile.frame_width, tile.frame_height, self.frame_width, self.frame_height
            )));
        }
        if tile.pixels.len() as u64 != tile.width as u64 * tile.height as u64 {
            return Err(ImageError::Invalid(
                "tile size does not match its pixels".into(),
            ));
        }
        if tile.aovs.names != self.aovs.names {
            return Err(ImageError::Invalid(format!(
                "a tile with channels R, G, B{} cannot be pasted into a frame with R, G, B{}",
                tile.aovs
                    .names
                    .iter()
                    .map(|n| format!(", {n}"))
                    .collect::<String>(),
                self.aovs
                    .names
                    .iter()
                    .map(|n| format!(", {n}"))
                    .collect::<String>(),
            )));
        }
        if tile.aovs.values.len() != tile.pixels.len() * tile.aovs.names.len() {
            return Err(ImageError::Invalid(
                "tile's further channels do not match its pixels".into(),
            ));
        }
        let inside = |t0: u32, tn: u32, s0: u32, sn: u32| {
            t0 >= s0 && t0 as u64 + tn as u64 <= s0 as u64 + sn as u64
        };
        if !inside(tile.x0, tile.width, self.x0, self.width)
            || !inside(tile.y0, tile.height, self.y0, self.height)
        {
            return Err(ImageError::Invalid(format!(
                "the {}x{} tile at {},{} does not fit the {}x{} data window at {},{}",
                tile.width,
                tile.height,
                tile.x0,
                tile.y0,
                self.width,
                self.height,
                self.x0,
                self.y0
            )));
        }
        let w = tile.width as usize;
        for row in 0..tile.height as usize {
            let src = row * w;
            let dst = (tile.y0 - self.y0) as usize * self.width as usize
                + row * self.width as usize
                + (tile.x0 - self.x0) as usize;
            self.pixels[dst..dst + w].copy_from_slice(&tile.pixels[src..src + w]);
            let n = self.aovs.names.len();
            if n > 0 {
                self.aovs.values[dst * n..(dst + w) * n]
                    .copy_from_slice(&tile.aovs.values[src * n..(src + w) * n]);
            }
        }
        Ok(())
    }

    /// Mean of each channel over the data window.
    pub fn mean(&self) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                sum[c] += p[c] as f64;
            }
        }
        let n = self.pixels.len().max(1) as f64;
        sum.map(|s| s / n)
    }
}

/// A plain RGB image, as read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageRgb {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

/// Images smaller than this are encoded and decoded on the calling thread.
const PARALLEL_PIXELS: usize = 1 << 18;

/// Encodes a buffer as an EXR: float32 R, G, B; display window = the frame, data window = the buffer.
pub fn encode_exr(buffer: &RgbBuffer) -> Result<Vec<u8>, ImageError> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, IntegerBounds, Layer,
        LayerAttributes, Vec2, WritableImage,
    };
    if buffer.pixels.len() != buffer.width as usize * buffer.height as usize
        || buffer.width == 0
        || buffer.height == 0
        || buffer.aovs.values.len() != buffer.pixels.len() * buffer.aovs.names.len()
        || buffer.words.values.len() != buffer.pixels.len() * buffer.words.names.len()
    {
        return Err(ImageError::Invalid(
            "buffer size does not match its pixels".into(),
        ));
    }
    let channel = |name: &str, c: usize| {
        AnyChannel::new(
            name,
            FlatSamples::F32(buffer.pixels.iter().map(|p| p[c]).collect()),
        )
    };
    let mut list = vec![channel("B", 2), channel("G", 1), channel("R", 0)];
    // Channel c of values interleaved n to a pixel.
    fn column<T: Copy>(values: &[T], c: usize, n: usize) -> Vec<T> {
        values.iter().skip(c).step_by(n).copied().collect()
    }
    let (aovs, words) = (&buffer.aovs, &buffer.words);
    for (c, name) in aovs.names.iter().enumerate() {
        let samples = FlatSamples::F32(column(&aovs.values, c, aovs.names.len()));
        list.push(AnyChannel::new(name.as_str(), samples));
    }
    for (c, name) in words.names.iter().enumerate() {
        let samples = FlatSamples::U32(column(&words.values, c, words.names.len()));
        list.push(AnyChannel::new(name.as_str(), samples));
    }
    let channels = AnyChannels::sort(smallvec_of(list));
    let size = Vec2(buffer.width as usize, buffer.height as usize);
    let attributes = LayerAttributes {
        layer_position: Vec2(buffer.x0 as i32, buffer.y0 as i32),
        ..Default::default()
    };
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, channels);
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new(
        Vec2(0, 0),
        Vec2(buffer.frame_width as usize, buffer.frame_height as usize),
    );
    let mut bytes = Vec::new();
    // exr's parallel writer starts a thread pool per image: worth it for whole frames,
    // ruinous for the small tiles a farm coordinator receives by the thousand.
    let writer = image.write();
    let writer = if buffer.pixels.len() < PARALLEL_PIXELS {
        writer.non_parallel()
    } else {
        writer
    };
    writer
        .to_buffered(Cursor::new(&mut bytes))
        .map_err(|e| ImageError::Exr(e.to_string()))?;
    Ok(bytes)
}

fn smallvec_of(
    v: Vec<exr::prelude::AnyChannel<exr::prelude::FlatSamples>>,
) -> exr::prelude::SmallVec<[exr::prelude::AnyChannel<exr::prelude::FlatSamples>; 4]> {
    v.into_iter().collect()
}

/// Decodes an EXR written by [`encode_exr`] (or any EXR with R, G, B channels in its first layer).
pub fn decode_exr(bytes: &[u8]) -> Result<RgbBuffer, ImageError> {
    decode_exr_limited(bytes, MAX_PIXELS)
}

/// The most pixels [`decode_exr`] accepts in an image's data window or display window: a
/// 16384 x 16384 frame, 3 GiB of float RGB. [`decode_exr_limited`] takes another limit.
pub const MAX_PIXELS: u64 = 1 << 28;

/// The most bytes the samples of an image's data window may take, all its channels
/// together, whatever its pixel count: 3 GiB. A header claiming more (many channels over
/// a large window) is refused before anything of that size is allocated.
pub const MAX_SAMPLE_BYTES: u64 = 3 << 30;

/// Where an image's pixels sit: the frame's size (the display window) and the data window
/// inside it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Windows {
    pub frame_width: u32,
    pub frame_height: u32,
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
}

/// Reads an EXR's windows (of its first layer) from its header alone, decoding no pixels.
pub fn read_exr_windows(bytes: &[u8]) -> Result<Windows, ImageError> {
    read_exr_header(bytes).map(|(w, _)| w)
}

/// An EXR's windows (of its first layer) and the bytes a pixel's samples take, all its
/// channels together, from its header alone.
fn read_exr_header(bytes: &[u8]) -> Result<(Windows, u64), ImageError> {
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| ImageError::Exr(e.to_string()))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| ImageError::Exr("no layer".into()))?;
    let bytes_per_pixel = header.channels.bytes_per_pixel as u64;
    let display = header.shared_attributes.display_window;
    let pos = header.own_attributes.layer_position;
    let to_u32 = |v: usize, what: &str| {
        u32::try_from(v).map_err(|_| ImageError::Invalid(format!("EXR {what} {v} is too large")))
    };
    let windows = Windows {
        frame_width: to_u32(display.size.0, "width")?,
        frame_height: to_u32(display.size.1, "height")?,
        x0: (pos.0 as i64 - display.position.0 as i64).clamp(0, u32::MAX as i64) as u32,
        y0: (pos.1 as i64 - display.position.1 as i64).clamp(0, u32::MAX as i64) as u32,
        width: to_u32(header.layer_size.0, "width")?,
        height: to_u32(header.layer_size.1, "height")?,
    };
    Ok((windows, bytes_per_pixel))
}

/// Decodes an EXR whose data window holds at most `max_pixels` pixels (and whose display
/// window, the frame, at most [`MAX_PIXELS`]). The header is read and checked before
/// anything the size of the image is allocated, so a small file that claims a huge image
/// is an error, not an allocation failure.
pub fn decode_exr_limited(bytes: &[u8], max_pixels: u64) -> Result<RgbBuffer, ImageError> {
    use exr::prelude::{ReadChannels, ReadLayers};
    let (w, bytes_per_pixel) = read_exr_header(bytes)?;
    let checks = [
        ("data window", w.width, w.height, max_pixels),
        ("display window", w.frame_width, w.frame_height, MAX_PIXELS),
    ];
    for (what, width, height, limit) in checks {
        if u64::from(width) * u64::from(height) > limit {
            return Err(ImageError::Invalid(format!(
                "EXR {what} of {width}x{height} pixels is larger than the {limit} pixels allowed here"
            )));
        }
    }
    let sample_bytes = u64::from(w.width) * u64::from(w.height) * bytes_per_pixel;
    if sample_bytes > MAX_SAMPLE_BYTES {
        return Err(ImageError::Invalid(format!(
            "EXR data window of {}x{} pixels at {bytes_per_pixel} bytes each ({sample_bytes} bytes) is larger than the {MAX_SAMPLE_BYTES} bytes allowed",
            w.width, w.height
        )));
    }
    let reader = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes();
    // Small files (a farm's tiles) decode on the calling thread; see PARALLEL_PIXELS.
    let reader = if bytes.len() < PARALLEL_PIXELS * 4 {
        reader.non_parallel()
    } else {
        reader
    };
    let image = reader
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| ImageError::Exr(e.to_string()))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    let mut pixels = vec![[0.0f32; 3]; w * h];
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        let channel = layer
            .channel_data
            .list
            .iter()
            .find(|ch| ch.name.to_string() == *name)
            .ok_or_else(|| ImageError::Exr(format!("no {name} channel")))?;
        for (i, v) in channel.sample_data.values_as_f32().enumerate() {
            if i < pixels.len() {
                pixels[i][c] = v;
            }
        }
    }
    // Every other channel but alpha is a further channel, in the file's (sorted) order:
    // the integer ones words, the rest float.
    let is_word = |ch: &&exr::prelude::AnyChannel<exr::prelude::FlatSamples>| {
        matches!(ch.sample_data, exr::prelude::FlatSamples::U32(_))
    };
    let (word_channels, others): (Vec<_>, Vec<_>) = layer
        .channel_data
        .list
        .iter()
        .filter(|ch| !["R", "G", "B", "A"].contains(&ch.name.to_string().as_str()))
        .partition(is_word);
    if word_channels.len() > MAX_WORDS {
        return Err(ImageError::Invalid(format!(
            "EXR has {} integer channels; at most {MAX_WORDS} are read",
            word_channels.len()
        )));
    }
    let mut words = Words {
        names: word_channels.iter().map(|ch| ch.name.to_string()).collect(),
        values: vec![0; word_channels.len() * w * h],
    };
    words.names.sort();
    let nw = word_channels.len();
    for ch in &word_channels {
        let name = ch.name.to_string();
        let c = words.names.iter().position(|n| *n == name).unwrap_or(0);
        if let exr::prelude::FlatSamples::U32(v) = &ch.sample_data {
            for (i, &x) in v.iter().enumerate().take(w * h) {
                words.values[i * nw + c] = x;
            }
        }
    }
    if others.len() > MAX_AOVS {
        return Err(ImageError::Invalid(format!(
            "EXR has {} channels besides R, G, B and A; at most {MAX_AOVS} are read",
            others.len()
        )));
    }
    let mut aovs = Aovs {
        names: others.iter().map(|ch| ch.name.to_string()).collect(),
        values: vec![0.0; others.len() * w * h],
    };
    aovs.names.sort();
    for ch in &others {
        let c = aovs
            .names
            .iter()
            .position(|n| *n == ch.name.to_string())
            .unwrap();
        for (i, v) in ch.sample_data.values_as_f32().enumerate().take(w * h) {
            aovs.values[i * others.len() + c] = v;
        }
    }
    let display = image.attributes.display_window;
    let pos = layer.attributes.layer_position;
    Ok(RgbBuffer {
        frame_width: display.size.0 as u32,
        frame_height: display.size.1 as u32,
        x0: (pos.0 - display.position.0).max(0) as u32,
        y0: (pos.1 - display.position.1).max(0) as u32,
        width: w as u32,
        height: h as u32,
        pixels,
        aovs,
        words,
    })
}

/// Reads an EXR file's first layer as RGB (environment maps, reference renders).
pub fn read_exr_rgb(path: &Path) -> Result<ImageRgb, ImageError> {
    let bytes = std::fs::read(path).map_err(|cause| ImageError::Io {
        path: path.display().to_string(),
        cause,
    })?;
    let b = decode_exr(&bytes)?;
    Ok(ImageRgb {
        width: b.width,
        height: b.height,
        pixels: b.pixels,
    })
}

/// Writes a buffer to an EXR file.
pub fn write_exr(path: &Path, buffer: &RgbBuffer) -> Result<(), ImageError> {
    let bytes = encode_exr(buffer)?;
    std::fs::write(path, bytes).map_err(|cause| ImageError::Io {
        path: path.display().to_string(),
        cause,
    })
}

fn srgb_encode(linear: f32) -> u8 {
    let v = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * libm::powf(v, 1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Encodes a PNG preview: linear values times 2^exposure, clamped, sRGB-encoded, 8 bits.
pub fn encode_png(buffer: &RgbBuffer, exposure: f32) -> Result<Vec<u8>, ImageError> {
    let gain = libm::powf(2f32, exposure);
    let mut data = Vec::with_capacity(buffer.pixels.len() * 3);
    for p in &buffer.pixels {
        for c in p {
            data.push(srgb_encode(c * gain));
        }
    }
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, buffer.width, buffer.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder
            .write_header()
            .map_err(|e| ImageError::Png(e.to_string()))?;
        writer
            .write_image_data(&data)
            .map_err(|e| ImageError::Png(e.to_string()))?;
    }
    Ok(bytes)
}

pub fn write_png(path: &Path, buffer: &RgbBuffer, exposure: f32) -> Result<(), ImageError> {
    let bytes = encode_png(buffer, exposure)?;
    std::fs::write(path, bytes).map_err(|cause| ImageError::Io {
        path: path.display().to_string(),
        cause,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_pixels_and_windows() {
        let mut b = RgbBuffer::new(10, 8, 3, 2, 4, 5);
        for (i, p) in b.pixels.iter_mut().enumerate() {
            *p = [i as f32, 0.5 * i as f32, -1.0 / (i as f32 + 1.0)];
        }
        let back = decode_exr(&encode_exr(&b).unwrap()).unwrap();
        assert_eq!(back, b);
    }

    /// Further channels (a G-buffer's) survive an EXR round trip and a paste, value for
    /// value; a tile whose channels differ from the frame's is refused.
    #[test]
    fn further_channels_round_trip_and_paste() {
        let mut tile = RgbBuffer::new(10, 8, 3, 2, 4, 5).with_aovs(["P.Z", "Albedo.R", "u"]);
        assert_eq!(tile.aovs.names, ["Albedo.R", "P.Z", "u"]);
        for (i, v) in tile.aovs.values.iter_mut().enumerate() {
            *v = i as f32 * 0.25 - 3.0;
        }
        let back = decode_exr(&encode_exr(&tile).unwrap()).unwrap();
        assert_eq!(back, tile);
        let mut frame = RgbBuffer::new(10, 8, 0, 0, 10, 8).with_aovs(["u", "P.Z", "Albedo.R"]);
        frame.paste(&tile).unwrap();
        assert_eq!(frame.aovs_at(3, 2), tile.aovs_at(0, 0));
        assert_eq!(frame.aovs_at(6, 6), tile.aovs_at(3, 4));
        assert_eq!(frame.aovs_at(2, 2), [0.0; 3]);
        let mut plain = RgbBuffer::new(10, 8, 0, 0, 10, 8);
        assert!(plain.paste(&tile).is_err());
        assert!(frame.paste(&RgbBuffer::new(10, 8, 3, 2, 4, 5)).is_err());
    }

    /// Integer channels keep every bit (NaN patterns and all, which a float channel could
    /// not promise), come back in name order beside float ones, and are not pasted.
    #[test]
    fn integer_channels_round_trip_exactly_and_stay_out_of_frames() {
        let mut tile = RgbBuffer::new(10, 8, 3, 2, 4, 5).with_aovs(["u"]);
        tile.words = Words {
            names: vec!["kiln.b".into(), "kiln.a".into()],
            values: Vec::new(),
        };
        tile.words.names.sort();
        tile.words.values = (0..40u32)
            .map(|i| i.wrapping_mul(0x9e37_79b9) ^ 0x7fc0_0001)
            .collect();
        tile.words.values[0] = u32::MAX;
        let back = decode_exr(&encode_exr(&tile).unwrap()).unwrap();
        assert_eq!(back, tile);
        let mut frame = RgbBuffer::new(10, 8, 0, 0, 10, 8).with_aovs(["u"]);
        frame.paste(&tile).unwrap();
        assert!(frame.words.names.is_empty() && frame.words.values.is_empty());
        let mut short = tile.clone();
        short.words.values.pop();
        assert!(encode_exr(&short).is_err(), "words must match the pixels");
    }
    /// A tiny file whose header claims a huge image (the 440-byte tile upload that aborted
    /// the coordinator) is refused before anything of that size is allocated.
    #[test]
    fn an_exr_claiming_a_huge_window_is_refused_before_allocating() {
        let bytes = encode_exr(&RgbBuffer::new(1, 1, 0, 0, 1, 1)).unwrap();
        for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
            let mut evil = bytes.clone();
            let at = evil
                .windows(name.len())
                .position(|w| w == name)
                .expect("the attribute is in the header")
                + name.len()
                + 4;
            // xMax and yMax: 100,000 x 100,000 pixels.
            evil[at + 8..at + 12].copy_from_slice(&99_999i32.to_le_bytes());
            evil[at + 12..at + 16].copy_from_slice(&99_999i32.to_le_bytes());
            let err = decode_exr(&evil).unwrap_err().to_string();
            assert!(err.contains("100000x100000"), "{err}");
        }
        // The windows come from the header alone, and agree with the decoded image's.
        let tile = encode_exr(&RgbBuffer::new(8, 8, 2, 3, 4, 5)).unwrap();
        assert_eq!(
            read_exr_windows(&tile).unwrap(),
            decode_exr(&tile).unwrap().windows()
        );
        // The limit is the caller's to choose.
        let tile = encode_exr(&RgbBuffer::new(8, 8, 0, 0, 4, 4)).unwrap();
        assert!(decode_exr_limited(&tile, 16).is_ok());
        assert!(decode_exr_limited(&tile, 15).is_err());
    }

    /// A header within the pixel limits whose many channels would still take tens of
    /// gigabytes (a tile of 35 channels whose window a flipped bit made 16384 x 16384: an
    /// allocation failure that aborted, found by the farm's damaged-upload test) is refused
    /// by its bytes.
    #[test]
    fn an_exr_whose_channels_would_take_too_many_bytes_is_refused() {
        let names: Vec<String> = (0..32).map(|i| format!("aov.{i:02}")).collect();
        let bytes = encode_exr(&RgbBuffer::new(1, 1, 0, 0, 1, 1).with_aovs(names)).unwrap();
        let mut evil = bytes.clone();
        for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
            let at = evil.windows(name.len()).position(|w| w == name).unwrap() + name.len() + 4;
            evil[at + 8..at + 12].copy_from_slice(&16_383i32.to_le_bytes());
            evil[at + 12..at + 16].copy_from_slice(&16_383i32.to_le_bytes());
        }
        let err = decode_exr(&evil).unwrap_err().to_string();
        assert!(err.contains("bytes"), "{err}");
        assert!(decode_exr(&bytes).is_ok());
    }

    #[test]
    fn corrupt_exr_is_an_error_not_a_panic() {
        let b = RgbBuffer::new(4, 4, 0, 0, 4, 4);
        let bytes = encode_exr(&b).unwrap();
        assert!(decode_exr(&bytes[..bytes.len() / 2]).is_err());
        assert!(decode_exr(b"not an exr").is_err());
    }

    /// A buffer whose every pixel holds `v`.
    fn filled(fw: u32, fh: u32, x0: u32, y0: u32, w: u32, h: u32, v: f32) -> RgbBuffer {
        let mut b = RgbBuffer::new(fw, fh, x0, y0, w, h);
        b.pixels.iter_mut().for_each(|p| *p = [v; 3]);
        b
    }

    #[test]
    fn paste_places_tiles_by_their_data_windows() {
        // The frame's data window is 6x4 at (2, 1) in a 10x8 frame (a crop window).
        let mut frame = RgbBuffer::new(10, 8, 2, 1, 6, 4);
        let mut tile = RgbBuffer::new(10, 8, 5, 2, 3, 2);
        for (i, p) in tile.pixels.iter_mut().enumerate() {
            *p = [i as f32 + 1.0, 0.0, 0.0];
        }
        frame.paste(&tile).unwrap();
        for y in 0..4 {
            for x in 0..6 {
                let (fx, fy) = (x + 2, y + 1);
                let want = if (5..8).contains(&fx) && (2..4).contains(&fy) {
                    ((fy - 2) * 3 + (fx - 5)) as f32 + 1.0
                } else {
                    0.0
                };
                assert_eq!(frame.get(x, y)[0], want, "pixel {fx},{fy}");
            }
        }
        // A tile covering the whole data window replaces it.
        frame.paste(&filled(10, 8, 2, 1, 6, 4, 2.0)).unwrap();
        assert!(frame.pixels.iter().all(|p| *p == [2.0; 3]));
    }

    #[test]
    fn paste_refuses_tiles_that_do_not_fit() {
        let mut frame = filled(10, 8, 2, 1, 6, 4, 7.0);
        let before = frame.clone();
        for (tile, why) in [
            (filled(10, 8, 6, 1, 3, 2, 1.0), "overlaps the right edge"),
            (filled(10, 8, 2, 4, 2, 2, 1.0), "overlaps the bottom edge"),
            (
                filled(10, 8, 1, 1, 2, 2, 1.0),
                "starts left of the data window",
            ),
            (
                filled(10, 8, 2, 0, 2, 2, 1.0),
                "starts above the data window",
            ),
            (filled(10, 8, 20, 20, 2, 2, 1.0), "lies outside the frame"),
            (filled(12, 8, 2, 1, 2, 2, 1.0), "belongs to another frame"),
            (
                filled(10, 8, u32::MAX, 1, 2, 2, 1.0),
                "would overflow the coordinates",
            ),
        ] {
            let e = frame.paste(&tile);
            assert!(
                matches!(e, Err(ImageError::Invalid(_))),
                "a tile that {why}"
            );
            assert_eq!(frame, before, "a tile that {why} changed the frame");
        }
        let mut short = filled(10, 8, 2, 1, 2, 2, 1.0);
        short.pixels.pop();
        assert!(frame.paste(&short).is_err());
        assert_eq!(frame, before);
    }

    #[test]
    fn png_encodes_srgb() {
        assert_eq!(srgb_encode(0.0), 0);
        assert_eq!(srgb_encode(1.0), 255);
        assert_eq!(srgb_encode(0.5), 188);
        let b = RgbBuffer::new(2, 2, 0, 0, 2, 2);
        let png = encode_png(&b, 0.0).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
}
