//! The two tracers' twin files name each other in their first lines, and keep their functions
//! paired: a function added to a WGSL file and not to its Rust twin (or the reverse) fails
//! here, unless it is listed below as one-sided, with the reason. A listed name that no longer
//! stands on its side alone fails too, so the lists cannot go stale.

use std::collections::BTreeSet;

struct Twin {
    wgsl: &'static str,
    rust: &'static str,
    /// The prefix WGSL puts on the names (it has no modules): `env_sample` ↔ `sample`.
    prefix: &'static str,
    /// Functions only the WGSL file has, and why.
    wgsl_only: &'static [&'static str],
    /// Functions only the Rust file has.
    rust_only: &'static [&'static str],
}

const TWINS: &[Twin] = &[
    Twin {
        wgsl: "shaders/common/envmap.wgsl",
        rust: "src/scene/envmap_sampling.rs",
        prefix: "env_",
        // The GPU reads the map's words (`common::envmap`); the host holds typed arrays.
        // `invert`: the GPU searches a CDF whole; the host through guide tables (`guide`,
        // `buckets`, `invert_guided`), which find the same interval (tested against the
        // whole search). `floor`: the host's without a libm call (the GPU's is an
        // instruction); `direction_and_sin`: the host's sample keeps sin θ from the direction.
        wgsl_only: &[
            "cdf", "density", "height", "invert", "lookup", "texel", "width",
        ],
        rust_only: &[
            "bilinear",
            // The host builds the distribution (`new`, `build`: MIS-compensated or not) and
            // the GPU reads what it built.
            "build",
            "buckets",
            "bytes",
            "density_uv",
            "direction_and_sin",
            "floor",
            "guide",
            // The CPU's lanes gather from the guide tables.
            "guides",
            "invert_guided",
            "new",
            // The CPU's lanes ask the cache for every lane's texels before reading any.
            "prefetch",
            "rgbe_pack",
            "rgbe_unpack",
            "row",
            "search",
        ],
    },
    Twin {
        wgsl: "shaders/common/mirror.wgsl",
        rust: "src/cpu/mirror.rs",
        prefix: "mirror_",
        wgsl_only: &[],
        rust_only: &[],
    },
    Twin {
        wgsl: "shaders/common/lens.wgsl",
        rust: "src/cpu/lens.rs",
        prefix: "lens_",
        wgsl_only: &[],
        rust_only: &[],
    },
    Twin {
        wgsl: "shaders/common/fixed.wgsl",
        rust: "src/cpu/fixed.rs",
        prefix: "fixed_",
        // WGSL passes values; the host's type has methods over the words. `mean`: a half's
        // mean for the passes that read the accumulation (resolve, denoise); the host's is
        // `common::estimate::half_mean`, over decoded sums. The host's `add` is `words` then
        // `add_words` (`fixed_add` in two), so that the CPU's lanes make the words in vector
        // lanes (`cpu::lanes`).
        wgsl_only: &["from_words", "to_words", "value", "zero", "mean"],
        rust_only: &["load", "store", "words", "add_words"],
    },
    Twin {
        wgsl: "shaders/common/intersect.wgsl",
        rust: "src/cpu/intersect.rs",
        prefix: "",
        wgsl_only: &[],
        // WGSL has `sign` built in.
        rust_only: &["sign"],
    },
    Twin {
        wgsl: "shaders/common/material.wgsl",
        rust: "src/cpu/material.rs",
        prefix: "",
        wgsl_only: &[],
        // WGSL has `reflect` built in.
        rust_only: &["reflect"],
    },
    Twin {
        wgsl: "shaders/common/pbr.wgsl",
        rust: "src/cpu/pbr.rs",
        prefix: "pbr_",
        wgsl_only: &[],
        // WGSL has `reflect` built in.
        rust_only: &["reflect"],
    },
    Twin {
        wgsl: "shaders/common/rng.wgsl",
        rust: "src/cpu/rng.rs",
        prefix: "rng_",
        // The host also draws points ahead, in AVX lanes (`group*`, `next_point`; AVX-512
        // where the CPU has it, `has_avx512`), and resumes a sampler where a path in lanes
        // left it, for the lanes' tests (`resumed`).
        wgsl_only: &["init", "seed_mix", "slot", "unit_float"],
        rust_only: &[
            "group",
            "group_avx2",
            "group_avx512",
            "group_lanes",
            "has_avx512",
            "mix",
            "new",
            "next_point",
            "resumed",
            "root",
            "sample_index",
            "shuffle",
            "slot_point",
            "taken",
            "unit",
        ],
    },
    Twin {
        wgsl: "shaders/common/sampling.wgsl",
        rust: "src/cpu/sampling.rs",
        prefix: "",
        wgsl_only: &[],
        // (WGSL's sin and cos are the GPU's; the host's turn-based pair is `common::trig`'s.)
        rust_only: &[],
    },
    Twin {
        wgsl: "shaders/common/texture.wgsl",
        rust: "src/cpu/texture.rs",
        prefix: "tex_",
        // The GPU reads typed words one by one; the host decodes them into arrays.
        wgsl_only: &["f32", "texel", "vec3"],
        rust_only: &["decode", "f", "may_emit", "wrapped"],
    },
    Twin {
        wgsl: "shaders/trace.wgsl",
        rust: "src/cpu/trace.rs",
        prefix: "",
        // The GPU's wavefront (a path in flight per invocation, lanes' sums in scratch) and
        // the host's recursive walk differ in their plumbing, not in the model.
        wgsl_only: &[
            "add_u64",
            // A surface of its primitive's own coordinates; an instance's walk kept out of
            // the primitive test (the host's `hit_primitive` holds both).
            "hit_ref",
            "count_tests",
            "count_visit",
            // The cosine lobe as light sampling weighs it: the host's `Weighed::Cosine`, an
            // enum's variant where WGSL has a struct.
            "cosine_lobe",
            "fixed_load",
            "fixed_store",
            "guide_of",
            "guide_quantize",
            "guides",
            "intersect_all",
            "intersect_scene",
            "not_finite",
            "path_start",
            "path_step",
            "pop_slot",
            "scratch_store",
            "slabs",
            "slot_bits",
            "surface_in_place",
            "trace",
        ],
        rust_only: &[
            "all_refs",
            // `occluded`'s primitive test, shared by the host's four walks (WGSL's one walk
            // tests in place).
            "blocks",
            "camera_hits",
            "hit_except",
            "intersect",
            "leaving",
            "new",
            // The CPU lanes' shadow rays, walked on from the root they visited together (the
            // GPU walks one invocation's ray from its root).
            "occluded_below_root",
            "trace_path",
            "walk_closest",
        ],
    },
];

