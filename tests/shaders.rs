//! Every WGSL file parses and validates with naga (after its includes are resolved), every
//! file under shaders/ is compiled into the binary, and every Rust GPU mirror struct has the
//! size and field offsets naga computes for its WGSL twin.

use std::path::Path;
use termtrace::common::{layout, wgsl};
use termtrace::gpu::shader;

fn validate(name: &str) -> naga::Module {
    let src = shader::assemble(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{name} does not parse:\n{}", e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name} does not validate:\n{}", e.emit_to_string(&src)));
    module
}

fn wgsl_files(dir: &Path, prefix: &str, out: &mut Vec<String>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        if e.path().is_dir() {
            wgsl_files(&e.path(), &format!("{prefix}{name}/"), out);
        } else if name.ends_with(".wgsl") {
            out.push(format!("{prefix}{name}"));
        }
    }
}

#[test]
fn every_wgsl_file_is_embedded_and_validates() {
    let mut files = Vec::new();
    wgsl_files(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders")),
        "",
        &mut files,
    );
    assert!(files.len() >= 5, "found only {files:?}");
    for f in &files {
        let on_disk = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("shaders")
                .join(f),
        )
        .unwrap();
        assert_eq!(
            wgsl::source(f),
            Some(on_disk.as_str()),
            "{f} is not in common::wgsl::SOURCES (or differs from the file)"
        );
        validate(f);
    }
    assert_eq!(
        files.len(),
        wgsl::SOURCES.len(),
        "SOURCES lists a file that is not on disk"
    );
}

#[test]
fn include_errors_are_reported() {
    assert!(
        shader::assemble("nope.wgsl")
            .unwrap_err()
            .to_string()
            .contains("nope.wgsl")
    );
}

#[test]
fn mirrors_match_wgsl_layout() {
    let module = validate("trace.wgsl");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    for (wgsl, size, fields) in layout::mirrors() {
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(wgsl))
            .unwrap_or_else(|| panic!("no struct {wgsl} in trace.wgsl"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{wgsl} is not a struct");
        };
        assert_eq!(*span as usize, size, "size of {wgsl}");
        assert_eq!(
            layouter[handle].size as usize, size,
            "layout size of {wgsl}"
        );
        for &(field, offset) in &fields {
            let m = members
                .iter()
                .find(|m| m.name.as_deref() == Some(field))
                .unwrap_or_else(|| panic!("{wgsl} has no field {field}"));
            assert_eq!(m.offset as usize, offset, "offset of {wgsl}.{field}");
        }
        let named = members
            .iter()
            .filter(|m| !m.name.as_deref().unwrap_or("").starts_with('_'));
        assert_eq!(
            named.count(),
            fields.len(),
            "{wgsl}: the WGSL struct has fields the Rust mirror test does not list"
        );
    }
}
