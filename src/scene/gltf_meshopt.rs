//! `EXT_meshopt_compression` (and its Khronos twin `KHR_meshopt_compression`), as gltfpack
//! and glTF-Transform write it: a buffer view's bytes come compressed from another buffer and
//! are decoded, before anything reads them, into the view's own (fallback) buffer, by
//! meshoptimizer's decoders (the `meshopt` crate; the bitstreams and filters are the
//! extension's, https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Vendor/EXT_meshopt_compression).

use super::error::Malformed;
use std::os::raw::c_void;

/// The extension's names: the vendor one gltfpack writes, and the Khronos one.
pub const NAMES: [&str; 2] = ["EXT_meshopt_compression", "KHR_meshopt_compression"];

/// Whether buffer `b` is a fallback that the compressed views decode into (it has no data of
/// its own: the loader gives it zeros of its length).
pub fn is_fallback(b: &gltf::Buffer) -> bool {
    NAMES.iter().any(|n| {
        b.extension_value(n)
            .and_then(|e| e.get("fallback"))
            .and_then(|f| f.as_bool())
            .unwrap_or(false)
    })
}

/// One compressed view, as its extension object gives it.
struct Compressed {
    buffer: usize,
    offset: usize,
    length: usize,
    stride: usize,
    count: usize,
    mode: String,
    filter: String,
}

fn read(view: &gltf::buffer::View, ext: &gltf::json::Value) -> Result<Compressed, Malformed> {
    let int = |k: &str, default: Option<u64>| {
        ext.get(k)
            .and_then(|v| v.as_u64())
            .or(default)
            .map(|v| v as usize)
            .ok_or_else(|| Malformed(format!("no `{k}`")))
    };
    let text = |k: &str, default: &str| {
        ext.get(k)
            .map_or(Some(default), |v| v.as_str())
            .map(str::to_string)
            .ok_or_else(|| Malformed(format!("`{k}` is not a string")))
    };
    let c = Compressed {
        buffer: int("buffer", None)?,
        offset: int("byteOffset", Some(0))?,
        length: int("byteLength", None)?,
        stride: int("byteStride", None)?,
        count: int("count", None)?,
        mode: text("mode", "")?,
        filter: text("filter", "NONE")?,
    };
    if c.count.checked_mul(c.stride) != Some(view.length()) {
        return Err(Malformed(format!(
            "{} elements of {} bytes, but the view has {} bytes",
            c.count,
            c.stride,
            view.length()
        )));
    }
    Ok(c)
}

/// Decodes every compressed view of `doc` into its buffer in `buffers`.
pub fn decode(doc: &gltf::Document, buffers: &mut [gltf::buffer::Data]) -> Result<(), Malformed> {
    let start = std::time::Instant::now();
    let (mut views, mut bytes) = (0, 0);
    for view in doc.views() {
        let Some(ext) = NAMES.iter().find_map(|n| view.extension_value(n)) else {
            continue;
        };
        let what = format!("bufferViews[{}] (meshopt)", view.index());
        let c = read(&view, ext).map_err(|e| Malformed(format!("{what}: {}", e.0)))?;
        let src = buffers
            .get(c.buffer)
            .and_then(|b| b.get(c.offset..c.offset.checked_add(c.length)?))
            .ok_or_else(|| {
                Malformed(format!(
                    "{what}: bytes {}..+{} are not in buffers[{}]",
                    c.offset, c.length, c.buffer
                ))
            })?
            .to_vec();
        let mut out = vec![0u8; view.length()];
        decode_view(&c, &src, &mut out).map_err(|e| Malformed(format!("{what}: {}", e.0)))?;
        let dst = buffers
            .get_mut(view.buffer().index())
            .and_then(|b| {
                b.0.get_mut(view.offset()..view.offset().checked_add(view.length())?)
            })
            .ok_or_else(|| Malformed(format!("{what}: the view lies outside its buffer")))?;
        dst.copy_from_slice(&out);
        views += 1;
        bytes += out.len();
    }
    if views > 0 {
        tracing::info!(
            "meshopt: {views} buffer views ({:.1} MiB) decoded in {:.1} ms",
            bytes as f64 / (1 << 20) as f64,
            start.elapsed().as_secs_f64() * 1e3
        );
    }
    Ok(())
}

/// One view's stream decoded into `out` (`count × stride` bytes), its filter applied.
fn decode_view(c: &Compressed, src: &[u8], out: &mut [u8]) -> Result<(), Malformed> {
    use meshopt::ffi;
    let dst = out.as_mut_ptr() as *mut c_void;
    // SAFETY (every call below): `out` holds count × stride bytes, checked by `read`, and
    // each decoder writes at most that; the decoders check `src` themselves (meshoptimizer
    // documents them as safe on untrusted input).
    let rc = match c.mode.as_str() {
        "ATTRIBUTES" if c.stride.is_multiple_of(4) && c.stride <= 256 => unsafe {
            ffi::meshopt_decodeVertexBuffer(dst, c.count, c.stride, src.as_ptr(), src.len())
        },
        "TRIANGLES" if (c.stride == 2 || c.stride == 4) && c.count.is_multiple_of(3) => unsafe {
            ffi::meshopt_decodeIndexBuffer(dst, c.count, c.stride, src.as_ptr(), src.len())
        },
        "INDICES" if c.stride == 2 || c.stride == 4 => unsafe {
            ffi::meshopt_decodeIndexSequence(dst, c.count, c.stride, src.as_ptr(), src.len())
        },
        m => {
            return Err(Malformed(format!(
                "mode `{m}` with a stride of {} and {} elements is not one the extension allows",
                c.stride, c.count
            )));
        }
    };
    if rc != 0 {
        return Err(Malformed(format!(
            "its {} stream does not decode (code {rc})",
            c.mode
        )));
    }
    match (c.filter.as_str(), c.mode.as_str()) {
        ("NONE", _) => {}
        ("OCTAHEDRAL", "ATTRIBUTES") if c.stride == 4 || c.stride == 8 => unsafe {
            ffi::meshopt_decodeFilterOct(dst, c.count, c.stride)
        },
        ("QUATERNION", "ATTRIBUTES") if c.stride == 8 => unsafe {
            ffi::meshopt_decodeFilterQuat(dst, c.count, c.stride)
        },
        ("EXPONENTIAL", "ATTRIBUTES") => unsafe {
            ffi::meshopt_decodeFilterExp(dst, c.count, c.stride)
        },
        (f, _) => {
            return Err(Malformed(format!(
                "filter `{f}` on a {} stream of stride {} is not one the extension allows",
                c.mode, c.stride
            )));
        }
    }
    Ok(())
}
