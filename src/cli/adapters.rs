//! `termtrace adapters`: the GPU adapters of this machine, best first.

use crate::gpu::{describe, list_adapters};
use std::process::ExitCode;

pub fn run() -> anyhow::Result<ExitCode> {
    let all = list_adapters();
    if all.is_empty() {
        println!("No GPU adapters found.");
        println!(
            "Install Mesa's software adapters (`apt-get install mesa-vulkan-drivers`) or a GPU driver."
        );
        return Ok(ExitCode::FAILURE);
    }
    for (i, (info, bad)) in all.iter().enumerate() {
        let mark = if i == 0 && bad.is_none() { "*" } else { " " };
        print!("{mark} [{i}] {}", describe(info));
        if let Some(b) = bad {
            print!("  (unusable: {b})");
        }
        println!();
    }
    println!("\n* = chosen by default. Select another with --adapter NAME or TERMTRACE_ADAPTER.");
    Ok(ExitCode::SUCCESS)
}
