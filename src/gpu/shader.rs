//! WGSL sources, compiled into the binary, and the `// #include "path"` resolver that
//! assembles one module from a file and the shared files it names (`shaders/common/`).
//! For shader work without rebuilding, `TERMTRACE_SHADER_DIR=shaders` reads the files from
//! that folder instead (any file it lacks comes from the binary).

use std::borrow::Cow;

/// Every WGSL file under `shaders/`, by its path relative to that folder.
pub const SOURCES: &[(&str, &str)] = &[
    ("trace.wgsl", include_str!("../../shaders/trace.wgsl")),
    ("probe.wgsl", include_str!("../../shaders/probe.wgsl")),
    ("reduce.wgsl", include_str!("../../shaders/reduce.wgsl")),
    ("resolve.wgsl", include_str!("../../shaders/resolve.wgsl")),
    (
        "common/fixed.wgsl",
        include_str!("../../shaders/common/fixed.wgsl"),
    ),
    (
        "common/types.wgsl",
        include_str!("../../shaders/common/types.wgsl"),
    ),
    (
        "common/rng.wgsl",
        include_str!("../../shaders/common/rng.wgsl"),
    ),
    (
        "common/sampling.wgsl",
        include_str!("../../shaders/common/sampling.wgsl"),
    ),
    (
        "common/intersect.wgsl",
        include_str!("../../shaders/common/intersect.wgsl"),
    ),
    (
        "common/material.wgsl",
        include_str!("../../shaders/common/material.wgsl"),
    ),
];

const INCLUDE: &str = "// #include \"";

/// The source of one file compiled into the binary, by path relative to `shaders/`.
pub fn source(name: &str) -> Option<&'static str> {
    SOURCES.iter().find(|(n, _)| *n == name).map(|(_, s)| *s)
}

/// The value of `const NAME: u32 = …;` (decimal or 0x hex) declared at the start of a line of
/// a compiled-in file: the tests that tie a WGSL constant to its Rust twin read it here.
#[cfg(test)]
pub fn u32_constant(file: &str, name: &str) -> u32 {
    let src = source(file).unwrap_or_else(|| panic!("no shader {file}"));
    let head = format!("const {name}: u32 = ");
    let line = src
        .lines()
        .find(|l| l.starts_with(&head))
        .unwrap_or_else(|| panic!("{file} declares {name}"));
    let v = line[head.len()..]
        .trim_end_matches(';')
        .trim_end_matches('u');
    match v.strip_prefix("0x") {
        Some(hex) => u32::from_str_radix(hex, 16).unwrap(),
        None => v.parse().unwrap(),
    }
}

/// The source the tracer uses: from `TERMTRACE_SHADER_DIR` when it is set and has the file,
/// else compiled in.
fn current_source(name: &str) -> Option<Cow<'static, str>> {
    if let Some(dir) = std::env::var_os("TERMTRACE_SHADER_DIR") {
        let path = std::path::Path::new(&dir).join(name);
        if let Ok(text) = std::fs::read_to_string(&path) {
            tracing::info!("shader {name} read from {}", path.display());
            return Some(Cow::Owned(text));
        }
    }
    source(name).map(Cow::Borrowed)
}

/// `name` with every file it includes (transitively) placed before it, each once.
pub fn assemble(name: &str) -> Result<String, String> {
    let mut done = Vec::new();
    let mut out = String::new();
    visit(name, &mut done, &mut Vec::new(), &mut out)?;
    Ok(out)
}

fn visit(
    name: &str,
    done: &mut Vec<String>,
    stack: &mut Vec<String>,
    out: &mut String,
) -> Result<(), String> {
    if done.iter().any(|d| d == name) {
        return Ok(());
    }
    if stack.iter().any(|d| d == name) {
        return Err(format!("include cycle: {} -> {name}", stack.join(" -> ")));
    }
    let src = current_source(name).ok_or_else(|| {
        let from = stack
            .last()
            .map_or(String::new(), |s| format!(" (included from {s})"));
        format!("no shader file `{name}`{from}")
    })?;
    stack.push(name.to_string());
    for line in src.lines() {
        if let Some(rest) = line.trim().strip_prefix(INCLUDE) {
            let inc = rest.trim_end_matches('"');
            visit(inc, done, stack, out)?;
        }
    }
    stack.pop();
    out.push_str(&format!("// ---- {name} ----\n{src}\n"));
    done.push(name.to_string());
    Ok(())
}
