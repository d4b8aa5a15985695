//! `KHR_draco_mesh_compression`: a primitive's attributes and indices come as one Draco
//! bitstream, decoded at load by `draco-core` (a pure-Rust port of Google's decoder). The
//! decoded values are written into a buffer of their own and the primitive's accessors
//! pointed at them, before the file is validated, so that the importer reads them as any
//! others (the extension's specification:
//! https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Khronos/KHR_draco_mesh_compression).

use super::error::Malformed;
use draco_core::{DataType, DecoderBuffer, Mesh, MeshDecoder, PointIndex};
use gltf::json::{self, validation::Checked};

pub const NAME: &str = "KHR_draco_mesh_compression";

/// glTF's component type that a Draco data type stores as, and its size.
fn component(t: DataType) -> Option<(json::accessor::ComponentType, usize)> {
    use json::accessor::ComponentType as C;
    Some(match t {
        DataType::Int8 => (C::I8, 1),
        DataType::Uint8 => (C::U8, 1),
        DataType::Int16 => (C::I16, 2),
        DataType::Uint16 => (C::U16, 2),
        DataType::Uint32 => (C::U32, 4),
        DataType::Float32 => (C::F32, 4),
        _ => return None,
    })
}

/// Decodes every Draco primitive of `root` (whose buffers' bytes are `buffers`), appending
/// one buffer of decoded data and pointing the primitives' accessors into it.
pub fn decode(
    root: &mut json::Root,
    buffers: &mut Vec<gltf::buffer::Data>,
) -> Result<(), Malformed> {
    let start_time = std::time::Instant::now();
    let mut faces = 0usize;
    let mut out: Vec<u8> = Vec::new();
    let new_buffer = root.buffers.len();
    let mut new_views = Vec::new();
    let mut pointed = Vec::new();
    for (mi, m) in root.meshes.iter().enumerate() {
        for (pi, p) in m.primitives.iter().enumerate() {
            let Some(ext) = p.extensions.as_ref().and_then(|e| e.others.get(NAME)) else {
                continue;
            };
            let what = format!("meshes[{mi}].primitives[{pi}] ({NAME})");
            let err = |e: String| Malformed(format!("{what}: {e}"));
            let bytes = ext
                .get("bufferView")
                .and_then(|v| v.as_u64())
                .and_then(|v| root.buffer_views.get(v as usize))
                .and_then(|v| {
                    let start = v.byte_offset.map_or(0, |o| o.0 as usize);
                    let data = buffers.get(v.buffer.value())?;
                    data.get(start..start.checked_add(v.byte_length.0 as usize)?)
                })
                .ok_or_else(|| err("its bufferView is not in the file's buffers".into()))?;
            let mut mesh = Mesh::new();
            MeshDecoder::new()
                .decode(&mut DecoderBuffer::new(bytes), &mut mesh)
                .map_err(|e| err(format!("the Draco stream does not decode: {e}")))?;
            faces += mesh.num_faces();
            let ids = ext
                .get("attributes")
                .and_then(|a| a.as_object())
                .ok_or_else(|| err("no attributes".into()))?;
            // Each attribute the primitive names, by its Draco id.
            for (semantic, accessor) in &p.attributes {
                let name = match semantic {
                    Checked::Valid(s) => s.to_string(),
                    Checked::Invalid => continue,
                };
                let Some(id) = ids.get(&name).and_then(|v| v.as_u64()) else {
                    continue;
                };
                let a = mesh
                    .attribute_by_unique_id(id as u32)
                    .ok_or_else(|| err(format!("{name}: no Draco attribute {id}")))?;
                let (ty, size) = component(a.data_type())
                    .ok_or_else(|| err(format!("{name}: Draco data of {:?}", a.data_type())))?;
                let elem = size * a.num_components() as usize;
                let stride = a.byte_stride() as usize;
                let data = a.buffer().data();
                let start = out.len();
                for k in 0..mesh.num_points() {
                    let at = a.mapped_index(PointIndex(k as u32)).0 as usize * stride;
                    let v = data
                        .get(at..at + elem)
                        .ok_or_else(|| err(format!("{name}: point {k} maps outside its values")))?;
                    out.extend_from_slice(v);
                }
                pointed.push((
                    accessor.value(),
                    ty,
                    mesh.num_points(),
                    start,
                    out.len() - start,
                    what.clone(),
                ));
            }
            if let Some(indices) = &p.indices {
                let (ty, size) = match root
                    .accessors
                    .get(indices.value())
                    .map(|a| a.component_type)
                {
                    Some(Checked::Valid(json::accessor::GenericComponentType(t))) => (
                        t,
                        match t {
                            json::accessor::ComponentType::U8 => 1,
                            json::accessor::ComponentType::U16 => 2,
                            _ => 4,
                        },
                    ),
                    _ => return Err(err("its indices' accessor has no valid type".into())),
                };
                let start = out.len();
                for f in 0..mesh.num_faces() {
                    for c in mesh.face(draco_core::FaceIndex(f as u32)) {
                        out.extend_from_slice(&c.0.to_le_bytes()[..size]);
                    }
                }
                pointed.push((
                    indices.value(),
                    ty,
                    3 * mesh.num_faces(),
                    start,
                    out.len() - start,
                    what.clone(),
                ));
            }
            while !out.len().is_multiple_of(4) {
                out.push(0);
            }
        }
    }
    if pointed.is_empty() {
        return Ok(());
    }
    for (accessor, ty, count, start, length, what) in pointed {
        let a = root
            .accessors
            .get_mut(accessor)
            .ok_or_else(|| Malformed(format!("{what}: accessor {accessor} is not in the file")))?;
        let declared = match a.component_type {
            Checked::Valid(json::accessor::GenericComponentType(t)) => Some(t),
            Checked::Invalid => None,
        };
        if declared != Some(ty) || a.count.0 as usize != count {
            return Err(Malformed(format!(
                "{what}: accessor {accessor} declares {} of {declared:?}, and Draco decodes {count} \
                 of {ty:?}",
                a.count.0
            )));
        }
        a.buffer_view = Some(json::Index::new(
            (root.buffer_views.len() + new_views.len()) as u32,
        ));
        a.byte_offset = None;
        new_views.push(json::buffer::View {
            buffer: json::Index::new(new_buffer as u32),
            byte_length: length.into(),
            byte_offset: Some(start.into()),
            byte_stride: None,
            name: None,
            target: None,
            extensions: None,
            extras: Default::default(),
        });
    }
    root.buffer_views.extend(new_views);
    root.buffers.push(json::Buffer {
        byte_length: out.len().into(),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    buffers.push(gltf::buffer::Data(out));
    tracing::info!(
        "Draco: {faces} triangles decoded in {:.1} ms",
        start_time.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}
