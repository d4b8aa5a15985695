//! The house's shape, read from the source: the modules' `use` lines (and paths written in
//! code) form no circle, and the two tracers stand side by side on the backend-neutral
//! `common` module: `src/cpu` imports nothing from `src/gpu`, nor `gpu` from `cpu`.
//!
//! Each file under `src/` is a module (`src/cpu/bvh.rs` is `cpu::bvh`, `src/cpu/mod.rs` is
//! `cpu`). An edge goes from a module to each module a path in it names (`use` trees,
//! `crate::…`, `super::…`, `self::…`, and paths through a name a `use` or `mod` line brought
//! in), resolved to the longest prefix that is a module file; a name a `mod.rs` re-exports
//! (`pub use child::Name`) resolves to the child that defines it, and the re-export line
//! itself is no edge. Items under `#[cfg(test)]` (or `all(test, …)`) are left out: a test may
//! use anything.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path, `["cpu", "bvh"]`; the crate root is `[]`.
type ModPath = Vec<String>;

struct Module {
    file: PathBuf,
    /// The code with comments, strings and test modules removed.
    code: String,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

fn module_path(src: &Path, file: &Path) -> Option<ModPath> {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    match last.as_str() {
        "lib.rs" if parts.is_empty() => Some(parts),
        "main.rs" if parts.is_empty() => None, // the binary: a client of the library
        "mod.rs" => Some(parts),
        name => {
            parts.push(name.trim_end_matches(".rs").to_string());
            Some(parts)
        }
    }
}

/// `src` without comments, string and char literals (blanked, so positions keep their
/// meaning), and without `#[cfg(test)]` items.
fn strip(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let end = src[i + 2..].find("*/").map_or(b.len(), |e| i + 2 + e + 2);
            i = end;
        } else if b[i] == b'r' && (b[i + 1..].starts_with(b"\"") || b[i + 1..].starts_with(b"#")) {
            // A raw string r"…" or r#"…"#.
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            if b.get(i + 1 + hashes) == Some(&b'"') {
                let close = format!("\"{}", "#".repeat(hashes));
                let start = i + 2 + hashes;
                i = src[start..]
                    .find(&close)
                    .map_or(b.len(), |e| start + e + close.len());
                out.push_str("\"\"");
            } else {
                out.push('r');
                i += 1;
            }
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && i + 2 < b.len() && (b[i + 2] == b'\'' || b[i + 1] == b'\\') {
            // A char literal ('x', '\n', '\u{..}'), not a lifetime.
            i += 1;
            while i < b.len() && b[i] != b'\'' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("' '");
        } else {
            let c = src[i..].chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    remove_test_items(&out)
}

/// Removes each item that follows `#[cfg(test)]`: to the end of its `{…}` block or its `;`
/// (a field or a struct literal's member: to its `,`, or to the `}` that closes what holds
/// it).
fn remove_test_items(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(at) = ["#[cfg(test)]", "#[cfg(all(test,"]
        .iter()
        .filter_map(|a| rest.find(a))
        .min()
    {
        out.push_str(&rest[..at]);
        // The item starts after the attribute's closing `]` (its own commas are not the end).
        let mut brackets = 0usize;
        let close = rest[at..]
            .char_indices()
            .find(|&(_, c)| {
                match c {
                    '[' => brackets += 1,
                    ']' => brackets -= 1,
                    _ => {}
                }
                c == ']' && brackets == 0
            })
            .map_or(rest.len() - at, |(k, _)| k + 1);
        let after = &rest[at + close..];
        let mut depth = 0usize;
        // Parentheses and brackets open (a parameter list's commas are not the end).
        let mut parens = 0usize;
        let mut end = after.len();
        for (k, c) in after.char_indices() {
            match c {
                '(' | '[' => parens += 1,
                ')' | ']' => parens = parens.saturating_sub(1),
                '{' => depth += 1,
                '}' if depth == 0 => {
                    end = k;
                    break;
                }
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = k + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = k + 1;
                    break;
                }
                ',' if depth == 0 && parens == 0 => {
                    end = k + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The paths of a use tree (`a::{b, c::{d as e}, self}`), each with the name it binds.
fn expand_use_tree(tree: &str, prefix: &[String], out: &mut Vec<(Vec<String>, String)>) {
    let tree = tree.trim();
    if tree.is_empty() {
        return;
    }
    if let Some(open) = tree.find('{') {
        let head: Vec<String> = tree[..open]
            .split("::")
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect();
        let mut base = prefix.to_vec();
        base.extend(head);
        let close = tree
            .rfind('}')
            .unwrap_or_else(|| panic!("a use tree without its end: {tree}"));
        let inner = &tree[open + 1..close];
        let mut depth = 0;
        let mut start = 0;
        for (k, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand_use_tree(&inner[start..k], &base, out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        expand_use_tree(&inner[start..], &base, out);
    } else {
        let (path, alias) = match tree.split_once(" as ") {
            Some((p, a)) => (p, Some(a.trim().to_string())),
            None => (tree, None),
        };
        let mut full = prefix.to_vec();
        full.extend(path.split("::").map(|s| s.trim().to_string()));
        if full.last().is_some_and(|s| s == "self") {
            full.pop();
        }
        let name = alias.unwrap_or_else(|| full.last().cloned().unwrap_or_default());
        out.push((full, name));
    }
}

/// Every `use` item of the code: (is `pub`, its text after `use`), with the text removed
/// from the code that is returned.
fn use_items(code: &str) -> (Vec<(bool, String)>, String) {
    let mut uses = Vec::new();
    let mut rest_code = String::new();
    let mut rest = code;
    loop {
        let Some(at) = find_word(rest, "use") else {
            rest_code.push_str(rest);
            break;
        };
        if rest[at + 3..].trim_start().starts_with('<') {
            // `impl Trait + use<'a>`: a capture list, not an import.
            rest_code.push_str(&rest[..at + 3]);
            rest = &rest[at + 3..];
            continue;
        }
        let before = rest[..at].trim_end();
        let public = before.ends_with("pub") || before.ends_with(')');
        let end = at + rest[at..].find(';').unwrap();
        uses.push((public, rest[at + 3..end].trim().to_string()));
        rest_code.push_str(&rest[..at]);
        rest = &rest[end + 1..];
    }
    (uses, rest_code)
}

/// The byte offset of `word` standing alone (not part of an identifier).
fn find_word(s: &str, word: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(k) = s[from..].find(word) {
        let at = from + k;
        let before_ok = s[..at].chars().next_back().is_none_or(|c| !is_ident(c));
        let after_ok = s[at + word.len()..]
            .chars()
            .next()
            .is_none_or(|c| !is_ident(c));
        if before_ok && after_ok {
            return Some(at);
        }
        from = at + word.len();
    }
    None
}

/// Paths written in code: `a::b::c` sequences of identifiers (generic arguments ignored).
fn code_paths(code: &str) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    let chars: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        if is_ident(chars[i]) && (i == 0 || !(is_ident(chars[i - 1]) || chars[i - 1] == ':')) {
            let mut segs = Vec::new();
            let mut j = i;
            loop {
                let s = j;
                while j < chars.len() && is_ident(chars[j]) {
                    j += 1;
                }
                segs.push(chars[s..j].iter().collect::<String>());
                if chars.get(j) == Some(&':')
                    && chars.get(j + 1) == Some(&':')
                    && chars.get(j + 2).is_some_and(|&c| is_ident(c))
                {
                    j += 2;
                } else {
                    break;
                }
            }
            if segs.len() > 1 {
                paths.push(segs);
            }
            i = j;
        } else {
            i += 1;
        }
    }
    paths
}

struct Crate {
    modules: BTreeMap<ModPath, Module>,
    /// For each module, the names its `pub use` lines re-export, with the path they name.
    reexports: BTreeMap<ModPath, BTreeMap<String, Vec<String>>>,
}

impl Crate {
    fn read(src: &Path) -> Crate {
        let mut files = Vec::new();
        rust_files(src, &mut files);
        let mut modules = BTreeMap::new();
        for file in files {
            if let Some(path) = module_path(src, &file) {
                let code = strip(&std::fs::read_to_string(&file).unwrap());
                modules.insert(path, Module { file, code });
            }
        }
        let mut reexports = BTreeMap::new();
        for (path, m) in &modules {
            let mut names = BTreeMap::new();
            for (public, tree) in use_items(&m.code).0 {
                if public {
                    let mut expanded = Vec::new();
                    expand_use_tree(&tree, &[], &mut expanded);
                    for (p, name) in expanded {
                        names.insert(name, p);
                    }
                }
            }
            reexports.insert(path.clone(), names);
        }
        Crate { modules, reexports }
    }

    /// Absolute segments of `path` as written in module `from` (`crate::`, `super::`,
    /// `self::`, or a child module's name), or `None` for an outside crate.
    fn absolute(&self, from: &ModPath, path: &[String]) -> Option<Vec<String>> {
        let mut base = from.clone();
        let mut segs = path;
        match segs.first()?.as_str() {
            "crate" => {
                base.clear();
                segs = &segs[1..];
            }
            "self" => segs = &segs[1..],
            "super" => {
                while segs.first().is_some_and(|s| s == "super") {
                    base.pop()?;
                    segs = &segs[1..];
                }
            }
            first => {
                let mut child = from.clone();
                child.push(first.to_string());
                if !self.modules.contains_key(&child) {
                    return None;
                }
            }
        }
        base.extend(segs.iter().cloned());
        Some(base)
    }

    /// The module an absolute path lands in: its longest module prefix, following a mod.rs's
    /// re-exports to the child module that defines the name.
    fn resolve(&self, abs: &[String], depth: usize) -> ModPath {
        let mut k = abs.len();
        while !self.modules.contains_key(&abs[..k]) {
            k -= 1;
        }
        let module = abs[..k].to_vec();
        if depth < 8
            && let Some(name) = abs.get(k)
            && let Some(target) = self.reexports[&module].get(name)
            && let Some(t) = self.absolute(&module, target)
        {
            return self.resolve(&t, depth + 1);
        }
        module
    }

    /// Each module's edges to the other modules it names.
    fn edges(&self) -> BTreeMap<ModPath, BTreeSet<ModPath>> {
        let mut graph = BTreeMap::new();
        for (from, m) in &self.modules {
            let (uses, code) = use_items(&m.code);
            let mut targets = BTreeSet::new();
            // Names a `use` line binds to a module, usable as a path's first segment.
            let mut aliases: BTreeMap<String, Vec<String>> = BTreeMap::new();
            for (public, tree) in uses {
                let mut expanded = Vec::new();
                expand_use_tree(&tree, &[], &mut expanded);
                for (p, name) in expanded {
                    let Some(abs) = self.absolute(from, &p) else {
                        continue;
                    };
                    if self.modules.contains_key(&abs) {
                        aliases.insert(name, abs.clone());
                    }
                    if !public {
                        targets.insert(self.resolve(&abs, 0));
                    }
                }
            }
            for p in code_paths(&code) {
                let abs = match aliases.get(&p[0]) {
                    Some(base) => {
                        let mut a = base.clone();
                        a.extend(p[1..].iter().cloned());
                        Some(a)
                    }
                    None => self.absolute(from, &p),
                };
                if let Some(abs) = abs {
                    targets.insert(self.resolve(&abs, 0));
                }
            }
            targets.remove(from);
            graph.insert(from.clone(), targets);
        }
        graph
    }
}

fn name(p: &ModPath) -> String {
    if p.is_empty() {
        "crate".into()
    } else {
        p.join("::")
    }
}

/// The strongly connected components of more than one module (Tarjan 1972).
fn circles(graph: &BTreeMap<ModPath, BTreeSet<ModPath>>) -> Vec<Vec<ModPath>> {
    struct State<'a> {
        graph: &'a BTreeMap<ModPath, BTreeSet<ModPath>>,
        index: BTreeMap<&'a ModPath, usize>,
        low: BTreeMap<&'a ModPath, usize>,
        stack: Vec<&'a ModPath>,
        on_stack: BTreeSet<&'a ModPath>,
        out: Vec<Vec<ModPath>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a ModPath) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        s.on_stack.insert(v);
        for w in &s.graph[v] {
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on_stack.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on_stack.remove(w);
                comp.push(w.clone());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

fn crate_graph() -> (Crate, BTreeMap<ModPath, BTreeSet<ModPath>>) {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let krate = Crate::read(&src);
    let graph = krate.edges();
    (krate, graph)
}

/// Each circle's files and the edges among them.
fn describe(
    krate: &Crate,
    graph: &BTreeMap<ModPath, BTreeSet<ModPath>>,
    comps: &[Vec<ModPath>],
) -> String {
    let mut text = String::new();
    for c in comps {
        let files: Vec<String> = c
            .iter()
            .map(|m| krate.modules[m].file.display().to_string())
            .collect();
        text += &format!("{}\n", files.join(" ↔ "));
        for from in c {
            for to in graph[from].iter().filter(|t| c.contains(t)) {
                text += &format!("    {} → {}\n", name(from), name(to));
            }
        }
    }
    text
}

#[test]
fn modules_form_no_circle() {
    let (krate, graph) = crate_graph();
    assert!(
        graph.len() > 50,
        "the reader found only {} modules",
        graph.len()
    );
    let comps = circles(&graph);
    assert!(
        comps.is_empty(),
        "modules that import each other (directly or through others):\n{}",
        describe(&krate, &graph, &comps)
    );
}

/// The top-level stages (`cpu`, `gpu`, `render`, …) also form no circle.
#[test]
fn stages_form_no_circle() {
    let (krate, graph) = crate_graph();
    let mut stages: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    for (from, tos) in &graph {
        let Some(a) = from.first() else { continue };
        let entry = stages.entry(vec![a.clone()]).or_default();
        for to in tos {
            if let Some(b) = to.first()
                && b != a
            {
                entry.insert(vec![b.clone()]);
            }
        }
    }
    let comps = circles(&stages);
    let text = comps
        .iter()
        .map(|c| c.iter().map(name).collect::<Vec<_>>().join(" ↔ "))
        .collect::<Vec<_>>()
        .join("\n");
    assert!(comps.is_empty(), "stages that import each other:\n{text}");
    drop(krate);
}

#[test]
fn tracers_stand_side_by_side() {
    let (_, graph) = crate_graph();
    let mut crossings = Vec::new();
    for (from, tos) in &graph {
        for to in tos {
            let (a, b) = (from.first(), to.first());
            let pair = (a.map(String::as_str), b.map(String::as_str));
            if matches!(
                pair,
                (Some("cpu"), Some("gpu")) | (Some("gpu"), Some("cpu"))
            ) {
                crossings.push(format!("{} → {}", name(from), name(to)));
            }
        }
    }
    assert!(
        crossings.is_empty(),
        "the tracers import each other:\n{}",
        crossings.join("\n")
    );
    // Both stand on the backend-neutral core.
    for tracer in ["cpu", "gpu"] {
        assert!(
            graph
                .iter()
                .any(|(f, tos)| f.first().is_some_and(|a| a == tracer)
                    && tos.iter().any(|t| t.first().is_some_and(|b| b == "common"))),
            "{tracer} does not use common"
        );
    }
}

/// Stages that must not import others: the preview asks `render` for frames and never names
/// a backend; the denoiser's filter is backend-neutral (its GPU pass lives in `gpu`); the
/// backend-neutral core stands below the output stage.
const FORBIDDEN: &[(&str, &str, &str)] = &[
    ("ui", "gpu", "the preview asks `render` for frames"),
    ("ui", "cpu", "the preview asks `render` for frames"),
    (
        "denoise",
        "gpu",
        "the filter is backend-neutral; its GPU pass lives in `gpu`",
    ),
    ("common", "output", "the core stands below the output stage"),
];

/// Each edge that breaks a rule of [`FORBIDDEN`], described.
fn broken_rules(graph: &BTreeMap<ModPath, BTreeSet<ModPath>>) -> Vec<String> {
    let mut broken = Vec::new();
    for (from, tos) in graph {
        for to in tos {
            let (Some(a), Some(b)) = (from.first(), to.first()) else {
                continue;
            };
            for (stage, other, why) in FORBIDDEN {
                if a == stage && b == other {
                    broken.push(format!("{} → {}: {why}", name(from), name(to)));
                }
            }
        }
    }
    broken
}

#[test]
fn stages_keep_the_house_rules() {
    let (_, graph) = crate_graph();
    let broken = broken_rules(&graph);
    assert!(
        broken.is_empty(),
        "imports across the house rules:\n{}",
        broken.join("\n")
    );
}

/// Each rule catches a hand-made violation: a small crate on disk whose `ui`, `denoise` and
/// `common` each name what they must not, read by the same reader.
#[test]
fn house_rules_catch_hand_made_violations() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    let files = [
        (
            "lib.rs",
            "pub mod common; pub mod cpu; pub mod denoise; pub mod gpu; pub mod output; pub mod ui;",
        ),
        ("gpu/mod.rs", "pub mod resolve;"),
        ("gpu/resolve.rs", "pub struct ResolvePass;"),
        ("cpu/mod.rs", "pub fn threads() -> usize { 1 }"),
        ("output/mod.rs", "pub struct LinearImage;"),
        ("common/mod.rs", "use crate::output::LinearImage;"),
        (
            "denoise/mod.rs",
            "pub fn f(_: crate::gpu::resolve::ResolvePass) {}",
        ),
        (
            "ui/mod.rs",
            "pub mod worker;\nfn n() -> usize { crate::cpu::threads() }",
        ),
        ("ui/worker.rs", "use crate::gpu::resolve::ResolvePass;"),
    ];
    for (file, code) in files {
        let path = src.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, code).unwrap();
    }
    let graph = Crate::read(src).edges();
    let broken = broken_rules(&graph);
    for expected in [
        "ui::worker → gpu::resolve",
        "ui → cpu",
        "denoise → gpu::resolve",
        "common → output",
    ] {
        assert!(
            broken.iter().any(|b| b.starts_with(expected)),
            "`{expected}` not caught: {broken:?}"
        );
    }
    assert_eq!(broken.len(), 4, "{broken:?}");
}

/// The reader itself: it sees the edges it must, so a pass above is not a blind one.
#[test]
fn reader_finds_known_edges() {
    let code = strip(
        "use crate::a::{b::{C, d as e}, f};\n// use crate::z;\nlet s = \"crate::y::Q\";\n\
         fn g() { super::h::k(); }\n#[cfg(test)]\nmod tests { use crate::t::U; }\n",
    );
    let (uses, rest) = use_items(&code);
    let mut expanded = Vec::new();
    for (_, tree) in &uses {
        expand_use_tree(tree, &[], &mut expanded);
    }
    let paths: Vec<String> = expanded.iter().map(|(p, _)| p.join("::")).collect();
    assert_eq!(paths, ["crate::a::b::C", "crate::a::b::d", "crate::a::f"]);
    assert_eq!(expanded[1].1, "e");
    let code_p: Vec<String> = code_paths(&rest).iter().map(|p| p.join("::")).collect();
    assert_eq!(code_p, ["super::h::k"]);
    // A circle of two and a chain of three.
    let m = |s: &str| -> ModPath { s.split('.').map(String::from).collect() };
    let mut g: BTreeMap<ModPath, BTreeSet<ModPath>> = BTreeMap::new();
    g.insert(m("a"), [m("b")].into());
    g.insert(m("b"), [m("a"), m("c")].into());
    g.insert(m("c"), BTreeSet::new());
    assert_eq!(circles(&g), vec![vec![m("a"), m("b")]]);
}

/// The library's error style: `thiserror` types, `anyhow` only in the command line's
/// `cli/`, no `Result<_, String>`, and no command-line flag named below the front ends
/// (`cli/`, and `ui/`, whose on-screen hints tell the user what to type).
fn error_style_breaks(src: &Path, flags: &[String]) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut broken = Vec::new();
    for file in files {
        let rel = file.strip_prefix(src).unwrap().display().to_string();
        if rel.starts_with("cli/") {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        let code = strip(&text);
        if find_word(&code, "anyhow").is_some() {
            broken.push(format!("{rel}: anyhow below `cli`"));
        }
        let squashed: String = code.chars().filter(|c| !c.is_whitespace()).collect();
        if string_errors(&squashed) {
            broken.push(format!("{rel}: a `Result<_, String>`"));
        }
        if rel.starts_with("ui/") {
            continue;
        }
        for lit in literals(&remove_test_items(&without_comments(&text))) {
            for flag in flags {
                let named = lit.match_indices(flag.as_str()).any(|(k, _)| {
                    let next = lit[k + flag.len()..].chars().next();
                    !next.is_some_and(|c| c.is_ascii_alphanumeric() || c == '-')
                });
                if named {
                    broken.push(format!("{rel}: names the flag {flag}"));
                }
            }
        }
    }
    broken
}

/// Whether whitespace-free `code` has a `Result<…,String>` (the error type `String` at the
/// generic list's top level).
fn string_errors(code: &str) -> bool {
    code.match_indices("Result<").any(|(k, m)| {
        let mut depth = 1;
        let mut top_comma = None;
        for (j, c) in code[k + m.len()..].char_indices() {
            match c {
                '<' | '(' | '[' => depth += 1,
                '>' | ')' | ']' => {
                    depth -= 1;
                    if depth == 0 {
                        let body = &code[k + m.len()..k + m.len() + j];
                        return top_comma.is_some_and(|t: usize| &body[t + 1..] == "String");
                    }
                }
                ',' if depth == 1 => top_comma = Some(j),
                _ => {}
            }
        }
        false
    })
}

/// `src` without its comments (strings kept).
fn without_comments(src: &str) -> String {
    let mut out = String::new();
    let mut in_string = false;
    let mut chars = src.chars().peekable();
    while let Some(c) = chars.next() {
        if in_string {
            out.push(c);
            match c {
                '\\' => out.extend(chars.next()),
                '"' => in_string = false,
                _ => {}
            }
        } else if c == '/' && chars.peek() == Some(&'/') {
            for d in chars.by_ref() {
                if d == '\n' {
                    out.push('\n');
                    break;
                }
            }
        } else {
            in_string = c == '"';
            out.push(c);
        }
    }
    out
}

/// The contents of `code`'s string literals.
fn literals(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut chars = code.chars();
    while let Some(c) = chars.next() {
        if c == '"' {
            let mut s = String::new();
            while let Some(d) = chars.next() {
                match d {
                    '\\' => s.extend(chars.next()),
                    '"' => break,
                    _ => s.push(d),
                }
            }
            out.push(s);
        }
    }
    out
}

/// Every long flag of the command line, from clap's own description of it.
fn cli_flags() -> Vec<String> {
    use clap::CommandFactory;
    fn walk(cmd: &clap::Command, out: &mut Vec<String>) {
        for a in cmd.get_arguments() {
            if let Some(l) = a.get_long()
                && !["help", "version"].contains(&l)
            {
                out.push(format!("--{l}"));
            }
        }
        for s in cmd.get_subcommands() {
            walk(s, out);
        }
    }
    let mut out = Vec::new();
    walk(&termtrace::cli::Cli::command(), &mut out);
    out.sort();
    out.dedup();
    out
}

#[test]
fn errors_keep_one_style() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let flags = cli_flags();
    assert!(
        flags.iter().any(|f| f == "--sky") && flags.iter().any(|f| f == "--adapter"),
        "{flags:?}"
    );
    let broken = error_style_breaks(&src, &flags);
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

/// Each error-style rule catches a hand-made violation.
#[test]
fn error_style_catches_hand_made_violations() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    let files = [
        (
            "cli/mod.rs",
            "pub fn run() -> anyhow::Result<()> { Ok(()) }",
        ),
        (
            "scene/mod.rs",
            "pub fn f() -> anyhow::Result<()> { Ok(()) }",
        ),
        (
            "gpu/mod.rs",
            "pub fn g() -> Result<Vec<(u8, u8)>, String> { Err(\"x\".into()) }\n\
             pub fn ok() -> Result<u8, Error<String>> { todo!() }",
        ),
        (
            "render/mod.rs",
            "pub fn h() -> &'static str { \"name one with --adapter 0\" }\n\
             // --sky in a comment is fine\npub fn k() -> &'static str { \"--skyline\" }",
        ),
        (
            "ui/app.rs",
            "pub fn hint() -> &'static str { \"open with --sky\" }",
        ),
    ];
    for (file, code) in files {
        let path = src.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, code).unwrap();
    }
    let flags = vec!["--adapter".to_string(), "--sky".to_string()];
    let mut broken = error_style_breaks(src, &flags);
    broken.sort();
    assert_eq!(
        broken,
        [
            "gpu/mod.rs: a `Result<_, String>`",
            "render/mod.rs: names the flag --adapter",
            "scene/mod.rs: anyhow below `cli`",
        ],
    );
}
