//! Where a glTF mesh is drawn more than once: by several nodes, or by one node's
//! `EXT_mesh_gpu_instancing` attributes. The loader chooses per mesh whether its copies are
//! instances (stored once, traced through a two-level BVH) or flattened into world space.

use super::error::Malformed;
use glam::{DMat4, DQuat, DVec3};

/// How a file's repeated meshes are stored: the TOML's `instancing` key on a `[[gltf]]` table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Instancing {
    /// Instances where flattening would make more than [`FLATTEN_AT_MOST`] triangles of one
    /// mesh; flattened below (faster to trace, and the memory is small).
    #[default]
    Auto,
    /// Every mesh drawn more than once is instanced.
    Always,
    /// Every copy is flattened into world space.
    Never,
}

impl Instancing {
    pub const NAMES: &[&str] = &["auto", "always", "never"];

    pub fn named(name: &str) -> Option<Instancing> {
        match name {
            "auto" => Some(Instancing::Auto),
            "always" => Some(Instancing::Always),
            "never" => Some(Instancing::Never),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Instancing::Auto => "auto",
            Instancing::Always => "always",
            Instancing::Never => "never",
        }
    }

    /// Whether a mesh of `triangles` drawn `copies` times is instanced.
    pub fn instances(self, copies: usize, triangles: usize) -> bool {
        match self {
            Instancing::Never => false,
            Instancing::Always => copies > 1,
            Instancing::Auto => copies > 1 && copies.saturating_mul(triangles) > FLATTEN_AT_MOST,
        }
    }
}

/// Under `auto`, the most triangles one mesh's copies are flattened into: 2²⁰ triangles
/// take about 150 MB flattened (BENCHMARKS.md, "Instancing").
pub const FLATTEN_AT_MOST: usize = 1 << 20;

/// Host memory one flattened triangle takes by the time it is traced: the scene's copy, the
/// tracer's arrays and bounds, the BVH's build and nodes. Measured: 2·10⁶ flattened triangles
/// (`benches/instanced-forest.py`, 100 copies, `instancing = "never"`) peaked at 834 MB
/// rendering on the CPU tracer, 417 bytes each.
pub const BYTES_PER_TRIANGLE: u64 = 420;

/// Memory this process may still take: the kernel's `MemAvailable`, or less where a cgroup
/// limits it (`None` where neither can be read: no guard).
pub fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<u64>()
        .ok()?;
    let read = |f: &str| {
        std::fs::read_to_string(format!("/sys/fs/cgroup/{f}"))
            .ok()
            .and_then(|s| s.trim().parse::<u64>().ok())
    };
    let cgroup = match (read("memory.max"), read("memory.current")) {
        (Some(max), Some(cur)) => Some(max.saturating_sub(cur)),
        _ => None,
    };
    Some(cgroup.map_or(kib * 1024, |c| c.min(kib * 1024)))
}

/// The memory guard: `triangles` to store (flattened copies counted each) against what is
/// `available`; the refusal names both, and what would open the file.
pub fn check_memory(triangles: u64, available: Option<u64>) -> Result<(), Malformed> {
    let need = triangles.saturating_mul(BYTES_PER_TRIANGLE);
    match available {
        Some(have) if need > have => {
            let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
            Err(Malformed(format!(
                "its meshes make {triangles} triangles to store, about {:.1} GiB by the time they \
                 are traced ({BYTES_PER_TRIANGLE} bytes each), more than the {:.1} GiB this \
                 machine has available; a mesh drawn many times is stored once with \
                 `instancing = \"auto\"` (the default) or \"always\" on its `[[gltf]]` table",
                gib(need),
                gib(have)
            )))
        }
        _ => Ok(()),
    }
}

/// The triangles a mesh has, from its accessors' counts (before reading them).
pub fn triangle_estimate(mesh: &gltf::Mesh) -> usize {
    mesh.primitives()
        .map(|p| {
            let n = match p.indices() {
                Some(i) => i.count(),
                None => p.get(&gltf::Semantic::Positions).map_or(0, |a| a.count()),
            };
            match p.mode() {
                gltf::mesh::Mode::Triangles => n / 3,
                gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => {
                    n.saturating_sub(2)
                }
                _ => 0,
            }
        })
        .sum()
}

