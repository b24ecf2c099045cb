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

/// Saves linear radiance as 32-bit float OpenEXR (no tone mapping): run-length compressed
/// 64x64 tiles (exr's fast lossless encoding, which `image` writes too), written in increasing
/// order, so that the same pixels make the same bytes (the tiles compress on several threads;
/// in the order they finished the file differed from run to run).
pub fn save_exr(
    path: impl AsRef<Path>,
    pixels: &[[f32; 3]],
    width: u32,
    height: u32,
) -> Result<(), Error> {
    use exr::prelude::{Encoding, Image, LineOrder, SpecificChannels, Vec2, WritableImage};
    let path = path.as_ref();
    check_dims(path, pixels, width, height)?;
    let w = width as usize;
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let image = Image::from_encoded_channels(
        (w, height as usize),
        encoding,
        SpecificChannels::rgb(|p: Vec2<usize>| {
            let [r, g, b] = pixels[p.y() * w + p.x()];
            (r, g, b)
        }),
    );
    write_atomically(path, |out| {
        image.write().to_buffered(out).map_err(|e| e.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same radiance saves as the same bytes every time: the EXR's tiles are compressed on
    /// several threads, and a file whose tiles were written in the order they finished (exr's
    /// `LineOrder::Unspecified`, the `image` crate's default) differed from run to run while
    /// its pixels did not, so a render could not be checked by its file's hash.
    #[test]
    fn exr_files_of_the_same_image_are_the_same_bytes() {
        // Enough 64x64 tiles (10 x 8) for the compressing threads to finish out of order, with
        // values that do not all run-length-compress alike.
        let (w, h) = (640u32, 480u32);
        let mut s = 0x2545_f491u32;
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                let noise = (s >> 8) as f32 / (1u32 << 24) as f32;
                let flat = if (i / 4096) % 3 == 0 { 0.0 } else { noise };
                [flat, 0.5 * flat, (i % w) as f32 / w as f32]
            })
            .collect();
        let dir = std::env::temp_dir().join(format!("raylume-exr-bytes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files: Vec<Vec<u8>> = (0..12)
            .map(|k| {
                let p = dir.join(format!("{k}.exr"));
                save_exr(&p, &pixels, w, h).unwrap();
                std::fs::read(&p).unwrap()
            })
            .collect();
        let back = image::open(dir.join("0.exr")).unwrap().into_rgb32f();
        std::fs::remove_dir_all(&dir).unwrap();
        let same = files.iter().filter(|f| **f == files[0]).count();
        assert_eq!(
            same,
            files.len(),
            "{same} of {} files equal the first",
            files.len()
        );
        let read: Vec<[f32; 3]> = back.pixels().map(|p| p.0).collect();
        assert!(read == pixels, "the pixels read back differ");
    }
}
