//! `termtrace adapters`: the GPU adapters of this machine, best first, and the native CPU
//! tracer (chosen when the best adapter is a software one, or when there is none).

use crate::gpu::{describe, list_adapters};
use std::process::ExitCode;

pub fn run() -> anyhow::Result<ExitCode> {
    let all = list_adapters();
    let gpu_first = all
        .first()
        .is_some_and(|(i, bad)| bad.is_none() && i.device_type != wgpu::DeviceType::Cpu);
    if all.is_empty() {
        println!("No GPU adapters found.");
    }
    for (i, (info, bad)) in all.iter().enumerate() {
        let mark = if i == 0 && gpu_first { "*" } else { " " };
        print!("{mark} [{i}] {}", describe(info));
        if let Some(b) = bad {
            print!("  (unusable: {b})");
        }
        println!();
    }
    let mark = if gpu_first { " " } else { "*" };
    println!(
        "{mark} [{}] {}",
        crate::cpu::ADAPTER_NAME,
        crate::cpu::describe()
    );
    println!(
        "\n* = chosen by default (a GPU where there is one; else the native CPU tracer, which is \
         faster than Mesa's software adapters). Select another with --adapter NAME or \
         TERMTRACE_ADAPTER (`--adapter cpu-native`, `--adapter llvmpipe`, …). `view`, `render`, \
         `bench` and `converge` also share one render among several: `--adapter all` (every hardware \
         GPU) or a list (`--adapter 0,1`)."
    );
    Ok(ExitCode::SUCCESS)
}
