//! Exact-sum snapshots (`.tta`): the accumulation words of a render or of one shard of it
//! (a range of every pixel's samples), with what they belong to, so that shards rendered
//! anywhere merge into the image one device would have made, bit for bit.
//!
//! A file is `TTACCUM\n`, the format version (u32), the header's length (u32) and the header
//! (TOML: the scene's hash, the frame settings, the whole render's samples per pixel, the
//! shard and the sample range it holds), then the even and the odd halves' words (u32,
//! `ACCUM_WORDS` per pixel, little-endian), then the CRC-32 of everything before it. Written
//! atomically; read with every field checked. Version 2 (written now) stores the words'
//! bytes as four planes (every word's lowest byte, then the next, …: the high bytes of
//! fixed-point sums are mostly zero) compressed by deflate; version 1 (raw words) is still
//! read.

use crate::common::accum::ACCUM_WORDS;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"TTACCUM\n";
/// The format version this build writes (it reads this one and version 1).
pub const VERSION: u32 = 2;
/// Deflate expands a stream by at most ~1032:1; a payload claiming more is refused before
/// it is inflated (no zip bomb reaches memory).
const MAX_INFLATION: usize = 1100;

/// What a snapshot's sums belong to, and which of them it holds.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// The termtrace version that traced it: another build may trace other paths.
    pub termtrace: String,
    /// The scene, for messages.
    pub scene: String,
    /// A hash of everything the image depends on (`render::shard::scene_hash`).
    pub scene_hash: String,
    pub width: u32,
    pub height: u32,
    pub max_bounces: u32,
    pub seed: u32,
    pub nee: bool,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// This part is shard `shard` of `shards`.
    pub shard: u32,
    pub shards: u32,
    /// The samples of every pixel it holds: `[first, end)`.
    pub first_sample: u32,
    pub end_sample: u32,
    /// Samples discarded as NaN or infinite.
    pub invalid: u64,
}

impl Header {
    /// The header of shard `shard` of `shards` of `scene` rendered with `s` at `spp` samples
    /// per pixel by this termtrace, `invalid` samples discarded.
    pub fn new(
        scene: &crate::scene::Scene,
        s: &crate::common::FrameSettings,
        spp: u32,
        (shard, shards): (u32, u32),
        invalid: u64,
    ) -> Header {
        let (first_sample, end_sample) = Header::range(shard, shards, spp);
        Header {
            termtrace: env!("CARGO_PKG_VERSION").to_string(),
            scene: scene.origin.clone(),
            scene_hash: scene_hash(scene),
            width: s.width,
            height: s.height,
            max_bounces: s.max_bounces,
            seed: s.seed,
            nee: s.nee,
            spp,
            shard,
            shards,
            first_sample,
            end_sample,
            invalid,
        }
    }

    /// The samples shard `i` of `k` holds of a render of `spp`: `[⌊i·spp/k⌋, ⌊(i+1)·spp/k⌋)`.
    pub fn range(i: u32, k: u32, spp: u32) -> (u32, u32) {
        let at = |i: u32| (i as u64 * spp as u64 / k as u64) as u32;
        (at(i), at(i + 1))
    }

    /// What makes two parts of one render: everything but the shard, its range and its
    /// invalid count.
    fn render_key(&self) -> Header {
        Header {
            shard: 0,
            first_sample: 0,
            end_sample: 0,
            invalid: 0,
            ..self.clone()
        }
    }
}

/// A snapshot: its header and the words of both halves.
#[derive(Clone, Debug)]
pub struct Part {
    pub header: Header,
    pub even: Vec<u32>,
    pub odd: Vec<u32>,
}

/// A hash of everything an image depends on besides the frame settings: the scene as its
/// file says it (`to_toml`: camera, sky, materials, objects, placements), the geometry
/// (triangles included), the texture words and the environment map's texels; two CRC-32s
/// over different halves of that, as 16 hex digits.
pub fn scene_hash(scene: &crate::scene::Scene) -> String {
    let mut a = crc32fast::Hasher::new();
    a.update(crate::scene::to_toml(scene).as_bytes());
    a.update(&crate::common::arrays::geometry_content_hash(scene).to_le_bytes());
    let mut b = crc32fast::Hasher::new();
    if let Some(words) = crate::common::textures::words(scene) {
        b.update(bytemuck::cast_slice(&words));
    }
    if let Some(e) = &scene.environment {
        b.update(bytemuck::cast_slice(&e.map.rgbe));
    }
    format!("{:08x}{:08x}", a.finalize(), b.finalize())
}

/// Whether `path` names a snapshot file (`.tta`, any case).
pub fn is_part_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("tta"))
}

fn words_of(h: &Header) -> usize {
    (h.width as usize)
        .saturating_mul(h.height as usize)
        .saturating_mul(ACCUM_WORDS)
}

/// Writes `part` to `path` atomically (version [`VERSION`]).
pub fn write(path: &Path, part: &Part) -> Result<(), crate::output::OutputError> {
    crate::output::write::write_bytes(path, &encode(part, VERSION))
}

