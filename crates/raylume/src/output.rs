//! Writing renders to disk: `.png` (tone-mapped, sRGB, 8-bit) and `.exr` (linear radiance,
//! after bloom, before tone mapping). Files are written to a temporary name beside the target
//! and renamed into place, so an error never leaves a partial output file behind.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::Error;

/// Output formats, chosen from the file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB after exposure and tone curve.
    Png,
    /// 32-bit float linear radiance (OpenEXR).
    Exr,
}

impl ImageFormat {
    /// The format for `path`'s extension (case-insensitive), or a clear error.
    pub fn from_path(path: &Path) -> Result<Self, Error> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            _ => Err(Error::Output {
                path: path.to_path_buf(),
                reason: "unsupported output format: use a .png or .exr file name".into(),
            }),
        }
    }
}

fn output_err(path: &Path, reason: impl std::fmt::Display) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

fn check_dims(path: &Path, pixels: &[[f32; 3]], width: u32, height: u32) -> Result<(), Error> {
    if width == 0 || height == 0 || pixels.len() != width as usize * height as usize {
        return Err(output_err(
            path,
            format!(
                "image of {}x{} does not match its {} pixels",
                width,
                height,
                pixels.len()
            ),
        ));
    }
    Ok(())
}

/// Writes `encode`'s bytes to a temporary file beside `path`, then renames it into place.
fn write_atomically(
    path: &Path,
    encode: impl FnOnce(&mut BufWriter<std::fs::File>) -> Result<(), String>,
) -> Result<(), Error> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(output_err(
            path,
            format!("the folder {} does not exist", dir.display()),
        ));
    }
    let name = path
        .file_name()
        .ok_or_else(|| output_err(path, "not a file name"))?
        .to_string_lossy();
    let tmp = dir.join(format!(".{name}.raylume-tmp-{}", std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&tmp).map_err(|e| e.to_string())?;
        let mut w = BufWriter::new(file);
        encode(&mut w)?;
        w.flush().map_err(|e| e.to_string())?;
        w.get_ref().sync_all().map_err(|e| e.to_string())?;
        drop(w);
        std::fs::rename(&tmp, path).map_err(|e| e.to_string())
    })();
    if let Err(reason) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(output_err(path, reason));
    }
    Ok(())
}

/// Saves linear radiance as 8-bit sRGB PNG after `tone` (exposure, curve, sRGB encoding).
pub fn save_png(
    path: impl AsRef<Path>,
    pixels: &[[f32; 3]],
    width: u32,
    height: u32,
    tone: &raylume_post::ToneMap,
) -> Result<(), Error> {
    let path = path.as_ref();
    check_dims(path, pixels, width, height)?;
    let bytes: Vec<u8> = tone
        .to_srgb8(pixels)
        .map_err(|e| output_err(path, e))?
        .into_flattened();
    let img = image::RgbImage::from_raw(width, height, bytes)
        .ok_or_else(|| output_err(path, "pixel buffer size mismatch"))?;
    write_atomically(path, |w| {
        img.write_to(w, image::ImageFormat::Png)
            .map_err(|e| e.to_string())
    })
}

/// Saves linear radiance as 32-bit float OpenEXR (no tone mapping).
pub fn save_exr(
    path: impl AsRef<Path>,
    pixels: &[[f32; 3]],
    width: u32,
    height: u32,
) -> Result<(), Error> {
    let path = path.as_ref();
    check_dims(path, pixels, width, height)?;
    let flat: Vec<f32> = pixels.iter().flatten().copied().collect();
    let img = image::Rgb32FImage::from_raw(width, height, flat)
        .ok_or_else(|| output_err(path, "pixel buffer size mismatch"))?;
    write_atomically(path, |w| {
        image::DynamicImage::ImageRgb32F(img)
            .write_to(w, image::ImageFormat::OpenExr)
            .map_err(|e| e.to_string())
    })
}
