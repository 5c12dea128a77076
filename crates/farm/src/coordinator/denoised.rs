//! Denoised previews: a frame so far (or finished) denoised with its feature buffers by
//! Kiln's built-in denoiser, for `preview.png?denoise=1`, the dashboard's toggle and
//! `result.exr?denoise=1`.
//!
//! A frame is denoised when a client first asks after a merge moved it on (one larger than
//! `Config::max_denoised_pixels` is refused), one frame at a time (a 2880x1920 frame takes seconds of the coordinator's CPU, so hostile or eager
//! clients queue rather than pile up), and the last few are kept: every client asking for
//! the same merged frame gets the same picture without denoising it again. The built-in
//! denoiser is deterministic, so the picture is the same bytes whoever asks, whichever
//! coordinator leads.

use super::{Coordinator, Error};
use kiln_image::RgbBuffer;
use std::sync::{Arc, Weak};

/// How many denoised frames are kept.
const KEPT: usize = 4;

/// The frames denoised last, newest last.
#[derive(Default)]
pub(super) struct Denoised {
    kept: Vec<Kept>,
}

/// A frame denoised: its job and index, what it was made from, and the denoised frame
/// (its beauty denoised, the raw beauty as raw.R, raw.G, raw.B).
struct Kept {
    id: u64,
    frame: u32,
    from: Made,
    denoised: Arc<RgbBuffer>,
}

/// What a kept frame was made from: the frame so far (while anything holds it), or the
/// result file after so many passes.
enum Made {
    Rendering(Weak<RgbBuffer>),
    Finished(u32),
}

/// The merged frame to denoise: the frame so far while it renders, or its result file
/// holding `written` passes.
pub(super) enum Source {
    Rendering(Arc<RgbBuffer>),
    Finished {
        written: u32,
        picture: Arc<RgbBuffer>,
    },
}

impl Coordinator {
    /// Frame `frame` of job `id` denoised from `source`: kept from an earlier request for
    /// the same merged frame, or made now.
    pub(super) async fn denoised(
        &self,
        (id, frame): (u64, u32),
        source: Source,
    ) -> Result<Arc<RgbBuffer>, Error> {
        let (Source::Rendering(picture) | Source::Finished { picture, .. }) = &source;
        let (pixels, limit) = (
            picture.pixels.len() as u64,
            self.config().max_denoised_pixels,
        );
        if pixels > limit {
            return Err(Error::DenoiseTooLarge { pixels, limit });
        }
        // One frame at a time: the lock is held while it is denoised.
        let mut cache = self.shared.denoised.lock().await;
        // A frame that moved on since leaves its old picture behind.
        cache.kept.retain(|k| match &k.from {
            Made::Rendering(w) => w.strong_count() > 0,
            Made::Finished(_) => true,
        });
        let same = |k: &Kept| {
            k.id == id
                && k.frame == frame
                && match (&k.from, &source) {
                    (Made::Rendering(w), Source::Rendering(s)) => {
                        w.upgrade().is_some_and(|w| Arc::ptr_eq(&w, s))
                    }
                    (Made::Finished(a), Source::Finished { written, .. }) => a == written,
                    _ => false,
                }
        };
        if let Some(k) = cache.kept.iter().find(|k| same(k)) {
            return Ok(k.denoised.clone());
        }
        let (picture, kept_from) = match source {
            Source::Rendering(p) => {
                let weak = Arc::downgrade(&p);
                (p, Made::Rendering(weak))
            }
            Source::Finished { written, picture } => (picture, Made::Finished(written)),
        };
        let from = picture.clone();
        let denoised = tokio::task::spawn_blocking(move || {
            let started = std::time::Instant::now();
            let pixels =
                kiln_denoise::denoise(&from, kiln_denoise::Denoiser::built_in(), &|_, _| {})?;
            tracing::info!(
                "denoised a {}x{} frame in {:.2} s",
                from.width,
                from.height,
                started.elapsed().as_secs_f64()
            );
            Ok::<_, kiln_denoise::Error>(kiln_denoise::with_denoised(&from, pixels))
        })
        .await?
        .map_err(Error::Denoise)?;
        let denoised = Arc::new(denoised);
        if cache.kept.len() >= KEPT {
            cache.kept.remove(0);
        }
        cache.kept.push(Kept {
            id,
            frame,
            from: kept_from,
            denoised: denoised.clone(),
        });
        Ok(denoised)
    }
}
