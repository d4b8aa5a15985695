//! The reference a convergence run is measured against: an EXR the user gives, or a long
//! render made once and cached under a hash of everything that decides its pixels.

use super::ConvergeError;
use crate::common::AccumData;
use crate::common::FrameSettings;
use crate::output::LinearImage;
use crate::render::Backend;
use crate::render::team::Team;
use crate::render::{RenderOptions, Snapshot};
use crate::scene::Scene;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Seed of rendered references: no run uses it (runs count up from the scene's seed), so a
/// reference's noise is independent of the runs measured against it.
pub const REFERENCE_SEED: u32 = 0x5eed_2ef0;

pub struct Reference {
    pub image: LinearImage,
    /// The accumulation behind a rendered reference (its halves give its own noise, which the
    /// bias check needs); `None` for a reference read from a file, taken as exact.
    pub snapshot: Option<Snapshot>,
    /// Where it came from, for reports.
    pub source: String,
}

impl Reference {
    /// Its own estimated relative RMSE, when known.
    pub fn noise(&self) -> Option<f64> {
        self.snapshot.as_ref().and_then(Snapshot::noise_estimate)
    }
}

/// Reads a reference file: a rendered reference from the cache (`reference-….bin`, with its
/// two halves, so that its own noise is known: how a reference made by an earlier build is
/// kept for the bias check of a new one), or else a linear EXR, taken as exact. Its size
/// must be the render's.
pub fn from_file(path: &Path, width: u32, height: u32) -> Result<Reference, ConvergeError> {
    if path.extension().is_some_and(|e| e == "bin") {
        let snap = read_cache(path, width, height).ok_or_else(|| ConvergeError::NotCached {
            path: path.to_path_buf(),
            width,
            height,
        })?;
        return Ok(Reference {
            image: snap.image(),
            source: format!("{} spp, from {}", snap.samples, path.display()),
            snapshot: Some(snap),
        });
    }
    from_exr(path, width, height)
}

/// Reads a linear EXR; its size must be the render's.
pub fn from_exr(path: &Path, width: u32, height: u32) -> Result<Reference, ConvergeError> {
    let img = image::open(path)
        .map_err(|source| ConvergeError::Read {
            path: path.to_path_buf(),
            source,
        })?
        .to_rgb32f();
    if img.dimensions() != (width, height) {
        return Err(ConvergeError::Size {
            path: path.to_path_buf(),
            reference: img.dimensions(),
            runs: (width, height),
        });
    }
    Ok(Reference {
        image: LinearImage {
            width,
            height,
            pixels: img.pixels().map(|p| p.0).collect(),
        },
        snapshot: None,
        source: path.display().to_string(),
    })
}

/// The directory for cached references: `$TERMTRACE_CACHE`, else `$XDG_CACHE_HOME/termtrace`,
/// else `~/.cache/termtrace`, else the temporary directory.
pub fn default_cache_dir() -> PathBuf {
    let env = |k| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    env("TERMTRACE_CACHE")
        .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("termtrace")))
        .or_else(|| env("HOME").map(|d| d.join(".cache/termtrace")))
        .unwrap_or_else(|| std::env::temp_dir().join("termtrace-cache"))
}

/// A hash of everything that decides a rendered reference's pixels: the scene as written
/// back, the settings, the sample count, the tracer's shaders and version, the adapter.
pub fn cache_key(scene: &Scene, s: &FrameSettings, spp: u32, adapter: &str) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    crate::scene::to_toml(scene).hash(&mut h);
    (
        s.width,
        s.height,
        s.max_bounces,
        s.pixel_aspect.to_bits(),
        s.nee,
        spp,
        REFERENCE_SEED,
    )
        .hash(&mut h);
    for (_, src) in crate::common::wgsl::SOURCES {
        src.hash(&mut h);
    }
    env!("CARGO_PKG_VERSION").hash(&mut h);
    adapter.hash(&mut h);
    h.finish()
}

const MAGIC: &[u8; 8] = b"TTREF01\0";

fn write_cache(path: &Path, snap: &Snapshot) -> std::io::Result<()> {
    let mut bytes = MAGIC.to_vec();
    for v in [snap.width, snap.height, snap.samples, 0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(bytemuck::cast_slice(&snap.data.even));
    bytes.extend_from_slice(bytemuck::cast_slice(&snap.data.odd));
    std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")))?;
    let tmp = path.with_extension("part");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

fn read_cache(path: &Path, width: u32, height: u32) -> Option<Snapshot> {
    let bytes = std::fs::read(path).ok()?;
    if bytes.len() < 24 || &bytes[..8] != MAGIC {
        return None;
    }
    let word = |i: usize| u32::from_le_bytes(bytes[8 + 4 * i..12 + 4 * i].try_into().unwrap());
    let (w, h, samples) = (word(0), word(1), word(2));
    let n = w as usize * h as usize;
    if (w, h) != (width, height) || bytes.len() != 24 + 2 * n * 16 {
        return None;
    }
    let floats: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes[24..]);
    Some(Snapshot {
        width: w,
        height: h,
        samples,
        data: AccumData::from_halves(floats[..n].to_vec(), floats[n..].to_vec()),
    })
}

/// Renders the reference at `spp` (or takes it from the cache), reporting progress.
pub fn rendered(
    backends: &[Backend],
    scene: &Scene,
    settings: FrameSettings,
    spp: u32,
    cache_dir: Option<&Path>,
    mut progress: impl FnMut(u32, u32),
) -> Reference {
    let names: Vec<String> = backends.iter().map(Backend::describe).collect();
    let key = cache_key(scene, &settings, spp, &names.join(" + "));
    let path = cache_dir.map(|d| d.join(format!("reference-{key:016x}.bin")));
    if let Some(p) = &path
        && let Some(snap) = read_cache(p, settings.width, settings.height)
    {
        return Reference {
            image: snap.image(),
            source: format!("{} spp, cached in {}", snap.samples, p.display()),
            snapshot: Some(snap),
        };
    }
    let s = FrameSettings {
        seed: REFERENCE_SEED,
        ..settings
    };
    let team = Team::new(backends, scene, s, RenderOptions::default(), 0..spp);
    team.run(Duration::from_millis(250), None, |t| {
        progress(t.samples().min(spp as u64) as u32, spp);
        true
    });
    let snap = team.snapshot();
    let mut source = format!("{spp} spp, rendered");
    if let Some(p) = &path {
        match write_cache(p, &snap) {
            Ok(()) => source = format!("{spp} spp, rendered and cached in {}", p.display()),
            Err(e) => tracing::warn!("could not cache the reference in {}: {e}", p.display()),
        }
    }
    Reference {
        image: snap.image(),
        snapshot: Some(snap),
        source,
    }
}