/// The node-from-instance transforms of a node's `EXT_mesh_gpu_instancing` (translation,
/// rotation, scale per instance, each optional; `None`: the node has none). The attributes'
/// accessors are checked like a primitive's and read dequantized (the extension allows
/// normalized 8- and 16-bit rotations).
pub fn gpu_instances(
    node: &gltf::Node,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Result<Option<Vec<DMat4>>, Malformed> {
    let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
        return Ok(None);
    };
    let what = format!("nodes[{}].extensions.EXT_mesh_gpu_instancing", node.index());
    let attributes = ext
        .get("attributes")
        .and_then(|a| a.as_object())
        .ok_or_else(|| Malformed(format!("{what}: no attributes")))?;
    use gltf::accessor::{DataType as T, Dimensions as D};
    let read =
        |key: &str, dims: D, types: &[T], n: usize| -> Result<Option<Vec<[f32; 4]>>, Malformed> {
            let Some(v) = attributes.get(key) else {
                return Ok(None);
            };
            let a = v
                .as_u64()
                .and_then(|i| doc.accessors().nth(i as usize))
                .ok_or_else(|| Malformed(format!("{what}.attributes.{key}: not an accessor")))?;
            if a.dimensions() != dims || !types.contains(&a.data_type()) {
                return Err(Malformed(format!(
                    "{what}.attributes.{key}: accessor {} holds {:?} of {:?}, where {dims:?} of \
                 {types:?} belong",
                    a.index(),
                    a.dimensions(),
                    a.data_type()
                )));
            }
            super::gltf_accessors::fits(&a, buffers, true)
                .map_err(|e| Malformed(format!("{what}.attributes.{key}: {e}")))?;
            Ok(Some(if n == 3 {
                super::gltf_accessors::read::<3>(&a, buffers)
                    .into_iter()
                    .map(|[x, y, z]| [x, y, z, 0.0])
                    .collect()
            } else {
                super::gltf_accessors::read::<4>(&a, buffers)
            }))
        };
    let translation = read("TRANSLATION", D::Vec3, &[T::F32], 3)?;
    let rotation = read("ROTATION", D::Vec4, &[T::F32, T::I8, T::I16], 4)?;
    let scale = read("SCALE", D::Vec3, &[T::F32], 3)?;
    let counts: Vec<usize> = [&translation, &rotation, &scale]
        .iter()
        .filter_map(|a| a.as_ref().map(Vec::len))
        .collect();
    let Some(&count) = counts.first() else {
        return Err(Malformed(format!(
            "{what}: none of TRANSLATION, ROTATION, SCALE"
        )));
    };
    if counts.iter().any(|&c| c != count) {
        return Err(Malformed(format!(
            "{what}: its attributes have different counts ({counts:?})"
        )));
    }
    let d = |v: [f32; 4]| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    (0..count)
        .map(|i| {
            let t = translation.as_ref().map_or(DVec3::ZERO, |a| d(a[i]));
            let s = scale.as_ref().map_or(DVec3::ONE, |a| d(a[i]));
            let r = rotation.as_ref().map_or(DQuat::IDENTITY, |a| {
                let [x, y, z, w] = a[i].map(f64::from);
                DQuat::from_xyzw(x, y, z, w)
            });
            let m = DMat4::from_scale_rotation_translation(s, r.normalize(), t);
            if m.is_finite() && r.length() > 0.0 {
                Ok(m)
            } else {
                Err(Malformed(format!(
                    "{what}: instance {i} has a transform that is not finite"
                )))
            }
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_instances_only_what_flattening_would_make_large() {
        assert!(!Instancing::Auto.instances(1, 1 << 24));
        assert!(!Instancing::Auto.instances(4, 1000));
        assert!(Instancing::Auto.instances(10_000, 20_000));
        assert!(Instancing::Always.instances(2, 1));
        assert!(!Instancing::Always.instances(1, 1 << 24));
        assert!(!Instancing::Never.instances(10_000, 20_000));
        for n in Instancing::NAMES {
            assert_eq!(Instancing::named(n).unwrap().name(), *n);
        }
    }

    #[test]
    fn the_memory_guard_refuses_with_the_figure_and_the_limit() {
        assert!(check_memory(1_000_000, Some(1 << 30)).is_ok());
        assert!(check_memory(u64::MAX / 1000, None).is_ok());
        let e = check_memory(200_000_000, Some(20 << 30)).unwrap_err().0;
        assert!(
            e.contains("200000000 triangles") && e.contains("78.2 GiB") && e.contains("20.0 GiB"),
            "{e}"
        );
        assert!(available_memory().is_none_or(|b| b > 0));
    }
}
