use raylume_gpu::GpuError;
use thiserror::Error;

/// Everything that can go wrong in post-processing: bad parameters, images whose sizes do not
/// add up, and GPU failures.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PostError {
    /// A GPU failure (no adapter, validation, out of memory, device lost, ...).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// A parameter outside its documented range.
    #[error("{what} = {value} is not allowed: {requirement}")]
    BadParam {
        /// The parameter, e.g. `bloom threshold`.
        what: &'static str,
        /// The value given, as text (it may be NaN).
        value: String,
        /// What the value must satisfy, e.g. `finite and >= 0`.
        requirement: &'static str,
    },
    /// An image with no pixels.
    #[error("{what} is {width}x{height}: both sizes must be at least 1")]
    ZeroSize {
        /// Which image.
        what: &'static str,
        width: u32,
        height: u32,
    },
    /// A pixel slice or buffer whose length does not match `width * height`.
    #[error(
        "{what} holds {got} pixels but a {width}x{height} image needs {expected} \
         (packed RGB f32 triples, 12 bytes per pixel)"
    )]
    SizeMismatch {
        /// Which slice or buffer.
        what: &'static str,
        got: u64,
        expected: u64,
        width: u32,
        height: u32,
    },
    /// Two images compared by a metric have different pixel counts.
    #[error("cannot compare images of {a} and {b} pixels: sizes differ")]
    LengthMismatch { a: usize, b: usize },
    /// An image too small for a windowed metric.
    #[error("{what} needs images of at least {min}x{min} pixels, got {width}x{height}")]
    TooSmall {
        /// The metric, e.g. `SSIM (11x11 Gaussian window)`.
        what: &'static str,
        min: u32,
        width: u32,
        height: u32,
    },
    /// A GPU buffer that cannot serve as the image (too small, or not a storage buffer).
    #[error("{what}: {detail}")]
    BadBuffer {
        /// Which buffer.
        what: &'static str,
        detail: String,
    },
}

/// Checks that `width x height` is non-empty and that `len` pixels match it.
pub(crate) fn check_image(
    what: &'static str,
    len: usize,
    width: u32,
    height: u32,
) -> Result<(), PostError> {
    if width == 0 || height == 0 {
        return Err(PostError::ZeroSize {
            what,
            width,
            height,
        });
    }
    let expected = u64::from(width) * u64::from(height);
    if len as u64 != expected {
        return Err(PostError::SizeMismatch {
            what,
            got: len as u64,
            expected,
            width,
            height,
        });
    }
    Ok(())
}