/// The words' bytes as four planes: byte 0 of every word, then byte 1, 2 and 3.
fn planes(words: &[&[u32]]) -> Vec<u8> {
    let n: usize = words.iter().map(|w| w.len()).sum();
    let mut out = vec![0u8; 4 * n];
    for (i, &w) in words.iter().flat_map(|w| w.iter()).enumerate() {
        for (b, byte) in w.to_le_bytes().into_iter().enumerate() {
            out[b * n + i] = byte;
        }
    }
    out
}

/// A snapshot's bytes in format `version` (1: raw words; 2: byte planes, deflated).
fn encode(part: &Part, version: u32) -> Vec<u8> {
    use std::io::Write;
    let header = toml::to_string(&part.header).expect("a header serializes");
    let payload = match version {
        1 => part
            .even
            .iter()
            .chain(&part.odd)
            .flat_map(|w| w.to_le_bytes())
            .collect(),
        _ => {
            let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::fast());
            z.write_all(&planes(&[&part.even, &part.odd]))
                .expect("deflate into memory");
            z.finish().expect("deflate into memory")
        }
    };
    let mut bytes = Vec::with_capacity(16 + header.len() + payload.len() + 4);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&version.to_le_bytes());
    bytes.extend_from_slice(&(header.len() as u32).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(&payload);
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

crate::message_error!(
    /// Why a snapshot cannot be read or a set of them merged, naming the file.
    ShardError
);

/// Reads a snapshot, refusing (with the file's name) anything that is not one, a version this
/// build does not read, a header that does not parse, a size that does not match it, or
/// bytes that do not match their checksum.
pub fn read(path: &Path) -> Result<Part, ShardError> {
    let name = path.display();
    let bytes =
        std::fs::read(path).map_err(|e| ShardError(format!("{name}: cannot read it: {e}")))?;
    parse(&bytes).map_err(|e| ShardError(format!("{name}: {e}")))
}

/// [`read`] from memory.
pub fn parse(bytes: &[u8]) -> Result<Part, ShardError> {
    if bytes.len() < 20 || &bytes[..8] != MAGIC {
        return Err("not a termtrace snapshot (.tta)".into());
    }
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let version = u32_at(8);
    if version != 1 && version != VERSION {
        return Err(ShardError(format!(
            "a snapshot of format version {version}; this termtrace reads versions 1 and \
             {VERSION}"
        )));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let crc = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    if crc32fast::hash(body) != crc {
        return Err("corrupted: its checksum does not match its bytes".into());
    }
    let len = u32_at(12) as usize;
    let text = body
        .get(16..16 + len)
        .and_then(|t| std::str::from_utf8(t).ok())
        .ok_or("corrupted: its header is cut short or not text")?;
    let header: Header =
        toml::from_str(text).map_err(|e| ShardError(format!("its header: {e}")))?;
    let n = words_of(&header);
    // Bytes of both halves' words.
    let need = n.saturating_mul(8);
    let payload = &body[16 + len..];
    let sizes = |bytes: usize| {
        format!(
            "holds {bytes} bytes of sums where a {}×{} image has {need}",
            header.width, header.height
        )
    };
    let words: Vec<u32> = if version == 1 {
        if payload.len() != need {
            return Err(sizes(payload.len()).into());
        }
        payload
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    } else {
        use std::io::Read;
        if need > MAX_INFLATION.saturating_mul(payload.len().max(1)) {
            return Err(ShardError(format!(
                "corrupted: {} compressed bytes cannot hold the {need} of a {}×{} image's sums",
                payload.len(),
                header.width,
                header.height
            )));
        }
        let mut planes = Vec::new();
        flate2::read::DeflateDecoder::new(payload)
            .take(need as u64 + 1)
            .read_to_end(&mut planes)
            .map_err(|e| ShardError(format!("corrupted: its sums do not inflate: {e}")))?;
        if planes.len() != need {
            return Err(sizes(planes.len()).into());
        }
        let count = 2 * n;
        (0..count)
            .map(|i| {
                u32::from_le_bytes([
                    planes[i],
                    planes[count + i],
                    planes[2 * count + i],
                    planes[3 * count + i],
                ])
            })
            .collect()
    };
    let odd = words[n..].to_vec();
    let mut even = words;
    even.truncate(n);
    Ok(Part { header, even, odd })
}

pub use crate::common::accum::{Sums, add_words};

/// Merges the parts of one render (in any order) into the whole: refused, naming the files,
/// if a part belongs to another render (scene, settings, version), a shard is missing or
/// given twice, or a part's range is not its shard's.
pub fn merge(parts: &[(PathBuf, Part)]) -> Result<Part, ShardError> {
    let Some((first_path, first)) = parts.first() else {
        return Err("no parts to merge".into());
    };
    let key = first.header.render_key();
    let k = key.shards;
    let mut seen: Vec<Option<&Path>> = vec![None; k as usize];
    for (path, p) in parts {
        let h = &p.header;
        if h.render_key() != key {
            return Err(ShardError(format!(
                "{} is not a part of the render {} belongs to: {}",
                path.display(),
                first_path.display(),
                difference(&key, &h.render_key())
            )));
        }
        if h.shard >= k {
            return Err(ShardError(format!(
                "{}: shard {} of {k}",
                path.display(),
                h.shard
            )));
        }
        if Header::range(h.shard, k, key.spp) != (h.first_sample, h.end_sample) {
            return Err(ShardError(format!(
                "{}: shard {} holds samples {}..{}, not its share of {} spp",
                path.display(),
                h.shard,
                h.first_sample,
                h.end_sample,
                key.spp
            )));
        }
        if let Some(other) = seen[h.shard as usize] {
            return Err(ShardError(format!(
                "shard {} of {k} is given twice: {} and {}",
                h.shard,
                other.display(),
                path.display()
            )));
        }
        seen[h.shard as usize] = Some(path);
    }
    let missing: Vec<String> = (0..k)
        .filter(|i| seen[*i as usize].is_none())
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(ShardError(format!(
            "{} of the {k} shards of {} are missing: {}",
            missing.len(),
            key.scene,
            missing.join(", ")
        )));
    }
    let mut whole = Part {
        header: Header {
            shard: 0,
            shards: 1,
            first_sample: 0,
            end_sample: key.spp,
            invalid: 0,
            ..key
        },
        even: vec![0; first.even.len()],
        odd: vec![0; first.odd.len()],
    };
    for (_, p) in parts {
        add_words(&mut whole.even, &p.even);
        add_words(&mut whole.odd, &p.odd);
        whole.header.invalid += p.header.invalid;
    }
    Ok(whole)
}

/// The fields in which two renders' headers differ, for messages.
fn difference(a: &Header, b: &Header) -> String {
    let ta = toml::to_string(a).unwrap_or_default();
    let tb = toml::to_string(b).unwrap_or_default();
    let diffs: Vec<String> = ta
        .lines()
        .zip(tb.lines())
        .filter(|(x, y)| x != y)
        .map(|(x, y)| format!("{y} where it has {x}"))
        .collect();
    diffs.join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A whole render's header at `width × height`, 8 spp.
    fn header(width: u32, height: u32) -> Header {
        Header {
            termtrace: "test".into(),
            scene: "test".into(),
            scene_hash: "0".into(),
            width,
            height,
            max_bounces: 4,
            seed: 1,
            nee: true,
            spp: 8,
            shard: 0,
            shards: 1,
            first_sample: 0,
            end_sample: 8,
            invalid: 0,
        }
    }

    #[test]
    fn both_versions_read_back_the_same_words() {
        // Sums of a few pixels (high words mostly zero, as fixed-point sums are): written as
        // version 1 (raw) and 2 (byte planes, deflated), both read back word for word, and
        // the compressed one is smaller. A version-2 payload that claims more than deflate
        // can expand to is refused before it is inflated.
        let header = header(7, 3);
        let n = words_of(&header);
        let word = |i: usize| {
            if i % 10 < 3 {
                (i as u32).wrapping_mul(2_654_435_761)
            } else {
                (i % 5) as u32
            }
        };
        let part = Part {
            header,
            even: (0..n).map(word).collect(),
            odd: (n..2 * n).map(word).collect(),
        };
        let (v1, v2) = (encode(&part, 1), encode(&part, 2));
        assert!(
            v2.len() < v1.len(),
            "{} against {} bytes",
            v2.len(),
            v1.len()
        );
        for bytes in [&v1, &v2] {
            let back = parse(bytes).unwrap();
            assert_eq!(
                (back.header, back.even, back.odd),
                (part.header.clone(), part.even.clone(), part.odd.clone())
            );
        }
        let mut huge = part.clone();
        huge.header.width = 1 << 30;
        let e = parse(&encode(&huge, 2)).unwrap_err();
        assert!(e.contains("cannot hold"), "{e}");
    }

    #[test]
    fn a_damaged_part_is_refused_never_a_panic() {
        // Every byte of a small version-2 part flipped, with the checksum made right again
        // (so the header's and the deflate stream's checks are what meets it), and every
        // truncation: each parses or is refused with a message.
        let header = header(3, 2);
        let n = words_of(&header);
        let part = Part {
            header,
            even: (0..n as u32).collect(),
            odd: (0..n as u32).map(|i| i * 7).collect(),
        };
        let good = encode(&part, 2);
        for at in 8..good.len() - 4 {
            for bit in [0x01u8, 0x80] {
                let mut bytes = good.clone();
                bytes[at] ^= bit;
                let body = bytes.len() - 4;
                let crc = crc32fast::hash(&bytes[..body]);
                bytes[body..].copy_from_slice(&crc.to_le_bytes());
                let _ = parse(&bytes);
            }
        }
        for len in 0..good.len() {
            assert!(parse(&good[..len]).is_err(), "cut at {len}");
        }
    }
}
