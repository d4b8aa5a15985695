//! The scenes shipped in `scenes/`, compiled into the binary so that every command can name
//! them (`termtrace render weekend`) from any directory.

/// The scene the preview opens when none is given.
pub const DEFAULT_SCENE: &str = "showcase";

/// `(name, TOML text)` of every shipped scene.
pub const BUILTIN_SCENES: &[(&str, &str)] = &[
    ("showcase", include_str!("../../scenes/showcase.toml")),
    ("basic", include_str!("../../scenes/basic.toml")),
    ("metal", include_str!("../../scenes/metal.toml")),
    ("fuzz", include_str!("../../scenes/fuzz.toml")),
    ("specular", include_str!("../../scenes/specular.toml")),
    ("emissive", include_str!("../../scenes/emissive.toml")),
    ("dielectric", include_str!("../../scenes/dielectric.toml")),
    ("spheres", include_str!("../../scenes/spheres.toml")),
    ("dof", include_str!("../../scenes/dof.toml")),
    ("cornell", include_str!("../../scenes/cornell.toml")),
    ("weekend", include_str!("../../scenes/weekend.toml")),
    ("mesh", include_str!("../../scenes/mesh.toml")),
    ("lamp", include_str!("../../scenes/lamp.toml")),
    ("outdoor", include_str!("../../scenes/outdoor.toml")),
    (
        "outdoor-caustics",
        include_str!("../../scenes/outdoor-caustics.toml"),
    ),
    ("pbr", include_str!("../../scenes/pbr.toml")),
    ("glass", include_str!("../../scenes/glass.toml")),
];

/// The extreme scenes of `scenes/extreme/` (numerical stability; `check --stress`).
pub const EXTREME_SCENES: &[(&str, &str)] = &[
    (
        "extreme/bounces_0",
        include_str!("../../scenes/extreme/bounces_0.toml"),
    ),
    (
        "extreme/bounces_1",
        include_str!("../../scenes/extreme/bounces_1.toml"),
    ),
    (
        "extreme/bounces_1000",
        include_str!("../../scenes/extreme/bounces_1000.toml"),
    ),
    (
        "extreme/coincident",
        include_str!("../../scenes/extreme/coincident.toml"),
    ),
    (
        "extreme/far_camera",
        include_str!("../../scenes/extreme/far_camera.toml"),
    ),
    (
        "extreme/firefly",
        include_str!("../../scenes/extreme/firefly.toml"),
    ),
    (
        "extreme/fuzz_1",
        include_str!("../../scenes/extreme/fuzz_1.toml"),
    ),
    (
        "extreme/glass_iors",
        include_str!("../../scenes/extreme/glass_iors.toml"),
    ),
    (
        "extreme/grazing",
        include_str!("../../scenes/extreme/grazing.toml"),
    ),
    (
        "extreme/ground_1e3",
        include_str!("../../scenes/extreme/ground_1e3.toml"),
    ),
    (
        "extreme/ground_1e5",
        include_str!("../../scenes/extreme/ground_1e5.toml"),
    ),
    (
        "extreme/ground_1e6",
        include_str!("../../scenes/extreme/ground_1e6.toml"),
    ),
    (
        "extreme/hollow",
        include_str!("../../scenes/extreme/hollow.toml"),
    ),
    (
        "extreme/inside_diffuse",
        include_str!("../../scenes/extreme/inside_diffuse.toml"),
    ),
    (
        "extreme/inside_glass",
        include_str!("../../scenes/extreme/inside_glass.toml"),
    ),
    (
        "extreme/tiny_spheres",
        include_str!("../../scenes/extreme/tiny_spheres.toml"),
    ),
    (
        "extreme/tir_trap",
        include_str!("../../scenes/extreme/tir_trap.toml"),
    ),
    (
        "extreme/translated_1e4",
        include_str!("../../scenes/extreme/translated_1e4.toml"),
    ),
];

/// The text of a built-in scene, by name (`weekend`, `extreme/ground_1e6`).
pub fn builtin_source(name: &str) -> Option<&'static str> {
    BUILTIN_SCENES
        .iter()
        .chain(EXTREME_SCENES)
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

/// Files that built-in scenes refer to (meshes), by their path relative to `scenes/`.
pub const BUILTIN_FILES: &[(&str, &str)] = &[
    (
        "meshes/torus.obj",
        include_str!("../../scenes/meshes/torus.obj"),
    ),
    (
        "meshes/icosphere.obj",
        include_str!("../../scenes/meshes/icosphere.obj"),
    ),
];

/// The environment maps the shipped scenes name, by their path relative to `scenes/`
/// (scenes/maps/SOURCE.md says where each comes from).
pub const BUILTIN_MAPS: &[(&str, &[u8])] = &[(
    "maps/quarry_01_1k.hdr",
    include_bytes!("../../scenes/maps/quarry_01_1k.hdr"),
)];
