//! A glTF accessor's elements as f32, dequantized: floats as they are, and the integer kinds
//! `KHR_mesh_quantization` allows, normalized (the specification's §3.11 rules: i8 c/127, u8
//! c/255, i16 c/32767, u16 c/65535, the signed ones at least −1) or not (their value); a
//! sparse accessor's substitutions applied over its base (zeros without a buffer view).

use super::error::Malformed;
use gltf::accessor::DataType;

/// Bytes of one component of `t`.
fn size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// The component of type `t` at the start of `b`, as f32.
fn component(t: DataType, normalized: bool, b: &[u8]) -> f32 {
    match (t, normalized) {
        (DataType::F32, _) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        (DataType::I8, true) => (b[0] as i8 as f32 / 127.0).max(-1.0),
        (DataType::I8, false) => b[0] as i8 as f32,
        (DataType::U8, true) => b[0] as f32 / 255.0,
        (DataType::U8, false) => b[0] as f32,
        (DataType::I16, n) => {
            let v = i16::from_le_bytes([b[0], b[1]]) as f32;
            if n { (v / 32767.0).max(-1.0) } else { v }
        }
        (DataType::U16, n) => {
            let v = u16::from_le_bytes([b[0], b[1]]) as f32;
            if n { v / 65535.0 } else { v }
        }
        (DataType::U32, n) => {
            let v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32;
            if n { v / u32::MAX as f32 } else { v }
        }
    }
}

/// The `N` components of each of `a`'s elements, as f32. The caller has checked that the
/// accessor lies inside its buffer ([`fits`]) and has `N` components; a missing
/// buffer or view reads as no elements.
pub fn read<const N: usize>(a: &gltf::Accessor, buffers: &[gltf::buffer::Data]) -> Vec<[f32; N]> {
    let t = a.data_type();
    let elem = a.size();
    let normalized = a.normalized();
    let element = |data: &[u8], at: usize| -> [f32; N] {
        std::array::from_fn(|c| component(t, normalized, &data[at + c * size(t)..]))
    };
    let mut out = match a.view() {
        Some(view) => {
            let Some(data) = buffers.get(view.buffer().index()) else {
                return Vec::new();
            };
            let stride = view.stride().unwrap_or(elem).max(elem);
            let start = view.offset() + a.offset();
            (0..a.count())
                .map(|i| element(&data.0, start + i * stride))
                .collect()
        }
        None => vec![[0.0; N]; a.count()],
    };
    if let Some(s) = a.sparse() {
        let (iv, vv) = (s.indices().view(), s.values().view());
        let (Some(idata), Some(vdata)) = (
            buffers.get(iv.buffer().index()),
            buffers.get(vv.buffer().index()),
        ) else {
            return out;
        };
        let istart = iv.offset() + s.indices().offset();
        let vstart = vv.offset() + s.values().offset();
        for k in 0..s.count() {
            let b = &idata.0[..];
            let i = match s.indices().index_type() {
                gltf::accessor::sparse::IndexType::U8 => b[istart + k] as usize,
                gltf::accessor::sparse::IndexType::U16 => {
                    u16::from_le_bytes([b[istart + 2 * k], b[istart + 2 * k + 1]]) as usize
                }
                gltf::accessor::sparse::IndexType::U32 => {
                    let at = istart + 4 * k;
                    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize
                }
            };
            // An index past the elements is the file's error; it is skipped.
            if let Some(slot) = out.get_mut(i) {
                *slot = element(&vdata.0, vstart + k * elem);
            }
        }
    }
    out
}

/// Checks that `a`'s elements lie inside its buffer's data: the crate's reader slices without
/// checking, so a view or accessor that overruns its buffer would otherwise panic.
pub fn fits(
    a: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    sparse_ok: bool,
) -> Result<(), Malformed> {
    let name = format!("accessor {}", a.index());
    // The specification's minimum; the crate's reader computes `count - 1` unchecked (its
    // accessor/util.rs:384, found by `fuzz/`).
    if a.count() == 0 {
        return Err(Malformed(format!(
            "{name} has a count of 0 (at least 1 is required)"
        )));
    }
    // A sparse attribute (its base, if any, then its substitutions) is read by
    // `gltf_accessors`; sparse indices are not read.
    if let Some(s) = a.sparse() {
        if !sparse_ok {
            return Err(Malformed(format!(
                "{name} is sparse, which termtrace does not read for indices"
            )));
        }
        let index_size = match s.indices().index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        for (what, view, offset, elem) in [
            (
                "indices",
                s.indices().view(),
                s.indices().offset(),
                index_size,
            ),
            ("values", s.values().view(), s.values().offset(), a.size()),
        ] {
            let data = buffers.get(view.buffer().index()).ok_or_else(|| {
                Malformed(format!(
                    "{name}'s sparse {what}: no buffer {}",
                    view.buffer().index()
                ))
            })?;
            let span = elem
                .checked_mul(s.count())
                .and_then(|x| x.checked_add(offset));
            let end = view.offset().checked_add(view.length());
            if !matches!((span, end), (Some(span), Some(end)) if span <= view.length() && end <= data.len())
            {
                return Err(Malformed(format!(
                    "{name}'s sparse {what} reach past the end of their buffer view or buffer"
                )));
            }
        }
        if a.view().is_none() {
            return Ok(());
        }
    }
    let Some(view) = a.view() else {
        return Err(Malformed(format!("{name} has no buffer view")));
    };
    let data = buffers
        .get(view.buffer().index())
        .ok_or_else(|| Malformed(format!("{name}: no buffer {}", view.buffer().index())))?;
    let elem = a.size();
    let stride = view.stride().unwrap_or(elem).max(elem);
    let span = match a.count() {
        0 => Some(0),
        n => stride
            .checked_mul(n - 1)
            .and_then(|x| x.checked_add(elem))
            .and_then(|x| x.checked_add(a.offset())),
    };
    let view_end = view.offset().checked_add(view.length());
    match (span, view_end) {
        (Some(span), Some(end)) if span <= view.length() && end <= data.len() => Ok(()),
        _ => Err(Malformed(format!(
            "{name} reaches past the end of its buffer view or buffer ({} bytes)",
            data.len()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_integers_follow_the_specification() {
        assert_eq!(component(DataType::I8, true, &[127]), 1.0);
        assert_eq!(component(DataType::I8, true, &[0x80]), -1.0);
        assert_eq!(component(DataType::I8, true, &[0x81]), -1.0);
        assert_eq!(component(DataType::U8, true, &[255]), 1.0);
        assert_eq!(
            component(DataType::I16, true, &(-32768i16).to_le_bytes()),
            -1.0
        );
        assert_eq!(component(DataType::U16, true, &[0xff, 0xff]), 1.0);
        assert_eq!(
            component(DataType::U16, false, &16383u16.to_le_bytes()),
            16383.0
        );
        assert_eq!(component(DataType::I8, false, &[0xfe]), -2.0);
        assert_eq!(component(DataType::F32, false, &1.5f32.to_le_bytes()), 1.5);
    }
}
