//! `termtrace merge`: the shards of a render (`render --shard I/K`, `.tta` files) into its
//! image, bit for bit the image one device would have made; parts missing, given twice, from
//! another render or corrupted are refused by name, and nothing is written.

use super::args::ImageArgs;
use crate::common::AccumData;
use crate::common::accum::decode;
use crate::output::{ImageFile, check_writable, write_exr, write_png};
use crate::render::Snapshot;
use crate::render::shard::{self, Part};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The parts (`.tta` files from `render --shard`), in any order.
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,
    /// The image: a PNG, linear OpenEXR (`.exr`), or the merged exact sums (`.tta`).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    #[command(flatten)]
    pub image: ImageArgs,
}

/// The image of merged sums, decoded as a render's snapshot is.
pub fn image_of(whole: &Part) -> crate::output::LinearImage {
    let h = &whole.header;
    Snapshot {
        width: h.width,
        height: h.height,
        data: AccumData {
            invalid: h.invalid,
            ..AccumData::from_halves(decode(&whole.even), decode(&whole.odd))
        },
        samples: h.spp,
    }
    .image()
}

pub fn run(a: MergeArgs) -> anyhow::Result<ExitCode> {
    let start = std::time::Instant::now();
    let kind = if shard::is_part_file(&a.output) {
        None
    } else {
        Some(ImageFile::of(&a.output)?)
    };
    check_writable(&a.output)?;
    a.image.check(&a.output, kind.unwrap_or(ImageFile::Png))?;
    let mut parts = Vec::with_capacity(a.parts.len());
    let mut errors = Vec::new();
    let mut bytes = 0u64;
    // Read (and inflated) on every core, in the order given.
    use rayon::prelude::*;
    let read: Vec<_> = a.parts.par_iter().map(|p| (p, shard::read(p))).collect();
    for (p, r) in read {
        match r {
            Ok(part) => {
                bytes += std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
                parts.push((p.clone(), part));
            }
            Err(e) => errors.push(e),
        }
    }
    if !errors.is_empty() {
        let all: Vec<String> = errors.iter().map(ToString::to_string).collect();
        anyhow::bail!("{}; nothing written", all.join("\n"));
    }
    let whole = shard::merge(&parts).map_err(|e| anyhow::anyhow!("{e}; nothing written"))?;
    let h = &whole.header;
    // Decoded once, where an image is written.
    let image = (kind.is_some() || a.image.exr.is_some()).then(|| image_of(&whole));
    match (kind, &image) {
        (Some(ImageFile::Png), Some(img)) => {
            write_png(&a.output, img, a.image.transfer, a.image.png16)?
        }
        (Some(ImageFile::Exr), Some(img)) => write_exr(&a.output, img)?,
        _ => shard::write(&a.output, &whole)?,
    }
    if let (Some(exr), Some(img)) = (&a.image.exr, &image) {
        write_exr(exr, img)?;
    }
    eprintln!(
        "wrote {} from {} parts of {} ({}x{}, {} spp, {} invalid samples; {:.1} MiB read, {:.2} s)",
        a.output.display(),
        parts.len(),
        h.scene,
        h.width,
        h.height,
        h.spp,
        h.invalid,
        bytes as f64 / (1 << 20) as f64,
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
