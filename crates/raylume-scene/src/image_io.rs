//! Textures and environment maps through the `image` crate.
//!
//! - Textures (png, jpg; hdr and exr are accepted too) become linear RGB: 8- and 16-bit
//!   images are sRGB-decoded, float images are taken as linear. Alpha is dropped.
//! - Environment maps must be `.hdr` or `.exr` (equirectangular, linear float RGB).
//!
//! Sizes are bounded by [`MAX_TEXTURE_SIZE`](crate::limits::MAX_TEXTURE_SIZE) per side,
//! enforced by the decoder before it allocates.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageFormat, ImageReader, Limits};

use crate::error::SceneError;
use crate::limits::MAX_TEXTURE_SIZE;
use crate::model::{Texels, Texture};

/// The exact sRGB transfer function, decoded.
pub(crate) fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn read(path: &Path, referenced_by: &str) -> Result<Vec<u8>, SceneError> {
    std::fs::read(path)
        .map_err(|e| SceneError::io(path.to_path_buf(), Some(referenced_by.to_string()), e))
}

fn decode(bytes: &[u8], path: &Path, referenced_by: &str) -> Result<DynamicImage, SceneError> {
    let image_err = |message: String| SceneError::Image {
        path: path.to_path_buf(),
        referenced_by: Some(referenced_by.to_string()),
        message,
    };
    let open = || -> Result<ImageReader<Cursor<&[u8]>>, SceneError> {
        let mut reader = ImageReader::new(Cursor::new(bytes));
        if let Ok(format) = ImageFormat::from_path(path) {
            reader.set_format(format);
        }
        let reader = reader
            .with_guessed_format()
            .map_err(|e| image_err(e.to_string()))?;
        if reader.format().is_none() {
            return Err(image_err("unknown image format".into()));
        }
        Ok(reader)
    };
    // The header first: a size past the limit is refused before any pixel is decoded.
    let (w, h) = open()?
        .into_dimensions()
        .map_err(|e| image_err(e.to_string()))?;
    if w.max(h) > MAX_TEXTURE_SIZE {
        return Err(SceneError::TooLarge {
            file: path.display().to_string(),
            at: crate::error::Location::None,
            what: format!("the larger side of this {w}x{h} image (referenced by {referenced_by})"),
            count: u64::from(w.max(h)),
            limit: u64::from(MAX_TEXTURE_SIZE),
        });
    }
    let mut reader = open()?;
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIZE);
    limits.max_image_height = Some(MAX_TEXTURE_SIZE);
    // Room for the largest allowed image decoded as RGBA f32, plus decoder scratch.
    limits.max_alloc = Some(u64::from(MAX_TEXTURE_SIZE).pow(2) * 16 + (64 << 20));
    reader.limits(limits);
    reader.decode().map_err(|e| match e {
        image::ImageError::Limits(l) => SceneError::TooLarge {
            file: path.display().to_string(),
            at: crate::error::Location::None,
            what: format!(
                "the texels of this {w}x{h} image, within the decoder's memory limit ({l}; referenced by {referenced_by})"
            ),
            count: u64::from(w) * u64::from(h),
            limit: u64::from(MAX_TEXTURE_SIZE).pow(2),
        },
        other => image_err(other.to_string()),
    })
}

fn is_float(img: &DynamicImage) -> bool {
    matches!(
        img,
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
    )
}

/// Converts a decoded image to a texture: 8-bit images keep their sRGB codes
/// ([`Texels::Srgb8`]), float images are linear, 16-bit ones are sRGB-decoded to floats.
fn to_texture(img: DynamicImage, name: &str) -> Texture {
    let (width, height) = (img.width(), img.height());
    let texels = if is_float(&img) {
        Texels::Linear(img.into_rgb32f().pixels().map(|p| p.0).collect())
    } else if matches!(
        img,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_)
    ) {
        let rgb = img.into_rgb8();
        Texels::Srgb8(rgb.pixels().map(|p| p.0).collect())
    } else {
        Texels::Linear(
            img.into_rgb32f()
                .pixels()
                .map(|p| p.0.map(srgb_to_linear))
                .collect(),
        )
    };
    Texture {
        name: name.to_string(),
        width,
        height,
        texels,
    }
}

