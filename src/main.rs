//! The `termtrace` binary: everything lives in the library.

fn main() -> std::process::ExitCode {
    termtrace::cli::quiet_vulkan_layers();
    termtrace::cli::main()
}
