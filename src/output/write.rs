//! Writing images atomically: encode into a temporary file beside the target, then rename
//! it over the target, so a reader never sees half a file and a failure leaves no debris.

use super::image::{LinearImage, Transfer};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {}: {message}", path.display())]
    Write { path: PathBuf, message: String },
}

fn err(path: &Path, e: impl std::fmt::Display) -> OutputError {
    OutputError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn dir_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The image files termtrace writes, told apart by the name's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFile {
    /// `.png`, or a name without an extension.
    Png,
    /// `.exr`: the linear radiance as 32-bit float OpenEXR.
    Exr,
}

impl ImageFile {
    /// The kind a name asks for (case-insensitive), or an error naming the file for an
    /// extension termtrace does not write, rather than PNG bytes under a `.jpg` name.
    pub fn of(path: &Path) -> Result<Self, OutputError> {
        let Some(ext) = path.extension() else {
            return Ok(Self::Png);
        };
        match ext.to_string_lossy().to_ascii_lowercase().as_str() {
            "png" => Ok(Self::Png),
            "exr" => Ok(Self::Exr),
            other => Err(err(
                path,
                format!(
                    "termtrace writes PNG (.png) and linear OpenEXR (.exr), not `.{other}`; \
                     convert the PNG with another tool"
                ),
            )),
        }
    }
}

/// Fails now, before any rendering, if `path` could not be written later.
pub fn check_writable(path: &Path) -> Result<(), OutputError> {
    if path.is_dir() {
        return Err(err(path, "it is a directory"));
    }
    let dir = dir_of(path);
    if !dir.is_dir() {
        return Err(err(
            path,
            format!("directory {} does not exist", dir.display()),
        ));
    }
    tempfile::Builder::new()
        .prefix(".termtrace-check-")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| err(path, e))
}

/// Runs `encode` into a temporary file beside `path`, then renames it to `path`.
fn atomic_write(
    path: &Path,
    encode: impl FnOnce(&mut BufWriter<&mut std::fs::File>) -> Result<(), ::image::ImageError>,
) -> Result<(), OutputError> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".termtrace-").suffix(".part");
    // An ordinary file's mode (0666 less the umask), not the temporary file's private 0600.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let mut tmp = builder
        .tempfile_in(dir_of(path))
        .map_err(|e| err(path, e))?;
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        encode(&mut w).map_err(|e| err(path, e))?;
        w.flush().map_err(|e| err(path, e))?;
    }
    tmp.as_file().sync_all().map_err(|e| err(path, e))?;
    tmp.persist(path).map_err(|e| err(path, e.error))?;
    Ok(())
}

/// Writes a text file (an edited scene).
pub fn write_text(path: &Path, text: &str) -> Result<(), OutputError> {
    write_bytes(path, text.as_bytes())
}

/// Writes a file of bytes (a built-in scene's map beside its edited scene).
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    atomic_write(path, |w| {
        w.write_all(bytes).map_err(::image::ImageError::IoError)
    })
}

/// Writes an 8-bit (or 16-bit) PNG encoded with `transfer`.
pub fn write_png(
    path: &Path,
    img: &LinearImage,
    transfer: Transfer,
    sixteen_bit: bool,
) -> Result<(), OutputError> {
    atomic_write(path, |w| {
        if sixteen_bit {
            img.to_rgb16(transfer)
                .write_to(w, ::image::ImageFormat::Png)
        } else {
            img.to_rgb8(transfer).write_to(w, ::image::ImageFormat::Png)
        }
    })
}

/// Writes 8-bit sRGB pixels already encoded (`width × height × 3` bytes: a plot) as a PNG.
pub fn write_rgb8_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb: Vec<u8>,
) -> Result<(), OutputError> {
    let img = ::image::RgbImage::from_raw(width, height, rgb)
        .ok_or_else(|| err(path, "the pixel buffer does not match the image size"))?;
    atomic_write(path, |w| img.write_to(w, ::image::ImageFormat::Png))
}

/// Writes the linear radiance as 32-bit float OpenEXR.
pub fn write_exr(path: &Path, img: &LinearImage) -> Result<(), OutputError> {
    atomic_write(path, |w| {
        img.to_rgb32f().write_to(w, ::image::ImageFormat::OpenExr)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_extension_decides_the_format_and_an_unknown_one_is_refused() {
        for (name, want) in [
            ("a.png", ImageFile::Png),
            ("dir.v2/a.PNG", ImageFile::Png),
            ("a", ImageFile::Png),
            ("a.exr", ImageFile::Exr),
            ("a.EXR", ImageFile::Exr),
        ] {
            assert_eq!(ImageFile::of(Path::new(name)).unwrap(), want, "{name}");
        }
        for name in ["a.jpg", "a.jpeg", "out.bmp", "a.png.tmp"] {
            let e = ImageFile::of(Path::new(name)).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(".png"), "{name}: {e}");
        }
    }
}