/// Loads an albedo texture from a file.
pub(crate) fn load_texture(path: &Path, referenced_by: &str) -> Result<Texture, SceneError> {
    let bytes = read(path, referenced_by)?;
    decode_texture(&bytes, path, referenced_by)
}

/// Decodes an albedo texture from bytes (glTF buffer views and data URIs); `path` names it in
/// messages and its extension, if any, hints the format.
pub(crate) fn decode_texture(
    bytes: &[u8],
    path: &Path,
    referenced_by: &str,
) -> Result<Texture, SceneError> {
    let img = decode(bytes, path, referenced_by)?;
    Ok(to_texture(img, &path.display().to_string()))
}

/// Loads an equirectangular environment map (`.hdr` or `.exr`). NaN or infinite texels are an
/// error; negative ones (some HDR processing leaves tiny negatives) are clamped to zero and
/// counted in the second value.
pub(crate) fn load_environment(
    path: &Path,
    referenced_by: &str,
) -> Result<(Texture, usize), SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("hdr" | "exr")) {
        return Err(SceneError::UnsupportedExtension {
            path: path.to_path_buf(),
            referenced_by: Some(referenced_by.to_string()),
            expected: ".hdr or .exr (equirectangular)",
        });
    }
    let bytes = read(path, referenced_by)?;
    decode_environment(&bytes, path, referenced_by)
}

/// Decodes an environment map from bytes (see [`load_environment`]).
pub(crate) fn decode_environment(
    bytes: &[u8],
    path: &Path,
    referenced_by: &str,
) -> Result<(Texture, usize), SceneError> {
    let img = decode(bytes, path, referenced_by)?;
    let mut tex = to_texture(img, &path.display().to_string());
    // Radiance is linear: an 8-bit map (a `.hdr` name over other bytes) is decoded now.
    let mut texels = tex.texels.to_linear();
    let mut negatives = 0;
    for (i, t) in texels.iter_mut().enumerate() {
        if !t.iter().all(|c| c.is_finite()) {
            return Err(SceneError::NotFinite {
                file: path.display().to_string(),
                at: crate::error::Location::path(format!(
                    "texel ({}, {})",
                    i % tex.width as usize,
                    i / tex.width as usize
                )),
                what: "environment map radiance".into(),
            });
        }
        if t.iter().any(|c| *c < 0.0) {
            negatives += 1;
            *t = t.map(|c| c.max(0.0));
        }
    }
    tex.texels = Texels::Linear(texels);
    Ok((tex, negatives))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_matches_known_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 0.5 is 0.21404 linear (IEC 61966-2-1).
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        // Linear segment below the knee.
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }

    #[test]
    fn png_is_srgb_decoded_and_row_major_top_first() {
        let mut img = image::RgbImage::new(2, 2);
        img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
        img.put_pixel(1, 0, image::Rgb([128, 128, 128]));
        img.put_pixel(0, 1, image::Rgb([0, 0, 255]));
        let mut bytes = Vec::new();
        DynamicImage::ImageRgb8(img)
            .write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
            .unwrap();
        let t = decode_texture(&bytes, Path::new("t.png"), "test").unwrap();
        assert_eq!((t.width, t.height), (2, 2));
        // Kept as the file's codes, decoded on lookup as the table says.
        assert_eq!(
            t.texels,
            Texels::Srgb8(vec![[255, 0, 0], [128, 128, 128], [0, 0, 255], [0, 0, 0]])
        );
        assert_eq!(t.texels.linear(0), [1.0, 0.0, 0.0]);
        let g = srgb_to_linear(128.0 / 255.0);
        assert_eq!(t.texels.linear(1), [g, g, g]);
        assert_eq!(t.texels.linear(2), [0.0, 0.0, 1.0]);
        assert_eq!(t.texels.linear(3), [0.0, 0.0, 0.0]);
    }

    #[test]
    fn garbage_is_an_image_error_naming_the_file() {
        let e = decode_texture(b"not an image", Path::new("x.png"), "scene.toml:3:1").unwrap_err();
        assert!(matches!(e, SceneError::Image { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("x.png") && msg.contains("scene.toml:3:1"),
            "{msg}"
        );
    }

    #[test]
    fn environment_needs_hdr_or_exr() {
        let e = load_environment(Path::new("sky.png"), "s.toml").unwrap_err();
        assert!(matches!(e, SceneError::UnsupportedExtension { .. }), "{e}");
    }
}
