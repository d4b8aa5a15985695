//! `termtrace merge`: the shards of a render (`render --shard I/K`, `.tta` files) into its
//! image, bit for bit the image one device would have made; parts missing, given twice, from
//! another render or corrupted are refused by name, and nothing is written.

use crate::common::AccumData;
use crate::common::accum::decode;
use crate::output::{ImageFile, Transfer, check_writable, write_exr, write_png};
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
    /// Also write the linear radiance as OpenEXR.
    #[arg(long, value_name = "EXR")]
    pub exr: Option<PathBuf>,
    /// Write a 16-bit PNG.
    #[arg(long)]
    pub png16: bool,
    /// Transfer function of the PNG.
    #[arg(long, value_enum, default_value_t = Transfer::Srgb)]
    pub transfer: Transfer,
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
    let tta = a
        .output
        .extension()
        .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("tta"));
    let kind = if tta {
        None
    } else {
        Some(ImageFile::of(&a.output)?)
    };
    check_writable(&a.output)?;
    if let Some(exr) = &a.exr {
        anyhow::ensure!(
            ImageFile::of(exr)? == ImageFile::Exr,
            "--exr {}: the OpenEXR file's name must end in .exr",
            exr.display()
        );
        check_writable(exr)?;
    }
    let mut parts = Vec::with_capacity(a.parts.len());
    let mut errors = Vec::new();
    let mut bytes = 0u64;
    for p in &a.parts {
        match shard::read(p) {
            Ok(part) => {
                bytes += std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
                parts.push((p.clone(), part));
            }
            Err(e) => errors.push(e),
        }
    }
    if !errors.is_empty() {
        anyhow::bail!("{}; nothing written", errors.join("\n"));
    }
    let whole = shard::merge(&parts).map_err(|e| anyhow::anyhow!("{e}; nothing written"))?;
    let h = &whole.header;
    match kind {
        None => shard::write(&a.output, &whole)?,
        Some(ImageFile::Png) => write_png(&a.output, &image_of(&whole), a.transfer, a.png16)?,
        Some(ImageFile::Exr) => write_exr(&a.output, &image_of(&whole))?,
    }
    if let Some(exr) = &a.exr {
        write_exr(exr, &image_of(&whole))?;
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