fn read(path: &str) -> String {
    std::fs::read_to_string(format!("{}/{path}", env!("CARGO_MANIFEST_DIR")))
        .unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The comment lines a file starts with (WGSL's `#include` lines among them).
fn header(text: &str) -> String {
    text.lines()
        .take_while(|l| l.starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Names of the functions a file defines, outside its tests.
fn functions(text: &str, prefix: &str) -> BTreeSet<String> {
    let code = text.split("#[cfg(test)]").next().unwrap_or(text);
    let mut names = BTreeSet::new();
    for line in code.lines() {
        let mut words = line.split_whitespace().peekable();
        while let Some(w) = words.next() {
            if w == "fn"
                && let Some(next) = words.peek()
            {
                let name: String = next
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    names.insert(name.strip_prefix(prefix).unwrap_or(&name).to_string());
                }
                break;
            }
            if !matches!(
                w,
                "pub" | "pub(crate)" | "pub(super)" | "const" | "unsafe" | "#[inline]"
            ) {
                break;
            }
        }
    }
    names
}

#[test]
fn twins_name_each_other() {
    for t in TWINS {
        let (w, r) = (read(t.wgsl), read(t.rust));
        assert!(
            header(&w).contains(t.rust),
            "{}'s first lines do not name its twin {}",
            t.wgsl,
            t.rust
        );
        assert!(
            header(&r).contains(t.wgsl),
            "{}'s first lines do not name its twin {}",
            t.rust,
            t.wgsl
        );
    }
}

#[test]
fn twins_define_the_same_functions() {
    let mut problems = Vec::new();
    for t in TWINS {
        let w = functions(&read(t.wgsl), t.prefix);
        let r = functions(&read(t.rust), "");
        assert!(
            w.len() > 2 && !r.is_empty(),
            "{} / {}: the reader found too little",
            t.wgsl,
            t.rust
        );
        for (side, ours, theirs, listed, file) in [
            ("WGSL", &w, &r, t.wgsl_only, t.wgsl),
            ("Rust", &r, &w, t.rust_only, t.rust),
        ] {
            for f in ours.difference(theirs) {
                if !listed.contains(&f.as_str()) {
                    problems.push(format!(
                        "{file} defines `{f}` and its twin does not (add it there, or list it \
                         as {side}-only with the reason)"
                    ));
                }
            }
            for f in listed {
                if !ours.contains(*f) || theirs.contains(*f) {
                    problems.push(format!(
                        "{file}: `{f}` is listed as {side}-only, and is not"
                    ));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The reader sees functions with their qualifiers, and strips a prefix.
#[test]
fn the_reader_finds_functions() {
    let text = "fn tex_a() {}\npub(crate) fn b() {}\n    pub const fn c() {}\nlet fnord = 1;\n\
                #[cfg(test)]\nmod tests { fn d() {} }";
    let names: Vec<String> = functions(text, "tex_").into_iter().collect();
    assert_eq!(names, ["a", "b", "c"]);
}
