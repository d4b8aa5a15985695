//! The WGSL sources, compiled into the binary: the GPU tracer's program, and the text both
//! tracers' tests read the shared constants from.

/// Every WGSL file under `shaders/`, by its path relative to that folder.
pub const SOURCES: &[(&str, &str)] = &[
    ("trace.wgsl", include_str!("../../shaders/trace.wgsl")),
    ("probe.wgsl", include_str!("../../shaders/probe.wgsl")),
    (
        "pbr_probe.wgsl",
        include_str!("../../shaders/pbr_probe.wgsl"),
    ),
    ("reduce.wgsl", include_str!("../../shaders/reduce.wgsl")),
    ("resolve.wgsl", include_str!("../../shaders/resolve.wgsl")),
    ("denoise.wgsl", include_str!("../../shaders/denoise.wgsl")),
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
    (
        "common/texture.wgsl",
        include_str!("../../shaders/common/texture.wgsl"),
    ),
    (
        "common/envmap.wgsl",
        include_str!("../../shaders/common/envmap.wgsl"),
    ),
    (
        "common/estimate.wgsl",
        include_str!("../../shaders/common/estimate.wgsl"),
    ),
    (
        "common/mirror.wgsl",
        include_str!("../../shaders/common/mirror.wgsl"),
    ),
    (
        "common/lens.wgsl",
        include_str!("../../shaders/common/lens.wgsl"),
    ),
    (
        "common/pbr.wgsl",
        include_str!("../../shaders/common/pbr.wgsl"),
    ),
];

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
