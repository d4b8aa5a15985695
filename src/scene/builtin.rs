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
];

/// The text of a built-in scene, by name.
pub fn builtin_source(name: &str) -> Option<&'static str> {
    BUILTIN_SCENES
        .iter()
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
