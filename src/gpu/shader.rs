//! The `// #include "path"` resolver that assembles one WGSL module from a file of
//! [`crate::common::wgsl`] and the shared files it names (`shaders/common/`).
//! For shader work without rebuilding, `TERMTRACE_SHADER_DIR=shaders` reads the files from
//! that folder instead (any file it lacks comes from the binary).

use crate::common::wgsl::source;
use std::borrow::Cow;

const INCLUDE: &str = "// #include \"";

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

/// Why the WGSL of a pipeline cannot be put together.
#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("include cycle: {}", .0.join(" -> "))]
    Cycle(Vec<String>),
    #[error("no shader file `{name}`{}", .from.as_ref().map_or(String::new(), |s| format!(" (included from {s})")))]
    Missing { name: String, from: Option<String> },
}

/// `name` with every file it includes (transitively) placed before it, each once.
pub fn assemble(name: &str) -> Result<String, ShaderError> {
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
) -> Result<(), ShaderError> {
    if done.iter().any(|d| d == name) {
        return Ok(());
    }
    if stack.iter().any(|d| d == name) {
        let mut chain = stack.clone();
        chain.push(name.to_string());
        return Err(ShaderError::Cycle(chain));
    }
    let src = current_source(name).ok_or_else(|| ShaderError::Missing {
        name: name.to_string(),
        from: stack.last().cloned(),
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
